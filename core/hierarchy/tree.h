// Surfel hierarchy: the binary tree of sender patches (seed 000 sec. 4.2).
//
// Each node is a sender: a subtree of surfels whose flux the relight pulls up the tree and
// whose radiosity links read. Two builders: a fast kd split (median of the surfel centres on
// the widest axis, balanced by construction) and the quality builder, hierarchical
// agglomerative clustering (HAC) with the seed's distance
//     d(a, b) = |x_a - x_b|^2 / |x_max - x_min|^2 + Cn (1 - <n_a, n_b>) + Cb |A_a - A_b| / max(A_a, A_b)
// (x: area-weighted centroid, n: normalised area-weighted mean normal, A: area; Cn = 0.1,
// Cb = 0.02). The centroid term makes d non-reducible, so nearest-neighbour chains do not
// apply; HAC runs Müllner's generic algorithm (a lazily updated priority queue of each
// cluster's nearest neighbour) over a uniform grid of cluster centroids. A nearest-neighbour
// search is exact when the spatial term alone proves it (the other terms are >= 0), and
// otherwise stops after at least `candidates` clusters in the nearest grid rings: an
// approximation that only matters when the normal/balance terms outweigh distance.
//
// Layout: flat per-node arrays in breadth-first order. Node 0 is the root, children have
// larger indices than their parent (a reverse loop over nodes is a valid bottom-up pull), and
// every depth is a contiguous index range (a GPU pull runs one dispatch per level). `buildTree`
// reorders the surfels so that every node covers a contiguous range [begin, end) of them;
// leaves cover exactly one. 2n - 1 nodes for n surfels; none for n = 0. Deterministic for any
// thread count.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/enum_names.h"
#include "core/common/progress.h"
#include "core/common/status.h"
#include "core/surfels/surfels.h"

namespace lightlink::hierarchy {

enum class Builder { kKdMedian, kAgglomerative };
// The one table of builder names: bake options, the canonical options string, reports and
// benchmarks all spell them so.
inline constexpr EnumNames<Builder, 2> kBuilderNames{{{"fast", Builder::kKdMedian}, {"hac", Builder::kAgglomerative}}};
constexpr std::string_view builderName(Builder b) { return enumName(kBuilderNames, b); }

struct TreeOptions {
  Builder builder = Builder::kAgglomerative;
  float normal_weight = 0.1f;    // Cn, >= 0
  float balance_weight = 0.02f;  // Cb, >= 0
  int candidates = 32;           // HAC: clusters examined per nearest-neighbour search, >= 1
  const Progress* progress = nullptr;  // polled for cancellation: buildTree then gives kCancelled
};

struct Tree {
  std::vector<std::int32_t> left, right;      // children, -1 for leaves
  std::vector<std::int32_t> parent;           // -1 for the root
  std::vector<std::uint32_t> begin, end;      // surfel range [begin, end) after reordering
  std::vector<std::uint32_t> depth;           // root = 0
  std::vector<float> area;                    // m^2, sum of the node's surfel areas
  std::vector<glm::vec3> bounds_min, bounds_max;  // box of the node's surfel *centres*, world
  std::vector<glm::vec3> centroid;            // area-weighted mean surfel position, world
  std::vector<glm::vec3> mean_normal;         // area-weighted mean normal, unit; 0 if it cancels
  // Nodes of depth d are [level_begin[d], level_begin[d + 1]); size = max depth + 2.
  std::vector<std::uint32_t> level_begin;
  std::vector<std::uint32_t> leaf_of_surfel;  // reordered surfel index -> its leaf node
  std::vector<std::uint32_t> original_index;  // reordered surfel index -> index before buildTree

  std::size_t nodeCount() const { return left.size(); }
  std::size_t surfelCount() const { return leaf_of_surfel.size(); }
  bool isLeaf(std::size_t node) const { return left[node] < 0; }
  std::uint32_t levelCount() const { return level_begin.empty() ? 0u : std::uint32_t(level_begin.size() - 1); }
};

// Builds the tree over `surfels` and reorders `surfels` in place to the tree's leaf order
// (Tree::original_index records the permutation). Rejects inconsistent array sizes,
// non-finite positions/normals/areas and bad options as invalid input.
Expected<Tree> buildTree(surfels::Surfels& surfels, const TreeOptions& options);

}  // namespace lightlink::hierarchy
