#include "bench/accuracy/rows.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace lightlink::bench {

std::string_view formName(relight::LinkForm f) { return relight::linkFormName(f); }

double netRmse(double rmse, double noise) { return std::sqrt(std::max(0.0, rmse * rmse - noise * noise)); }

std::string csvHeader() {
  return "scene,factor,value,surfels,links,bands,rays,builder,target_resolution,lightmap_resolution,texel_size_m,"
         "caches_valid,link_form,out_bands,max_bounces,bounces_run,bounce_stop,precompute_s,links_s,relight_ms,"
         "links_total,links_per_cache,link_bytes,memory_bytes,ref_points,ref_noise_total,ref_noise_indirect,"
         "total_rmse,total_p95,total_bias,indirect_rmse,indirect_rmse_net,indirect_rmse_debiased,indirect_p95,indirect_bias,mid_points,"
         "mid_total_rmse,mid_indirect_rmse,mid_indirect_p95,reference_bounces,sky,pareto_relight,pareto_precompute,error\n";
}

std::string csvRow(const Row& r) {
  return fmt::format(
      "{},{},{},{},{},{},{},{},{},{},{:.5g},{},{},{},{},{},{},{:.3f},{:.3f},{:.3f},{},{:.2f},{},{},{},{:.5f},{:.5f},"
      "{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{:.5f},{},{:.5f},{:.5f},{:.5f},{},{},{},{},{}\n",
      r.scene, r.factor, r.value, r.pre.surfels, r.pre.links, r.pre.bands, r.pre.rays,
      hierarchy::builderName(r.pre.builder), r.pre.target_resolution,
      r.lightmap_resolution, r.texel_size_m, r.caches_valid, formName(r.rel.link_form),
      r.rel.bands ? r.rel.bands : r.pre.bands, r.rel.max_bounces, r.bounces_run, r.bounce_stop, r.precompute_s,
      r.links_s, r.relight_ms, r.links, r.links_per_cache, r.link_bytes, r.memory_bytes, r.ref_points,
      r.ref_noise_total, r.ref_noise_indirect, r.total.rel_rmse, r.total.p95_rel_error, r.total.bias,
      r.indirect.rel_rmse, netRmse(r.indirect.rel_rmse, r.ref_noise_indirect), r.indirect_rmse_debiased, r.indirect.p95_rel_error,
      r.indirect.bias, r.mid_points, r.mid_total.rel_rmse, r.mid_indirect.rel_rmse, r.mid_indirect.p95_rel_error,
      r.reference_bounces, r.sky ? 1 : 0, r.pareto_relight ? 1 : 0, r.pareto_precompute ? 1 : 0, r.error);
}

nlohmann::ordered_json rowJson(const Row& r) {
  nlohmann::ordered_json j;
  j["factor"] = r.factor;
  j["value"] = r.value;
  if (!r.error.empty()) {
    j["error"] = r.error;
    return j;
  }
  j["options"] = r.pre.canonical();
  j["link_form"] = formName(r.rel.link_form);
  j["out_bands"] = r.rel.bands ? r.rel.bands : r.pre.bands;
  j["max_bounces"] = r.rel.max_bounces;
  j["reference_bounces"] = r.reference_bounces;
  j["bounces_run"] = r.bounces_run;
  j["caches_valid"] = r.caches_valid;
  j["precompute_s"] = r.precompute_s;
  j["relight_ms"] = r.relight_ms;
  j["link_bytes"] = r.link_bytes;
  j["memory_bytes"] = r.memory_bytes;
  j["reference_noise"] = {{"total", r.ref_noise_total}, {"indirect", r.ref_noise_indirect}};
  j["centres"] = {{"total", r.total.toJson()}, {"indirect", r.indirect.toJson()}};
  j["midpoints"] = {{"total", r.mid_total.toJson()}, {"indirect", r.mid_indirect.toJson()}};
  j["indirect_rmse_net"] = netRmse(r.indirect.rel_rmse, r.ref_noise_indirect);
  j["indirect_rmse_debiased"] = r.indirect_rmse_debiased;
  j["pareto"] = {{"relight", r.pareto_relight}, {"precompute", r.pareto_precompute}};
  return j;
}

}  // namespace lightlink::bench
