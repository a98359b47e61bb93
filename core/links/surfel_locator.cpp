#include "core/links/surfel_locator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/common/aabb.h"

namespace lightlink::links {
namespace {
constexpr std::size_t kMaxCells = std::size_t(1) << 22;
}

SurfelLocator::SurfelLocator(const surfels::Surfels& surfels, const scene::Scene& scene, std::size_t raster_budget,
                             bool narrow_raster)
    : surfel_count_(surfels.size()), raster_budget_(raster_budget), narrow_raster_(narrow_raster) {
  const std::size_t n = surfels.size();
  Aabb box;
  double area = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    box.grow(surfels.position[i]);
    area += surfels.area[i];
  }
  if (n == 0) {
    cell_begin_.assign(2, 0);
    return;
  }
  // Mean surfel spacing on the surface is sqrt(area per surfel); two of them per cell keep
  // the true owner inside the 27-cell neighbourhood even after relaxation (one spacing per
  // cell was measured slower on zdm2: more queries widen to 125 cells).
  const float spacing = static_cast<float>(std::sqrt(area / static_cast<double>(n)));
  const glm::vec3 extent = glm::max(box.extent(), glm::vec3(1e-6f));
  cell_ = std::max(2.0f * spacing, 1e-6f * glm::length(extent));
  for (;;) {
    dims_ = glm::max(glm::ivec3(glm::ceil(extent / cell_)), glm::ivec3(1));
    if (std::size_t(dims_.x) * dims_.y * dims_.z <= kMaxCells) break;
    cell_ *= 1.5f;
  }
  inv_cell_ = 1.0f / cell_;
  origin_ = box.min;
  const std::size_t cells = std::size_t(dims_.x) * dims_.y * dims_.z;
  std::vector<std::uint32_t> cell_of(n);
  cell_begin_.assign(cells + 1, 0);
  for (std::size_t i = 0; i < n; ++i) {
    const glm::ivec3 c = cellOf(surfels.position[i]);
    cell_of[i] = static_cast<std::uint32_t>((std::size_t(c.z) * dims_.y + c.y) * dims_.x + c.x);
    ++cell_begin_[cell_of[i] + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) cell_begin_[c + 1] += cell_begin_[c];
  ids_.resize(n);
  std::vector<std::uint32_t> fill(cell_begin_.begin(), cell_begin_.end() - 1);
  for (std::size_t i = 0; i < n; ++i) ids_[fill[cell_of[i]]++] = static_cast<std::uint32_t>(i);
  cell_position_.resize(n);
  cell_normal_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    cell_position_[k] = surfels.position[ids_[k]];
    cell_normal_[k] = surfels.normal[ids_[k]];
  }
  buildTriangleTables(surfels, scene);
}

