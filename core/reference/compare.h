// Error statistics of a baked irradiance against the reference (DESIGN.md sec 7): relative
// RMSE and the 95th percentile of the relative error over the compared points, and the
// energy bias (mean baked / mean reference). Computed on luminance (Rec. 709 weights) so one
// number summarises the three channels; points whose reference is (near) black are left
// out of the relative measures (their relative error is undefined) but counted.
#pragma once

#include <cstddef>
#include <span>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

namespace lightlink::reference {

struct ErrorStats {
  std::size_t points = 0;        // compared
  std::size_t black_points = 0;  // reference below the floor: not in the relative measures
  double rel_rmse = 0.0;         // sqrt(mean(((b - r) / r)^2))
  double p95_rel_error = 0.0;    // 95th percentile of |b - r| / r
  double max_rel_error = 0.0;
  double bias = 1.0;             // mean(b) / mean(r) over all points
  double mean_baked = 0.0, mean_reference = 0.0;

  nlohmann::ordered_json toJson() const;
};

inline float luminance(const glm::vec3& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

// `floor_fraction`: a reference value below floor_fraction * mean(reference) counts as black.
ErrorStats errorStats(std::span<const glm::vec3> baked, std::span<const glm::vec3> reference,
                      double floor_fraction = 1e-3);

}  // namespace lightlink::reference
