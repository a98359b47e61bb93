// Axis-aligned bounding box in whatever frame its points are in (world, unless named).
// Empty boxes have min > max, so growing the first point gives a degenerate box at it.
#pragma once

#include <limits>

#include <glm/glm.hpp>

namespace lightlink {

struct Aabb {
  glm::vec3 min{std::numeric_limits<float>::max()};
  glm::vec3 max{std::numeric_limits<float>::lowest()};

  bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
  void grow(const glm::vec3& p) {
    min = glm::min(min, p);
    max = glm::max(max, p);
  }
  void grow(const Aabb& b) {
    min = glm::min(min, b.min);
    max = glm::max(max, b.max);
  }
  glm::vec3 extent() const { return empty() ? glm::vec3(0.0f) : max - min; }
  glm::vec3 center() const { return 0.5f * (min + max); }
  float diagonal() const { return glm::length(extent()); }
};

}  // namespace lightlink
