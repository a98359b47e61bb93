// One measured point of the accuracy study (bench/accuracy/accuracy_study.cpp) and its two
// written forms: a CSV row with every column (docs/quality.md lists what they mean) and a
// JSON object for the summary. Errors are fractions (0.05 = 5 %), times in seconds or
// milliseconds as the field name says, memory in bytes.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "core/precompute/precompute.h"
#include "core/reference/compare.h"
#include "core/relight/relight.h"

namespace lightlink::bench {

struct Row {
  std::string scene, factor, value, error;
  precompute::PrecomputeOptions pre;
  relight::RelightOptions rel;
  int lightmap_resolution = 0;
  double texel_size_m = 0.0;
  std::size_t caches_valid = 0, links = 0;
  double links_per_cache = 0.0;
  int bounces_run = 0;
  int reference_bounces = -1;
  std::string bounce_stop;
  double precompute_s = 0.0, links_s = 0.0, relight_ms = 0.0;
  std::size_t link_bytes = 0, memory_bytes = 0;
  std::size_t ref_points = 0, mid_points = 0;
  double ref_noise_total = 0.0, ref_noise_indirect = 0.0;  // rms relative std error of the reference
  reference::ErrorStats total, indirect, mid_total, mid_indirect;
  double indirect_rmse_debiased = 0.0;  // after dividing the baked indirect by its bias
  bool sky = false;
  bool pareto_relight = false, pareto_precompute = false;
};

std::string_view formName(relight::LinkForm f);
// Indirect RMSE with the reference's own noise taken out (they add in quadrature).
double netRmse(double rmse, double noise);
std::string csvHeader();
std::string csvRow(const Row& r);
nlohmann::ordered_json rowJson(const Row& r);

}  // namespace lightlink::bench
