#include "core/hierarchy/tree.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <tbb/parallel_invoke.h>

#include "core/common/check.h"
#include "core/hierarchy/builders.h"

namespace lightlink::hierarchy {
namespace {

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

Status validate(const surfels::Surfels& s, const TreeOptions& o) {
  if (!std::isfinite(o.normal_weight) || o.normal_weight < 0.0f)
    return invalidInput("tree normal weight {} must be finite and >= 0", o.normal_weight);
  if (!std::isfinite(o.balance_weight) || o.balance_weight < 0.0f)
    return invalidInput("tree balance weight {} must be finite and >= 0", o.balance_weight);
  if (o.candidates < 1) return invalidInput("tree candidate count {} must be >= 1", o.candidates);
  const std::size_t n = s.size();
  if (s.normal.size() != n || s.area.size() != n || s.albedo.size() != n || s.emission.size() != n ||
      s.lightmap_uv.size() != n || s.mesh.size() != n || s.triangle.size() != n || s.barycentric.size() != n)
    return invalidInput("surfel arrays have inconsistent sizes ({} positions)", n);
  if (n > (std::size_t(1) << 30)) return invalidInput("{} surfels exceed the tree limit of 2^30", n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!finite(s.position[i]) || !finite(s.normal[i]) || !std::isfinite(s.area[i]) || s.area[i] < 0.0f)
      return invalidInput("surfel {}: non-finite position/normal or bad area {}", i, s.area[i]);
  }
  return Status::ok();
}

// Internal node ids follow the split position (node = n + mid - 1: every gap between two
// surfels is split exactly once), so parallel recursion numbers nodes deterministically.
void kdSplit(const surfels::Surfels& s, std::vector<std::uint32_t>& idx, std::uint32_t b, std::uint32_t e,
             detail::MergeTree& out, std::int32_t& node) {
  const std::uint32_t n = std::uint32_t(s.size());
  if (e - b == 1) {
    node = std::int32_t(idx[b]);
    return;
  }
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(std::numeric_limits<float>::lowest());
  for (std::uint32_t i = b; i < e; ++i) {
    lo = glm::min(lo, s.position[idx[i]]);
    hi = glm::max(hi, s.position[idx[i]]);
  }
  const glm::vec3 ext = hi - lo;
  const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
  const std::uint32_t mid = b + (e - b) / 2;
  std::nth_element(idx.begin() + b, idx.begin() + mid, idx.begin() + e, [&](std::uint32_t x, std::uint32_t y) {
    const float px = s.position[x][axis], py = s.position[y][axis];
    return px < py || (px == py && x < y);
  });
  std::int32_t l = -1, r = -1;
  if (e - b > 4096) {
    tbb::parallel_invoke([&] { kdSplit(s, idx, b, mid, out, l); }, [&] { kdSplit(s, idx, mid, e, out, r); });
  } else {
    kdSplit(s, idx, b, mid, out, l);
    kdSplit(s, idx, mid, e, out, r);
  }
  node = std::int32_t(n + mid - 1);
  out.left[std::size_t(node)] = l;
  out.right[std::size_t(node)] = r;
}

// Breadth-first renumbering, depth-first leaf order (-> contiguous ranges), bottom-up sums.
Tree finalize(surfels::Surfels& s, const detail::MergeTree& mt) {
  const std::size_t n = s.size();
  const std::size_t count = 2 * n - 1;
  LL_CHECK_EQ(mt.left.size(), count);
  Tree t;

  // Breadth-first order of the merge tree: new id k <-> old id bfs[k].
  std::vector<std::int32_t> bfs;
  bfs.reserve(count);
  std::vector<std::uint32_t> new_of_old(count);
  bfs.push_back(mt.root);
  for (std::size_t k = 0; k < bfs.size(); ++k) {
    const std::int32_t o = bfs[k];
    new_of_old[std::size_t(o)] = std::uint32_t(k);
    if (mt.left[std::size_t(o)] >= 0) {
      bfs.push_back(mt.left[std::size_t(o)]);
      bfs.push_back(mt.right[std::size_t(o)]);
    }
  }
  LL_CHECK_EQ(bfs.size(), count);

  t.left.assign(count, -1);
  t.right.assign(count, -1);
  t.parent.assign(count, -1);
  t.depth.assign(count, 0);
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t o = std::size_t(bfs[k]);
    if (mt.left[o] < 0) continue;
    const std::int32_t l = std::int32_t(new_of_old[std::size_t(mt.left[o])]);
    const std::int32_t r = std::int32_t(new_of_old[std::size_t(mt.right[o])]);
    t.left[k] = l;
    t.right[k] = r;
    t.parent[std::size_t(l)] = t.parent[std::size_t(r)] = std::int32_t(k);
    t.depth[std::size_t(l)] = t.depth[std::size_t(r)] = t.depth[k] + 1;
  }