void SurfelLocator::buildTriangleTables(const surfels::Surfels& surfels, const scene::Scene& scene) {
  const std::size_t meshes = scene.meshes.size();
  mesh_count_ = static_cast<std::uint32_t>(meshes);
  // Side meshes: [0, meshes) the front sides, [meshes, 2 meshes) the back sides, which only a
  // double-sided mesh has triangles in.
  const std::size_t sides = 2 * meshes;
  auto realMesh = [&](std::size_t vm) { return vm < meshes ? vm : vm - meshes; };
  std::vector<std::uint8_t> two_sided(meshes, 0);
  for (std::size_t m = 0; m < meshes; ++m) two_sided[m] = scene.materialOf(scene.meshes[m]).double_sided ? 1 : 0;
  mesh_first_.assign(sides + 1, 0);
  for (std::size_t vm = 0; vm < sides; ++vm) {
    const std::size_t m = realMesh(vm);
    const bool has = vm < meshes || two_sided[m];
    mesh_first_[vm + 1] = mesh_first_[vm] + (has ? static_cast<std::uint32_t>(scene.meshes[m].triangleCount()) : 0u);
  }
  auto triangleNormal = [&](std::size_t m, std::uint32_t tri) {
    const auto& mesh = scene.meshes[m];
    const glm::vec3 p0 = mesh.positions[mesh.indices[3 * std::size_t(tri)]],
                    p1 = mesh.positions[mesh.indices[3 * std::size_t(tri) + 1]],
                    p2 = mesh.positions[mesh.indices[3 * std::size_t(tri) + 2]];
    return glm::cross(p1 - p0, p2 - p0);
  };
  const std::size_t n = surfels.size();
  // Each surfel's side mesh: a double-sided mesh's surfels facing against their triangle's
  // winding normal stand for its back (surfels.h).
  std::vector<std::uint32_t> side_mesh(n, kNoSurfel);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t m = surfels.mesh[i];
    if (m >= meshes || surfels.triangle[i] >= scene.meshes[m].triangleCount()) continue;
    const bool back = two_sided[m] && glm::dot(surfels.normal[i], triangleNormal(m, surfels.triangle[i])) < 0.0f;
    side_mesh[i] = back ? m + static_cast<std::uint32_t>(meshes) : m;
  }
  const std::uint32_t tris = mesh_first_.back();
  // Per triangle: how many surfels lie on it, and (for one) which.
  std::vector<std::uint32_t> count(tris, 0), only(tris, kNoSurfel);
  for (std::size_t i = 0; i < n; ++i) {
    if (side_mesh[i] == kNoSurfel) continue;
    const std::uint32_t t = mesh_first_[side_mesh[i]] + surfels.triangle[i];
    ++count[t];
    only[t] = static_cast<std::uint32_t>(i);
  }
  // Big triangles (more than one surfel): bin their surfels by barycentric cell.
  big_of_tri_.assign(tris, kNoSurfel);
  std::vector<std::uint32_t> cell_count;
  std::vector<std::uint32_t> big_mesh, big_triangle;
  for (std::size_t vm = 0; vm < sides; ++vm) {
    for (std::uint32_t tri = 0; tri < mesh_first_[vm + 1] - mesh_first_[vm]; ++tri) {
      const std::uint32_t t = mesh_first_[vm] + tri;
      if (count[t] <= 1) continue;
      BigTriangle big;
      big.g = static_cast<std::uint32_t>(std::ceil(std::sqrt(double(count[t]))));
      big.first_cell = static_cast<std::uint32_t>(cell_count.size());
      big_of_tri_[t] = static_cast<std::uint32_t>(big_.size());
      big_.push_back(big);
      big_mesh.push_back(static_cast<std::uint32_t>(realMesh(vm)));
      big_triangle.push_back(tri);
      cell_count.resize(cell_count.size() + std::size_t(big.g) * big.g, 0);
    }
  }
  auto cellOfBary = [](const BigTriangle& big, glm::vec2 uv) {
    const auto g = static_cast<int>(big.g);
    const int iu = std::clamp(static_cast<int>(uv.x * float(g)), 0, g - 1);
    const int iv = std::clamp(static_cast<int>(uv.y * float(g)), 0, g - 1);
    return big.first_cell + static_cast<std::uint32_t>(iv * g + iu);
  };
  std::vector<std::uint32_t> big_cell_of(n, kNoSurfel);
  for (std::size_t i = 0; i < n; ++i) {
    if (side_mesh[i] == kNoSurfel) continue;
    const std::uint32_t t = mesh_first_[side_mesh[i]] + surfels.triangle[i];
    if (big_of_tri_[t] == kNoSurfel) continue;
    big_cell_of[i] = cellOfBary(big_[big_of_tri_[t]], surfels.barycentric[i]);
    ++cell_count[big_cell_of[i]];
  }
  big_cell_begin_.assign(cell_count.size() + 1, 0);
  for (std::size_t c = 0; c < cell_count.size(); ++c) big_cell_begin_[c + 1] = big_cell_begin_[c] + cell_count[c];
  big_surfel_.assign(big_cell_begin_.back(), kNoSurfel);
  big_position_.assign(big_cell_begin_.back(), glm::vec3(0.0f));
  std::vector<std::uint32_t> cell_fill(big_cell_begin_.begin(), big_cell_begin_.end() - 1);
  for (std::size_t i = 0; i < n; ++i) {
    if (big_cell_of[i] == kNoSurfel) continue;
    const std::uint32_t k = cell_fill[big_cell_of[i]]++;
    big_surfel_[k] = static_cast<std::uint32_t>(i);
    big_position_[k] = surfels.position[i];
  }
  buildRasters(scene, big_mesh, big_triangle);

  // Every triangle's raster reference: a big triangle's raster, or a 1 x 1 raster holding a
  // small triangle's surfel. A triangle too small to hold one of its own (its area went into
  // a neighbour's slice) is represented by the surfel nearest to its centroid.
  raster_ref_.assign(tris, RasterRef{});
  for (std::size_t vm = 0; vm < sides; ++vm) {
    const auto& mesh = scene.meshes[realMesh(vm)];
    for (std::uint32_t tri = 0; tri < mesh_first_[vm + 1] - mesh_first_[vm]; ++tri) {
      const std::uint32_t t = mesh_first_[vm] + tri;
      RasterRef ref;
      if (big_of_tri_[t] != kNoSurfel) {
        const BigTriangle& big = big_[big_of_tri_[t]];
        ref = {big.first_raster, big.gr, static_cast<float>(big.gr), static_cast<float>(big.gr - 1)};
      } else {
        std::uint32_t s = only[t];
        if (count[t] == 0) {
          const glm::vec3 p0 = mesh.positions[mesh.indices[3 * tri]], p1 = mesh.positions[mesh.indices[3 * tri + 1]],
                          p2 = mesh.positions[mesh.indices[3 * tri + 2]];
          glm::vec3 nrm = glm::cross(p1 - p0, p2 - p0);
          const float len = glm::length(nrm);
          nrm = len > 0.0f ? nrm / len : glm::vec3(0.0f, 0.0f, 1.0f);
          if (vm >= meshes) nrm = -nrm;
          s = owner((p0 + p1 + p2) / 3.0f, nrm);
        }
        if (s == kNoSurfel) continue;
        ref.first = static_cast<std::uint32_t>(raster_.size());
        raster_.push_back(s);
      }
      raster_ref_[t] = ref;
    }
  }
  // Fewer than 65535 surfels (the usual case, nS = 32k): the raster in 16 bits, half the
  // memory that every link ray's owner load reads from (precompute_bench's link rays/s).
  if (narrow_raster_ && surfel_count_ < kNoSurfel16) {
    raster16_.resize(raster_.size() + 1, kNoSurfel16);
    for (std::size_t k = 0; k < raster_.size(); ++k)
      raster16_[k] = raster_[k] == kNoSurfel ? kNoSurfel16 : static_cast<std::uint16_t>(raster_[k]);
    std::vector<std::uint32_t>().swap(raster_);
  }
}

