// Error statistics of a baked irradiance against the reference (DESIGN.md sec 7, docs/quality.md):
// relative RMSE and the 95th percentile of the relative error over the compared points, the
// energy bias (mean baked / mean reference), and leak counts. Computed on luminance (Rec. 709
// weights) so one number summarises the three channels.
//
// Every point counts, black references included: the relative error of a point is
//   e = |b - r| / max(r, F),   F = floor_fraction * mean(r)   (default 5 % of the mean),
// so a point that the reference sees black but the bake lights reads as a large error instead
// of being dropped (a dark point's error is measured against a tenth of a typical light level
// of the scene, not against its own ~0). The old figures over lit points only (|b - r| / r where
// r > black_fraction * mean) stay as lit_rel_rmse / lit_p95_rel_error.
#pragma once

#include <cstddef>
#include <optional>
#include <span>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

namespace lightlink::reference {

struct ErrorOptions {
  // Absolute error floor F as a fraction of the mean reference luminance.
  double floor_fraction = 0.05;
  // A reference below black_fraction * mean counts as black in the lit-only figures.
  double black_fraction = 1e-3;
  // Leaks: the reference is ~0 (below dark_fraction * F) while the bake is above F; missing
  // light: the bake is ~0 while the reference is above F.
  double dark_fraction = 0.1;
  // The mean reference luminance the floor is a fraction of; unset = the mean of the points
  // given. Set it to the whole scene's mean when measuring a subset (the near-contact band),
  // so that the subset's errors are judged by the scene's light level.
  std::optional<double> floor_mean;
};

struct ErrorStats {
  std::size_t points = 0;        // compared
  std::size_t black_points = 0;  // reference below black_fraction * mean: not in the lit-only figures
  double rel_rmse = 0.0;         // sqrt(mean(e^2)), e = |b - r| / max(r, F), all points
  double p95_rel_error = 0.0;    // 95th percentile of e
  double max_rel_error = 0.0;
  double lit_rel_rmse = 0.0;       // over points with a reference above black: |b - r| / r (no floor)
  double lit_p95_rel_error = 0.0;
  double bias = 1.0;             // mean(b) / mean(r) over all points
  double mean_baked = 0.0, mean_reference = 0.0;
  double floor = 0.0;            // F, luminance
  std::size_t leaks = 0;         // baked above F where the reference is ~0
  std::size_t missing_light = 0; // reference above F where the bake is ~0

  nlohmann::ordered_json toJson() const;
};

inline float luminance(const glm::vec3& c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

ErrorStats errorStats(std::span<const glm::vec3> baked, std::span<const glm::vec3> reference,
                      const ErrorOptions& options = {});

// Per point: e = |b - r| / max(r, F) with F = floor_fraction * floor_mean (what the heat maps show).
float flooredRelError(const glm::vec3& baked, const glm::vec3& reference, double floor);

}  // namespace lightlink::reference