  // Depth-first (left first) leaf order gives every node a contiguous surfel range.
  t.begin.assign(count, 0);
  t.end.assign(count, 0);
  t.original_index.resize(n);
  {
    std::vector<std::int32_t> stack{0};
    std::uint32_t rank = 0;
    while (!stack.empty()) {
      const std::int32_t k = stack.back();
      stack.pop_back();
      if (t.left[std::size_t(k)] < 0) {
        t.original_index[rank] = std::uint32_t(bfs[std::size_t(k)]);  // leaves are surfel ids
        t.begin[std::size_t(k)] = rank;
        t.end[std::size_t(k)] = ++rank;
      } else {
        stack.push_back(t.right[std::size_t(k)]);
        stack.push_back(t.left[std::size_t(k)]);
      }
    }
  }

  surfels::reorder(s, t.original_index);
  t.leaf_of_surfel.resize(n);
  t.area.resize(count);
  t.bounds_min.resize(count);
  t.bounds_max.resize(count);
  t.centroid.resize(count);
  t.mean_normal.resize(count);
  std::vector<double> area(count);
  std::vector<glm::dvec3> weighted_pos(count), weighted_normal(count);
  for (std::size_t k = count; k-- > 0;) {
    if (t.left[k] < 0) {
      const std::uint32_t i = t.begin[k];
      t.leaf_of_surfel[i] = std::uint32_t(k);
      area[k] = s.area[i];
      weighted_pos[k] = glm::dvec3(s.position[i]) * area[k];
      weighted_normal[k] = glm::dvec3(s.normal[i]) * area[k];
      t.bounds_min[k] = t.bounds_max[k] = s.position[i];
      t.centroid[k] = s.position[i];
    } else {
      const std::size_t l = std::size_t(t.left[k]), r = std::size_t(t.right[k]);
      t.begin[k] = t.begin[l];
      t.end[k] = t.end[r];
      area[k] = area[l] + area[r];
      weighted_pos[k] = weighted_pos[l] + weighted_pos[r];
      weighted_normal[k] = weighted_normal[l] + weighted_normal[r];
      t.bounds_min[k] = glm::min(t.bounds_min[l], t.bounds_min[r]);
      t.bounds_max[k] = glm::max(t.bounds_max[l], t.bounds_max[r]);
      // Zero-area subtrees (allowed, if odd) fall back to the box centre.
      t.centroid[k] = area[k] > 0.0
                          ? glm::clamp(glm::vec3(weighted_pos[k] / area[k]), t.bounds_min[k], t.bounds_max[k])
                          : 0.5f * (t.bounds_min[k] + t.bounds_max[k]);
    }
    t.area[k] = float(area[k]);
    const double len = glm::length(weighted_normal[k]);
    // Opposite faces cancel: below 1e-6 of the area the direction is noise, report 0.
    t.mean_normal[k] = len > 1e-6 * area[k] && len > 0.0 ? glm::vec3(weighted_normal[k] / len) : glm::vec3(0.0f);
  }

  // Breadth-first order makes depth non-decreasing with the node id.
  const std::uint32_t max_depth = t.depth.back();
  t.level_begin.assign(max_depth + 2, 0);
  for (std::size_t k = 0; k < count; ++k) ++t.level_begin[t.depth[k] + 1];
  for (std::uint32_t d = 0; d <= max_depth; ++d) t.level_begin[d + 1] += t.level_begin[d];
  return t;
}

}  // namespace

namespace detail {

MergeTree buildKdMedian(const surfels::Surfels& s) {
  const std::uint32_t n = std::uint32_t(s.size());
  MergeTree mt;
  mt.left.assign(2 * std::size_t(n) - 1, -1);
  mt.right.assign(2 * std::size_t(n) - 1, -1);
  std::vector<std::uint32_t> idx(n);
  std::iota(idx.begin(), idx.end(), 0u);
  kdSplit(s, idx, 0, n, mt, mt.root);
  return mt;
}

}  // namespace detail

Expected<Tree> buildTree(surfels::Surfels& surfels, const TreeOptions& options) {
  if (Status st = validate(surfels, options); !st) return st;
  if (surfels.empty()) return Tree{};
  const detail::MergeTree mt = options.builder == Builder::kKdMedian
                                   ? detail::buildKdMedian(surfels)
                                   : detail::buildAgglomerative(surfels, options);
  // A cancelled builder stops early with a partial merge tree: never finalised.
  if (stopRequested(options.progress)) return cancelled("hierarchy: cancelled");
  return finalize(surfels, mt);
}

}  // namespace lightlink::hierarchy
