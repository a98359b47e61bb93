#include "core/reference/compare.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace lightlink::reference {
namespace {

double percentile95(std::vector<double>& v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(0.95 * double(v.size())))];
}

}  // namespace

nlohmann::ordered_json ErrorStats::toJson() const {
  return {{"points", points},
          {"rel_rmse", rel_rmse},
          {"p95_rel_error", p95_rel_error},
          {"max_rel_error", max_rel_error},
          {"bias", bias},
          {"mean_baked", mean_baked},
          {"mean_reference", mean_reference},
          {"error_floor", floor},
          {"leaks", leaks},
          {"missing_light", missing_light},
          {"black_points", black_points},
          {"lit_rel_rmse", lit_rel_rmse},
          {"lit_p95_rel_error", lit_p95_rel_error}};
}

float flooredRelError(const glm::vec3& baked, const glm::vec3& reference, double floor) {
  const double r = luminance(reference);
  const double d = std::max(r, floor);
  const double diff = std::abs(double(luminance(baked)) - r);
  return d > 0.0 ? float(diff / d) : (diff > 0.0 ? INFINITY : 0.0f);
}

ErrorStats errorStats(std::span<const glm::vec3> baked, std::span<const glm::vec3> reference,
                      const ErrorOptions& options) {
  ErrorStats s;
  const std::size_t n = std::min(baked.size(), reference.size());
  s.points = n;
  if (n == 0) return s;
  double sum_b = 0.0, sum_r = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    sum_b += luminance(baked[i]);
    sum_r += luminance(reference[i]);
  }
  s.mean_baked = sum_b / double(n);
  s.mean_reference = sum_r / double(n);
  s.bias = sum_r > 0.0 ? sum_b / sum_r : (sum_b > 0.0 ? INFINITY : 1.0);
  const double mean = options.floor_mean.value_or(s.mean_reference);
  s.floor = options.floor_fraction * mean;
  const double black = options.black_fraction * mean;
  const double dark = options.dark_fraction * s.floor;
  std::vector<double> all, lit;
  all.reserve(n);
  double sq = 0.0, lit_sq = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = luminance(reference[i]), b = luminance(baked[i]);
    const double e = flooredRelError(baked[i], reference[i], s.floor);
    all.push_back(e);
    sq += e * e;
    if (r < dark && b > s.floor) ++s.leaks;
    if (b < dark && r > s.floor) ++s.missing_light;
    if (!(r > black)) {
      ++s.black_points;
      continue;
    }
    const double le = std::abs(b - r) / r;
    lit.push_back(le);
    lit_sq += le * le;
  }
  s.rel_rmse = std::sqrt(sq / double(n));
  s.p95_rel_error = percentile95(all);
  s.max_rel_error = all.back();
  if (!lit.empty()) {
    s.lit_rel_rmse = std::sqrt(lit_sq / double(lit.size()));
    s.lit_p95_rel_error = percentile95(lit);
  }
  return s;
}

}  // namespace lightlink::reference
