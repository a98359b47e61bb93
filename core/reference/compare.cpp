#include "core/reference/compare.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace lightlink::reference {

nlohmann::ordered_json ErrorStats::toJson() const {
  return {{"points", points},     {"black_points", black_points}, {"rel_rmse", rel_rmse},
          {"p95_rel_error", p95_rel_error}, {"max_rel_error", max_rel_error}, {"bias", bias},
          {"mean_baked", mean_baked}, {"mean_reference", mean_reference}};
}

ErrorStats errorStats(std::span<const glm::vec3> baked, std::span<const glm::vec3> reference,
                      double floor_fraction) {
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
  const double floor = floor_fraction * s.mean_reference;
  std::vector<double> rel;
  rel.reserve(n);
  double sq = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = luminance(reference[i]);
    if (!(r > floor)) {
      ++s.black_points;
      continue;
    }
    const double e = std::abs(double(luminance(baked[i])) - r) / r;
    rel.push_back(e);
    sq += e * e;
  }
  if (!rel.empty()) {
    s.rel_rmse = std::sqrt(sq / double(rel.size()));
    std::sort(rel.begin(), rel.end());
    s.p95_rel_error = rel[std::min(rel.size() - 1, static_cast<std::size_t>(0.95 * double(rel.size())))];
    s.max_rel_error = rel.back();
  }
  return s;
}

}  // namespace lightlink::reference
