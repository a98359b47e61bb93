#include "core/links/surfel_locator.h"

#include <algorithm>
#include <cmath>

#include "core/common/aabb.h"

namespace lightlink::links {
namespace {
constexpr std::size_t kMaxCells = std::size_t(1) << 22;
}

SurfelLocator::SurfelLocator(const surfels::Surfels& surfels) {
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
  // the true owner inside the 27-cell neighbourhood even after relaxation.
  const float spacing = static_cast<float>(std::sqrt(area / static_cast<double>(n)));
  const glm::vec3 extent = glm::max(box.extent(), glm::vec3(1e-6f));
  cell_ = std::max(spacing, 1e-6f * glm::length(extent));
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

std::uint32_t SurfelLocator::owner(const glm::vec3& p, const glm::vec3& n) const {
  if (ids_.empty()) return kNoSurfel;
  constexpr float kSameSide = 0.5f;  // cos 60 degrees
  std::uint32_t s = search(p, n, 1, kSameSide);
  if (s == kNoSurfel) s = search(p, n, 2, kSameSide);
  if (s == kNoSurfel) s = search(p, n, 1, -2.0f);
  return s;
}

}  // namespace lightlink::links