SurfelLocator::RasterTables SurfelLocator::rasterTables() const {
  static_assert(sizeof(RasterRef) == 4 * sizeof(std::uint32_t) && offsetof(RasterRef, size) == 4);
  RasterTables t;
  t.mesh_first = mesh_first_.data();
  t.mesh_first_count = static_cast<std::uint32_t>(mesh_first_.size());
  t.mesh_count = mesh_count_;
  t.raster_ref = reinterpret_cast<const std::uint32_t*>(raster_ref_.data());
  if (raster16_.empty())
    t.raster32 = raster_.data();
  else
    t.raster16 = raster16_.data();
  return t;
}

glm::ivec3 SurfelLocator::cellOf(const glm::vec3& p) const {
  const glm::ivec3 c(glm::floor((p - origin_) * inv_cell_));
  return glm::clamp(c, glm::ivec3(0), dims_ - 1);
}

std::uint32_t SurfelLocator::search(const glm::vec3& p, const glm::vec3& n, int radius, float min_cos) const {
  const glm::ivec3 c = cellOf(p);
  const glm::ivec3 lo = glm::max(c - radius, glm::ivec3(0));
  const glm::ivec3 hi = glm::min(c + radius, dims_ - 1);
  std::uint32_t best = kNoSurfel;
  float best_d2 = std::numeric_limits<float>::infinity();
  for (int z = lo.z; z <= hi.z; ++z) {
    for (int y = lo.y; y <= hi.y; ++y) {
      const std::size_t row = (std::size_t(z) * dims_.y + y) * dims_.x;
      const std::uint32_t begin = cell_begin_[row + lo.x], end = cell_begin_[row + hi.x + 1];
      for (std::uint32_t k = begin; k < end; ++k) {
        if (glm::dot(cell_normal_[k], n) < min_cos) continue;
        const glm::vec3 d = cell_position_[k] - p;
        const float d2 = glm::dot(d, d);
        // The scan order is fixed (cells, then ids), so ties resolve the same way every run.
        if (d2 < best_d2) {
          best_d2 = d2;
          best = k;
        }
      }
    }
  }
  return best == kNoSurfel ? kNoSurfel : ids_[best];
}

