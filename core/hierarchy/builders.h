// The two tree builders behind buildTree, in the numbering they find natural: leaves are the
// input surfel indices 0..n-1, internal nodes n..2n-2 in creation order, and `root` names the
// top. buildTree turns this into the breadth-first, range-contiguous Tree of tree.h.
#pragma once

#include <cstdint>
#include <vector>

#include "core/hierarchy/tree.h"

namespace lightlink::hierarchy::detail {

struct MergeTree {
  std::vector<std::int32_t> left, right;  // 2n - 1 entries; -1 for leaves
  std::int32_t root = -1;
};

// Median split of the surfel centres on the widest axis of each range.
MergeTree buildKdMedian(const surfels::Surfels& surfels);

// HAC with the seed-000 distance (tree.h), Müllner's generic algorithm over a centroid grid.
MergeTree buildAgglomerative(const surfels::Surfels& surfels, const TreeOptions& options);

}  // namespace lightlink::hierarchy::detail
