// The cut: which nodes of the surfel tree one cache links to (seed 000 sec 4.5).
//
// Link generation credits every hit of a cache's rays to a surfel and sorts the hits by
// surfel; since the tree's surfels are in leaf order, every node's hits are then one
// contiguous run of samples. The cut starts at the root and repeatedly refines the open node
// with the most samples (ties: the lower node index) until nL nodes are open or linked;
// nodes no ray reached never enter it. Kept apart from the ray loop so that tests can hold
// it against that definition taken literally (tests/links/cut_test.cpp).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/hierarchy/tree.h"

namespace lightlink::links {

// A credited hit as one sortable key: owner surfel in the high half, ray in the low half,
// so sorting the keys groups hits by surfel (tree order) with a fixed order inside.
using Sample = std::uint64_t;
inline Sample makeSample(std::uint32_t surfel, std::uint32_t ray) { return (Sample(surfel) << 32) | ray; }
inline std::uint32_t rayOf(Sample s) { return static_cast<std::uint32_t>(s); }
inline std::uint32_t surfelOf(Sample s) { return static_cast<std::uint32_t>(s >> 32); }

// What the cut reads of a tree node, packed so that a refinement touches one record instead
// of three arrays (left, right, end of left) of 65k+ nodes each. With the keyed heap and the
// branch-free split search (cut.cpp), the cut went from 0.52-0.55 to 0.27 Gcycles on the Cornell box
// (docs/results.md, phase table).
struct CutNode {
  std::uint32_t left;   // kLeaf for a leaf
  std::uint32_t right;
  std::uint32_t split;  // first surfel of the right child (= end of the left child's range)
};
inline constexpr std::uint32_t kLeaf = 0xffffffffu;


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

// The cut's open nodes as a binary max-heap keyed by one integer: visible samples in the high
// half, the complement of the node in the low half (so ties go to the lower node index, for
// determinism). Keys are unique, so the order of pops does not depend on the heap's layout.
struct OpenEntry {
  std::uint64_t key;
  std::uint32_t first;
};
// Reused between caches so that choosing a cut never allocates once warm.
struct CutScratch {
  std::vector<OpenEntry> open;          // the open nodes (a max-heap)
  std::vector<CutEntry> ordered;
  std::vector<std::uint32_t> at_first;  // per sample: the cut entry starting there
  std::vector<std::uint64_t> starts;    // per sample, one bit: a cut entry starts there
};

// Chooses the cut of at most max_links (>= 1) nodes over `samples`, sorted ascending (by
// surfel, then ray). `cut` receives the nodes with their sample ranges, ordered by first
// sample (= by surfel range, the order links are stored in).
void chooseCut(const CutTree& tree, std::span<const Sample> samples, int max_links, CutScratch& scratch,
               std::vector<CutEntry>& cut);

}  // namespace lightlink::links