void SurfelLocator::cellCandidates(const BigTriangle& big, int iu, int iv, std::vector<std::uint32_t>& out) const {
  const auto g = static_cast<int>(big.g);
  out.clear();
  // 3 x 3 cells first; if they are all empty (a hole in the surfel cover), the whole triangle.
  for (int radius : {1, g}) {
    for (int cv = std::max(0, iv - radius); cv <= std::min(g - 1, iv + radius); ++cv) {
      const std::uint32_t row = big.first_cell + static_cast<std::uint32_t>(cv * g);
      const std::uint32_t begin = big_cell_begin_[row + static_cast<std::uint32_t>(std::max(0, iu - radius))];
      const std::uint32_t end = big_cell_begin_[row + static_cast<std::uint32_t>(std::min(g - 1, iu + radius)) + 1];
      for (std::uint32_t k = begin; k < end; ++k) out.push_back(k);
    }
    if (!out.empty()) break;
  }
}

std::uint32_t SurfelLocator::nearestCandidate(const std::vector<std::uint32_t>& candidates, const glm::vec3& p) const {
  std::uint32_t best = kNoSurfel;
  float best_d2 = std::numeric_limits<float>::infinity();
  for (std::uint32_t k : candidates) {
    const glm::vec3 d = big_position_[k] - p;
    const float d2 = glm::dot(d, d);
    // Candidates come in a fixed order (cells, then surfels), so ties resolve the same way.
    if (d2 < best_d2) {
      best_d2 = d2;
      best = big_surfel_[k];
    }
  }
  return best;
}

std::uint32_t SurfelLocator::scanBigTriangle(const BigTriangle& big, float u, float v, const glm::vec3& p) const {
  const auto g = static_cast<int>(big.g);
  std::vector<std::uint32_t> candidates;
  cellCandidates(big, std::clamp(static_cast<int>(u * float(g)), 0, g - 1),
                 std::clamp(static_cast<int>(v * float(g)), 0, g - 1), candidates);
  return nearestCandidate(candidates, p);
}

