// The cut: which nodes of the surfel tree one cache links to (seed 000 sec 4.5).
//
// Link generation credits every hit of a cache's rays to a surfel and sorts the hits by
// surfel; since the tree's surfels are in leaf order, every node's hits are then one
// contiguous run of samples. The cut starts at the root and repeatedly refines the open node
// with the most samples (ties: the lower node index) until nL nodes are open or linked;
// nodes no ray reached never enter it. Kept apart from the ray loop so that tests can hold
// it against that definition taken literally (tests/links/cut_test.cpp).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/common/aligned_vector.h"
#include "core/hierarchy/tree.h"

namespace lightlink::links {

// A credited hit as one sortable key: owner surfel in the high half, ray in the low half,
// so sorting the keys groups hits by surfel (tree order) with a fixed order inside.
using Sample = std::uint64_t;
inline Sample makeSample(std::uint32_t surfel, std::uint32_t ray) { return (Sample(surfel) << 32) | ray; }
inline std::uint32_t rayOf(Sample s) { return static_cast<std::uint32_t>(s); }
inline std::uint32_t surfelOf(Sample s) { return static_cast<std::uint32_t>(s >> 32); }

// What the cut reads of a tree node: one 8-byte record instead of three arrays (left,
// right, end of left) of 65k+ nodes each. Siblings have consecutive indices (breadth-first
// layout), so the right child is the left one + 1; the children carry leaf flags, so a leaf
// is never split or its record read.
struct CutNode {
  std::uint32_t children;  // kLeaf for a leaf; else the left child | kLeftIsLeaf | kRightIsLeaf
  std::uint32_t split;     // first surfel of the right child (= end of the left child's range)
};
inline constexpr std::uint32_t kLeaf = 0xffffffffu;
// Where the cut holds a node index, a leaf is marked with this bit.
inline constexpr std::uint32_t kLeafChild = 0x80000000u;
// The children word's flags: the left one is kLeafChild itself and the right one the bit
// below it, so that leftChild and rightChild below move them into place with a mask and a shift.
inline constexpr std::uint32_t kLeftIsLeaf = kLeafChild, kRightIsLeaf = kLeafChild >> 1;
inline constexpr std::uint32_t kChildIndex = kRightIsLeaf - 1;
inline std::uint32_t leftChild(std::uint32_t children) { return children & (kChildIndex | kLeftIsLeaf); }
inline std::uint32_t rightChild(std::uint32_t children) {
  return ((children & kChildIndex) + 1) | ((children & kRightIsLeaf) << 1);
}

// The tree as the cut reads it: the node records, and the leaf of each surfel (a view of the
// tree's own array: a CutTree must not outlive the tree it was made from).
struct CutTree {
  std::vector<CutNode> nodes;
  std::span<const std::uint32_t> leaf_of_surfel;
};
CutTree cutTree(const hierarchy::Tree& tree);

struct CutEntry {
  std::uint32_t count, node, first;  // visible samples, tree node, index of its first sample
};

// Reused between caches so that choosing a cut never allocates once warm: the search's
// arrays (cut.cpp), the stopping count of the last cut (where the next search starts), and
// the final ordering's table and bitmap.
inline constexpr std::size_t kCutFields = 13;
struct CutScratch {
  std::array<LineVector<std::uint32_t>, kCutFields> field;
  LineVector<std::uint32_t> ties;
  std::uint32_t stop_count = 0;
  LineVector<std::uint32_t> at_first;  // per sample: the record of the cut entry starting there
  LineVector<std::uint64_t> starts;    // per sample, one bit: a cut entry starts there
};

// Which code splits the nodes: the best this CPU has (16 nodes at a time with AVX-512 where
// present), or one node at a time. Both choose the same cut (tests run both).
enum class CutKernel { kBest, kScalar };

// Chooses the cut of at most max_links (>= 1) nodes over `samples`, sorted ascending (by
// surfel, then ray). `cut` receives the nodes with their sample ranges, ordered by first
// sample (= by surfel range, the order links are stored in). The cut does not depend on
// what the scratch held before.
void chooseCut(const CutTree& tree, std::span<const Sample> samples, int max_links, CutScratch& scratch,
               std::vector<CutEntry>& cut, CutKernel kernel = CutKernel::kBest);

}  // namespace lightlink::links
