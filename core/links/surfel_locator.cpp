#include "core/links/surfel_locator.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/common/aabb.h"

namespace lightlink::links {
namespace {
constexpr std::size_t kMaxCells = std::size_t(1) << 22;
}

SurfelLocator::SurfelLocator(const surfels::Surfels& surfels, const scene::Scene& scene) {
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
  buildTriangleLists(surfels, scene);
}

void SurfelLocator::buildTriangleLists(const surfels::Surfels& surfels, const scene::Scene& scene) {
  const std::size_t meshes = scene.meshes.size();
  mesh_first_.assign(meshes + 1, 0);
  for (std::size_t m = 0; m < meshes; ++m)
    mesh_first_[m + 1] = mesh_first_[m] + static_cast<std::uint32_t>(scene.meshes[m].triangleCount());
  const std::uint32_t tris = mesh_first_.back();
  std::vector<std::uint32_t> count(tris, 0);
  const std::size_t n = surfels.size();
  for (std::size_t i = 0; i < n; ++i) {
    if (surfels.mesh[i] >= meshes) continue;
    ++count[mesh_first_[surfels.mesh[i]] + surfels.triangle[i]];
  }
  tri_use_grid_.assign(tris, 0);
  tri_begin_.assign(tris + 1, 0);
  for (std::uint32_t t = 0; t < tris; ++t) {
    std::uint32_t c = count[t];
    if (c > kTriangleListMax) {
      tri_use_grid_[t] = 1;
      c = 0;
    }
    // An empty triangle gets one entry (its nearest surfel), filled below.
    tri_begin_[t + 1] = tri_begin_[t] + (c == 0 && !tri_use_grid_[t] ? 1 : c);
  }
  tri_surfel_.assign(tri_begin_.back(), kNoSurfel);
  tri_position_.assign(tri_begin_.back(), glm::vec3(0.0f));
  std::vector<std::uint32_t> fill(tri_begin_.begin(), tri_begin_.end() - 1);
  for (std::size_t i = 0; i < n; ++i) {
    if (surfels.mesh[i] >= meshes) continue;
    const std::uint32_t t = mesh_first_[surfels.mesh[i]] + surfels.triangle[i];
    if (tri_use_grid_[t]) continue;
    tri_surfel_[fill[t]] = static_cast<std::uint32_t>(i);
    tri_position_[fill[t]] = surfels.position[i];
    ++fill[t];
  }
  // Big triangles: bin their surfels by barycentric cell.
  big_of_tri_.assign(tris, kNoSurfel);
  std::vector<std::uint32_t> cell_count;
  std::vector<std::uint32_t> big_mesh, big_triangle;
  for (std::size_t m = 0; m < meshes; ++m) {
    for (std::uint32_t tri = 0; tri < scene.meshes[m].triangleCount(); ++tri) {
      const std::uint32_t t = mesh_first_[m] + tri;
      if (!tri_use_grid_[t]) continue;
      BigTriangle big;
      big.g = static_cast<std::uint32_t>(std::ceil(std::sqrt(double(count[t]))));
      big.first_cell = static_cast<std::uint32_t>(cell_count.size());
      big_of_tri_[t] = static_cast<std::uint32_t>(big_.size());
      big_.push_back(big);
      big_mesh.push_back(static_cast<std::uint32_t>(m));
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
    if (surfels.mesh[i] >= meshes) continue;
    const std::uint32_t t = mesh_first_[surfels.mesh[i]] + surfels.triangle[i];
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
  buildFineLists(scene, big_mesh, big_triangle);

  // Triangles too small to hold a surfel of their own (their area went into a neighbour's
  // slice) are represented by the surfel nearest to their centroid.
  for (std::size_t m = 0; m < meshes; ++m) {
    const auto& mesh = scene.meshes[m];
    for (std::uint32_t tri = 0; tri < mesh.triangleCount(); ++tri) {
      const std::uint32_t t = mesh_first_[m] + tri;
      if (tri_use_grid_[t] || count[t] != 0) continue;
      const glm::vec3 p0 = mesh.positions[mesh.indices[3 * tri]], p1 = mesh.positions[mesh.indices[3 * tri + 1]],
                      p2 = mesh.positions[mesh.indices[3 * tri + 2]];
      const glm::vec3 c = (p0 + p1 + p2) / 3.0f;
      glm::vec3 nrm = glm::cross(p1 - p0, p2 - p0);
      const float len = glm::length(nrm);
      nrm = len > 0.0f ? nrm / len : glm::vec3(0.0f, 0.0f, 1.0f);
      const std::uint32_t s = owner(c, nrm);
      tri_surfel_[tri_begin_[t]] = s;
      tri_position_[tri_begin_[t]] = s == kNoSurfel ? c : surfels.position[s];
    }
  }
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

std::uint32_t SurfelLocator::scanBigTriangle(const BigTriangle& big, float u, float v, const glm::vec3& p) const {
  const auto g = static_cast<int>(big.g);
  const int iu = std::clamp(static_cast<int>(u * float(g)), 0, g - 1);
  const int iv = std::clamp(static_cast<int>(v * float(g)), 0, g - 1);
  std::uint32_t best = kNoSurfel;
  float best_d2 = std::numeric_limits<float>::infinity();
  // 3 x 3 cells first; if they are all empty (a hole in the surfel cover), the whole triangle.
  for (int radius : {1, g}) {
    for (int cv = std::max(0, iv - radius); cv <= std::min(g - 1, iv + radius); ++cv) {
      const std::uint32_t row = big.first_cell + static_cast<std::uint32_t>(cv * g);
      const std::uint32_t begin = big_cell_begin_[row + static_cast<std::uint32_t>(std::max(0, iu - radius))];
      const std::uint32_t end = big_cell_begin_[row + static_cast<std::uint32_t>(std::min(g - 1, iu + radius)) + 1];
      for (std::uint32_t k = begin; k < end; ++k) {
        const glm::vec3 d = big_position_[k] - p;
        const float d2 = glm::dot(d, d);
        if (d2 < best_d2) {
          best_d2 = d2;
          best = big_surfel_[k];
        }
      }
    }
    if (best != kNoSurfel) break;
  }
  return best;
}

std::uint32_t SurfelLocator::ownerOnBigTriangle(const BigTriangle& big, float u, float v, const glm::vec3& p) const {
  // The fine lists were proven for (u, v) in [-kBaryCheck, 1 + kBaryCheck]^2 and hit points
  // within max_offset of P(u, v); NaN fails the test too and takes the full scan.
  const glm::vec3 off = p - (big.v0 + u * big.e1 + v * big.e2);
  const float off_max = std::max(std::abs(off.x), std::max(std::abs(off.y), std::abs(off.z)));
  if (u >= -kBaryCheck && v >= -kBaryCheck && u <= 1.0f + kBaryCheck && v <= 1.0f + kBaryCheck &&
      off_max <= big.max_offset) {
    const auto gf = static_cast<int>(big.g * kFine);
    const int fu = std::clamp(static_cast<int>(u * float(gf)), 0, gf - 1);
    const int fv = std::clamp(static_cast<int>(v * float(gf)), 0, gf - 1);
    const std::uint32_t cell = big.first_fine + static_cast<std::uint32_t>(fv * gf + fu);
    const std::uint32_t begin = fine_begin_[cell], end = fine_begin_[cell + 1];
    if (begin != end) {
      // Same arithmetic and order as scanBigTriangle over the surviving candidates.
      std::uint32_t best = fine_candidate_[begin];
      glm::vec3 d = big_position_[best] - p;
      float best_d2 = glm::dot(d, d);
      for (std::uint32_t k = begin + 1; k < end; ++k) {
        const std::uint32_t c = fine_candidate_[k];
        d = big_position_[c] - p;
        const float d2 = glm::dot(d, d);
        if (d2 < best_d2) {
          best_d2 = d2;
          best = c;
        }
      }
      return big_surfel_[best];
    }
  }
  return scanBigTriangle(big, u, v, p);
}

void SurfelLocator::buildFineLists(const scene::Scene& scene, const std::vector<std::uint32_t>& big_mesh,
                                   const std::vector<std::uint32_t>& big_triangle) {
  // Per big triangle, its fine cells' candidate lists; built in parallel, concatenated in
  // triangle order (the result does not depend on the thread count).
  struct Lists {
    std::vector<std::uint32_t> count;  // per fine cell
    std::vector<std::uint32_t> candidate;  // indices into big_position_ / big_surfel_
  };
  std::vector<Lists> lists(big_.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, big_.size(), 1), [&](const tbb::blocked_range<std::size_t>& r) {
    std::vector<std::uint32_t> cand;
    std::vector<glm::dvec4> corner_d2;  // per candidate: squared distance to the 4 corners
    std::vector<double> reach;          // per candidate: largest distance to a corner
    for (std::size_t b = r.begin(); b < r.end(); ++b) {
      BigTriangle& big = big_[b];
      const scene::MeshInstance& mesh = scene.meshes[big_mesh[b]];
      const std::uint32_t tri = big_triangle[b];
      const glm::vec3 p0 = mesh.positions[mesh.indices[3 * tri]], p1 = mesh.positions[mesh.indices[3 * tri + 1]],
                      p2 = mesh.positions[mesh.indices[3 * tri + 2]];
      big.v0 = p0;
      big.e1 = p1 - p0;
      big.e2 = p2 - p0;
      const auto g = static_cast<int>(big.g);
      const int gf = g * static_cast<int>(kFine);
      auto maxAbs = [](const glm::vec3& x) { return std::max(std::abs(x.x), std::max(std::abs(x.y), std::abs(x.z))); };
      // Hits may lie off P(u, v) by float error of the hit point (relative to the
      // coordinates) and of Embree's (u, v) and t; 1 % of a fine cell covers it with room.
      // A hit further off takes the full scan, so this is a speed choice, not a correctness one.
      const float fine_size = std::max(maxAbs(big.e1), maxAbs(big.e2)) / float(gf);
      const float coord = std::max(maxAbs(p0), std::max(maxAbs(p1), maxAbs(p2)));
      big.max_offset = 0.01f * fine_size + 1e-6f * coord;
      // Lists are proven for points within eps of the exact P(u, v): the query's offset test
      // (with its own rounding) plus the float evaluation of v0 + u e1 + v e2.
      const double eps = 1.001 * double(big.max_offset) +
                         1e-6 * (double(maxAbs(big.v0)) + double(maxAbs(big.e1)) + double(maxAbs(big.e2)));
      const glm::dvec3 d0(p0), d1(p1), d2(p2);
      auto at = [&](double u, double v) { return (1.0 - u - v) * d0 + u * d1 + v * d2; };
      const double margin = double(kBaryCheck) * 2.0 + 1e-3 / double(gf);  // > kBaryCheck and (u, v) rounding

      Lists& out = lists[b];
      out.count.assign(std::size_t(gf) * std::size_t(gf), 0);
      for (int fv = 0; fv < gf; ++fv) {
        for (int fu = 0; fu < gf; ++fu) {
          const double ulo = double(fu) / gf - margin, uhi = double(fu + 1) / gf + margin;
          const double vlo = double(fv) / gf - margin, vhi = double(fv + 1) / gf + margin;
          // Wholly beyond the hypotenuse: no hit lands here; left empty (full scan).
          if (ulo + vlo > 1.0 + margin) continue;
          // The cell's candidates, exactly as scanBigTriangle collects them (ascending index).
          const int iu = fu / static_cast<int>(kFine), iv = fv / static_cast<int>(kFine);
          cand.clear();
          for (int radius : {1, g}) {
            for (int cv = std::max(0, iv - radius); cv <= std::min(g - 1, iv + radius); ++cv) {
              const std::uint32_t row = big.first_cell + static_cast<std::uint32_t>(cv * g);
              const std::uint32_t begin = big_cell_begin_[row + static_cast<std::uint32_t>(std::max(0, iu - radius))];
              const std::uint32_t end =
                  big_cell_begin_[row + static_cast<std::uint32_t>(std::min(g - 1, iu + radius)) + 1];
              for (std::uint32_t k = begin; k < end; ++k) cand.push_back(k);
            }
            if (!cand.empty()) break;
          }
          const std::array<glm::dvec3, 4> corner = {at(ulo, vlo), at(uhi, vlo), at(ulo, vhi), at(uhi, vhi)};
          const glm::dvec3 centre = at(0.5 * (ulo + uhi), 0.5 * (vlo + vhi));
          corner_d2.resize(cand.size());
          reach.resize(cand.size());
          // Dominator candidates: the nearest at the centre and at each corner.
          std::array<std::size_t, 5> best{};
          std::array<double, 5> best_d2;
          best_d2.fill(std::numeric_limits<double>::infinity());
          for (std::size_t k = 0; k < cand.size(); ++k) {
            const glm::dvec3 q(big_position_[cand[k]]);
            double far_d2 = 0.0;
            for (int c = 0; c < 4; ++c) {
              const glm::dvec3 d = corner[std::size_t(c)] - q;
              corner_d2[k][c] = glm::dot(d, d);
              far_d2 = std::max(far_d2, corner_d2[k][c]);
              if (corner_d2[k][c] < best_d2[std::size_t(c)]) {
                best_d2[std::size_t(c)] = corner_d2[k][c];
                best[std::size_t(c)] = k;
              }
            }
            const glm::dvec3 dc = centre - q;
            if (glm::dot(dc, dc) < best_d2[4]) {
              best_d2[4] = glm::dot(dc, dc);
              best[4] = k;
            }
            reach[k] = std::sqrt(far_d2) + std::sqrt(3.0) * eps;
          }
          std::uint32_t kept = 0;
          for (std::size_t j = 0; j < cand.size(); ++j) {
            bool dominated = false;
            for (std::size_t i : best) {
              if (i == j) continue;
              // |x - q_j|^2 - |x - q_i|^2 is affine in x: its least value over the cell is at a
              // corner, less at most 2 eps |q_i - q_j|_1 for a point eps off. It must exceed the
              // float rounding of both squared distances (< 3e-7 each, relative) by a margin.
              double least = std::numeric_limits<double>::infinity();
              for (int c = 0; c < 4; ++c) least = std::min(least, corner_d2[j][c] - corner_d2[i][c]);
              const glm::dvec3 qi(big_position_[cand[i]]), qj(big_position_[cand[j]]);
              const double l1 = std::abs(qi.x - qj.x) + std::abs(qi.y - qj.y) + std::abs(qi.z - qj.z);
              const double r = std::max(reach[i], reach[j]);
              if (least - 2.0 * eps * l1 > 2e-6 * r * r) {
                dominated = true;
                break;
              }
            }
            if (dominated) continue;
            out.candidate.push_back(cand[j]);
            ++kept;
          }
          out.count[std::size_t(fv) * std::size_t(gf) + std::size_t(fu)] = kept;
        }
      }
    }
  });
  std::size_t cells = 0, total = 0;
  for (const Lists& l : lists) {
    cells += l.count.size();
    total += l.candidate.size();
  }
  fine_begin_.assign(cells + 1, 0);
  fine_candidate_.reserve(total);
  std::size_t cell = 0;
  for (std::size_t b = 0; b < big_.size(); ++b) {
    big_[b].first_fine = static_cast<std::uint32_t>(cell);
    for (std::uint32_t c : lists[b].count) {
      fine_begin_[cell + 1] = fine_begin_[cell] + c;
      ++cell;
    }
    fine_candidate_.insert(fine_candidate_.end(), lists[b].candidate.begin(), lists[b].candidate.end());
    lists[b] = Lists();
  }
}

std::size_t SurfelLocator::fineListCount() const {
  std::size_t lists = 0;
  for (std::size_t c = 0; c + 1 < fine_begin_.size(); ++c) lists += fine_begin_[c + 1] != fine_begin_[c] ? 1 : 0;
  return lists;
}

double SurfelLocator::meanFineListLength() const {
  const std::size_t lists = fineListCount();
  return lists == 0 ? 0.0 : static_cast<double>(fine_candidate_.size()) / static_cast<double>(lists);
}

template <bool kExhaustive>
std::uint32_t SurfelLocator::ownerOfHitImpl(std::uint32_t mesh, std::uint32_t triangle, float u, float v,
                                            const glm::vec3& p, const glm::vec3& n) const {
  if (mesh + 1 < mesh_first_.size()) {
    const std::uint32_t t = mesh_first_[mesh] + triangle;
    if (t < big_of_tri_.size() && big_of_tri_[t] != kNoSurfel) {
      const BigTriangle& big = big_[big_of_tri_[t]];
      const std::uint32_t s = kExhaustive ? scanBigTriangle(big, u, v, p) : ownerOnBigTriangle(big, u, v, p);
      if (s != kNoSurfel) return s;
    }
    if (t < tri_use_grid_.size() && !tri_use_grid_[t]) {
      std::uint32_t best = kNoSurfel;
      float best_d2 = std::numeric_limits<float>::infinity();
      for (std::uint32_t k = tri_begin_[t]; k < tri_begin_[t + 1]; ++k) {
        if (tri_surfel_[k] == kNoSurfel) break;
        const glm::vec3 d = tri_position_[k] - p;
        const float d2 = glm::dot(d, d);
        if (d2 < best_d2) {
          best_d2 = d2;
          best = tri_surfel_[k];
        }
      }
      if (best != kNoSurfel) return best;
    }
  }
  return owner(p, n);
}

std::uint32_t SurfelLocator::ownerOfHit(std::uint32_t mesh, std::uint32_t triangle, float u, float v,
                                        const glm::vec3& p, const glm::vec3& n) const {
  return ownerOfHitImpl<false>(mesh, triangle, u, v, p, n);
}

std::uint32_t SurfelLocator::ownerOfHitExhaustive(std::uint32_t mesh, std::uint32_t triangle, float u, float v,
                                                  const glm::vec3& p, const glm::vec3& n) const {
  return ownerOfHitImpl<true>(mesh, triangle, u, v, p, n);
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