void SurfelLocator::buildRasters(const scene::Scene& scene, const std::vector<std::uint32_t>& big_mesh,
                                 const std::vector<std::uint32_t>& big_triangle) {
  std::size_t cells = 0;
  for (const BigTriangle& big : big_) cells += std::size_t(big.g) * big.g;
  raster_factor_ = kRaster;
  while (raster_factor_ > 1 && cells * raster_factor_ * raster_factor_ > raster_budget_) raster_factor_ /= 2;
  const std::uint32_t r = raster_factor_;
  // Work items: one row of big cells of one big triangle each (a box wall is two triangles of
  // thousands of surfels, so whole triangles would balance badly). Every raster cell is
  // written by exactly one item: the result does not depend on the thread count.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> rows;
  std::size_t first = 0;
  for (std::size_t b = 0; b < big_.size(); ++b) {
    BigTriangle& big = big_[b];
    const scene::MeshInstance& mesh = scene.meshes[big_mesh[b]];
    const std::uint32_t tri = big_triangle[b];
    const glm::vec3 p0 = mesh.positions[mesh.indices[3 * tri]], p1 = mesh.positions[mesh.indices[3 * tri + 1]],
                    p2 = mesh.positions[mesh.indices[3 * tri + 2]];
    big.v0 = p0;
    big.e1 = p1 - p0;
    big.e2 = p2 - p0;
    big.gr = big.g * r;
    big.first_raster = static_cast<std::uint32_t>(first);
    first += std::size_t(big.gr) * big.gr;
    for (std::uint32_t iv = 0; iv < big.g; ++iv) rows.emplace_back(static_cast<std::uint32_t>(b), iv);
  }
  raster_.assign(first, kNoSurfel);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rows.size(), 1), [&](const tbb::blocked_range<std::size_t>& range) {
    std::vector<std::uint32_t> cand;
    for (std::size_t item = range.begin(); item < range.end(); ++item) {
      const BigTriangle& big = big_[rows[item].first];
      const auto g = static_cast<int>(big.g);
      const int iv = static_cast<int>(rows[item].second);
      const float inv_gr = 1.0f / static_cast<float>(big.gr);
      for (int iu = 0; iu < g; ++iu) {
        // Cells wholly beyond the hypotenuse (u + v > 1 at their nearest corner) see no hit;
        // they stay kNoSurfel (the grid search answers a stray one) and cost nothing to build,
        // where their empty 3 x 3 neighbourhoods would scan the whole triangle.
        if (static_cast<double>(iu + iv) / static_cast<double>(g) > 1.0 + 1e-4) continue;
        cellCandidates(big, iu, iv, cand);
        if (cand.empty()) continue;
        for (std::uint32_t sv = 0; sv < r; ++sv) {
          const std::uint32_t fv = static_cast<std::uint32_t>(iv) * r + sv;
          for (std::uint32_t su = 0; su < r; ++su) {
            const std::uint32_t fu = static_cast<std::uint32_t>(iu) * r + su;
            if (static_cast<double>(fu + fv) / static_cast<double>(big.gr) > 1.0 + 1e-4) continue;
            // The raster cell's centre, evaluated as a hit there would be (rasterSize's rule):
            // the owner the scan gives there.
            const float uc = (static_cast<float>(fu) + 0.5f) * inv_gr, vc = (static_cast<float>(fv) + 0.5f) * inv_gr;
            raster_[big.first_raster + fv * big.gr + fu] = nearestCandidate(cand, big.v0 + uc * big.e1 + vc * big.e2);
          }
        }
      }
    }
  });
}

const SurfelLocator::BigTriangle* SurfelLocator::bigTriangle(std::uint32_t mesh, std::uint32_t triangle) const {
  const std::uint32_t t = globalTriangle(mesh, triangle);
  return t == kNoSurfel || big_of_tri_[t] == kNoSurfel ? nullptr : &big_[big_of_tri_[t]];
}

float SurfelLocator::rasterCellDiagonal(std::uint32_t mesh, std::uint32_t triangle) const {
  const BigTriangle* big = bigTriangle(mesh, triangle);
  if (!big) return 0.0f;
  // A raster cell is the parallelogram spanned by e1 / gr and e2 / gr.
  return std::max(glm::length(big->e1 + big->e2), glm::length(big->e1 - big->e2)) * (1.0f / static_cast<float>(big->gr));
}

std::uint32_t SurfelLocator::rasterSize(std::uint32_t mesh, std::uint32_t triangle) const {
  const BigTriangle* big = bigTriangle(mesh, triangle);
  return big ? big->gr : 0;
}

std::uint32_t SurfelLocator::ownerOfHitNearest(std::uint32_t mesh, std::uint32_t triangle, float u, float v,
                                               const glm::vec3& p, const glm::vec3& n) const {
  if (const BigTriangle* big = bigTriangle(mesh, triangle)) {
    const std::uint32_t s = scanBigTriangle(*big, u, v, p);
    if (s != kNoSurfel) return s;
  }
  return ownerOfHit(mesh, triangle, u, v, p, n);
}

std::uint32_t SurfelLocator::owner(const glm::vec3& p, const glm::vec3& n) const {
  if (ids_.empty()) return kNoSurfel;
  constexpr float kSameSide = 0.5f;  // cos 60 degrees
  std::uint32_t s = search(p, n, 1, kSameSide);
  if (s == kNoSurfel) s = search(p, n, 2, kSameSide);
  if (s == kNoSurfel) s = search(p, n, 1, -2.0f);
  return s;
}

}  // namespace lightlink::links
