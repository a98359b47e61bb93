// precompute_bench: docs/results.md "Precompute" figures in one run per scene.
//
//  - time per precompute stage and memory per structure (seed 000 Table 4);
//  - link generation throughput as a ratio to raw Embree throughput on the *same rays*
//    (links::LinkRays regenerates exactly the rays link generation traced), measured in the
//    same process right after the precompute (target >= 0.7), and again as the median of
//    --pairs (default 3) back-to-back runs of link generation and raw Embree on the same caches.
//    Raw Embree is timed twice: through the call link generation makes (Accel::intersectFan:
//    the headline ratio) and through the Foundation benchmark's rt::Ray / rt::Hit packet call;
//  - HAC build time vs kd build time on the same surfels;
//  - the owner lookup's build time and raster size (links::SurfelLocator).
// Usage: precompute_bench [--scene F] [--subdivide N] [--surfels N] [--links N] [--bands B]
//                         [--rays N] [--resolution R] [--hierarchy hac|fast] [--pairs N] [--json OUT]
//                         [--hit-credit best|scalar]
// --hit-credit scalar makes the pairs' link generation use the scalar hit-credit kernel on a
// CPU with AVX-512 too: the two kernels timed with one binary (docs/results.md).
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include "bench/common/bench_common.h"
#include "bench/rt/throughput.h"
#include "core/common/memory.h"
#include "core/links/surfel_locator.h"
#include "core/precompute/precompute.h"
#include "core/scene/load.h"
#include "core/scene/subdivide.h"

static_assert(lightlink::links::kPhaseProbes, "precompute_bench reports phase shares: configure with LIGHTLINK_PROBES=ON");

namespace {

using namespace lightlink;

struct Args {
  std::string scene;
  std::string json;
  int subdivide = 0;
  int pairs = 3;  // interleaved (link generation, raw Embree) pairs after the precompute
  links::HitCreditKernel hit_credit = links::HitCreditKernel::kBest;  // for the pairs
  precompute::PrecomputeOptions options;
};

bool parse(int argc, char** argv, Args& a) {
  a.scene = std::string(LIGHTLINK_SOURCE_DIR) + "/clients/demo/cornell_box.gltf";
  a.options.lightmap_resolution = bench::kMediumResolution;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (i + 1 >= argc) return false;
    const char* v = argv[++i];
    if (k == "--scene") a.scene = v;
    else if (k == "--json") a.json = v;
    else if (k == "--subdivide") a.subdivide = std::stoi(v);
    else if (k == "--pairs") a.pairs = std::max(0, std::stoi(v));
    else if (k == "--hit-credit" && (std::strcmp(v, "best") == 0 || std::strcmp(v, "scalar") == 0))
      a.hit_credit = std::strcmp(v, "scalar") == 0 ? links::HitCreditKernel::kScalar : links::HitCreditKernel::kBest;
    else if (!bench::parsePrecomputeFlag(k, v, a.options)) return false;
  }
  return true;
}

// The kernel the pairs' link generation runs.
const char* hitCreditName(links::HitCreditKernel k) {
  return links::hitCreditKernelRun(k) == links::HitCreditKernel::kAvx512 ? "avx512" : "scalar";
}

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (!parse(argc, argv, args)) {
    std::fprintf(stderr, "usage: precompute_bench [--scene F] [--subdivide N] [--surfels N] [--links N] "
                         "[--bands B] [--rays N] [--resolution R] [--hierarchy hac|fast] [--pairs N] [--json OUT] "
                         "[--hit-credit best|scalar]\n");
    return 1;
  }
  // Link runs after the first reuse the pages of the one before (core/common/memory.h).
  const HugeBlockCacheScope huge_blocks;
  auto scene = scene::loadScene(args.scene);
  if (bench::failed(scene)) return 2;
  scene::subdivide(*scene, args.subdivide);
  const std::size_t triangles = scene->triangleCount();
  auto p = precompute::run(*scene, args.options);
  if (bench::failed(p)) return 2;
  auto report = p->report();

  // Raw Embree on the same rays: the rays the lightmap links traced, 16-ray packets, all
  // threads, the same BVH build options as precompute. Rays and hits take 64 bytes each, so
  // past kMaxRawRays (4 GiB of them; zdm2 at 512² is 58 M rays) the pass takes every k-th
  // block of 32 caches (link generation's chunk), enough to time throughput on a 24 GiB
  // machine where all 451 M rays of zdm2 x4 at 1024² would not fit.
  constexpr std::size_t kMaxRawRays = std::size_t(1) << 26;
  constexpr std::size_t kBlock = 32;
  auto accel = rt::Accel::build(*scene);
  links::LinkOptions lo = args.options.linkOptions();
  lo.hit_credit = args.hit_credit;
  const links::LinkRays pattern(lo);
  const std::uint32_t per_cache = pattern.count();
  const std::size_t caches = p->lightmap.size();
  const std::size_t all_rays = std::size_t(per_cache) * caches;
  const std::size_t stride = std::max<std::size_t>(1, (all_rays + kMaxRawRays - 1) / kMaxRawRays);
  std::vector<std::size_t> sampled;
  for (std::size_t b = 0; b * kBlock < caches; b += stride)
    for (std::size_t c = b * kBlock; c < std::min(caches, (b + 1) * kBlock); ++c) sampled.push_back(c);
  // The same rays twice: as fans (one origin, direction arrays), traced the way link
  // generation traces them (Accel::intersectFan), and as rt::Ray records through the
  // general batched call (Accel::intersect, 16-ray packets) that the Foundation benchmark
  // (bench/rt) measures. The fan call converts less per ray, so it is the faster and
  // stricter yardstick: the headline ratio.
  std::vector<rt::Ray> rays(std::size_t(per_cache) * sampled.size());
  bench::FanSet fans;
  fans.per_fan = per_cache;
  for (auto* a : {&fans.x, &fans.y, &fans.z}) a->resize(rays.size());
  for (std::size_t k = 0; k < sampled.size(); ++k) {
    const std::size_t c = sampled[k];
    pattern.generate(*accel, c, p->lightmap.position[c], p->lightmap.normal[c],
                     std::span<rt::Ray>(rays.data() + k * per_cache, per_cache));
    const links::LinkRays::Directions d{fans.x.data() + k * per_cache, fans.y.data() + k * per_cache,
                                        fans.z.data() + k * per_cache};
    fans.origin.push_back(pattern.fan(*accel, c, p->lightmap.position[c], p->lightmap.normal[c], d).origin);
  }
  bench::ThroughputOptions to;
  to.api = bench::RayApi::kPacket16;
  to.threads = 0;
  to.chunk = per_cache * 32;  // link generation's chunk of 32 caches
  const auto raw_fan = bench::measureFanThroughput(*accel, fans, to);
  const auto raw = bench::measureThroughput(*accel, rays, to);
  const double link_rps = report["links"]["lightmap"]["rays_per_second"].get<double>();
  const double raw_rps = raw_fan.raysPerSecond();
  const double raw_api_rps = raw.raysPerSecond();
  if (raw_fan.hits != raw.hits) {
    std::fprintf(stderr, "the fan and the ray-record passes disagree: %zu against %zu hits\n", raw_fan.hits, raw.hits);
    return 2;
  }

  // The precompute's link time and the raw pass above are seconds apart; on a shared machine
  // the load between them moves their ratio by 30 %. So also time `pairs` back-to-back pairs
  // of (link generation over the sampled caches, raw Embree over exactly their rays) and
  // report the median of the pairs' ratios: the figure that docs/results.md quotes.
  std::vector<glm::vec3> sampled_position, sampled_normal;
  for (std::size_t c : sampled) {
    sampled_position.push_back(p->lightmap.position[c]);
    sampled_normal.push_back(p->lightmap.normal[c]);
  }
  // The owner lookup, as the precompute builds it: once, as its own stage ("owners"), not
  // part of the link time, as the BVH build is not part of the raw time. Timed here alone.
  auto t0 = std::chrono::steady_clock::now();
  const links::SurfelLocator locator(p->surfels, *scene);
  const double locator_s = seconds(t0);
  nlohmann::ordered_json pair_rows = nlohmann::ordered_json::array();
  std::vector<double> pair_ratios, pair_api_ratios, pair_outside;
  // Link generation's phases summed over the pairs: shares, and timer ticks per cache (rdtsc
  // on x86: a phase's own cost, steadier between runs than its share, which moves with the
  // tracing's noise; for A/B runs of one phase).
  std::array<std::uint64_t, links::kLinkPhases> pair_phase_ticks{};
  for (int k = 0; k < args.pairs; ++k) {
    auto l = links::generateLinks(*scene, *accel, locator, p->tree, {sampled_position, sampled_normal}, lo);
    if (bench::failed(l)) return 2;
    const double lrps = l->stats.seconds > 0 ? double(l->stats.rays) / l->stats.seconds : 0.0;
    const double rrps = bench::measureFanThroughput(*accel, fans, to).raysPerSecond();
    const double arps = bench::measureThroughput(*accel, rays, to).raysPerSecond();
    pair_ratios.push_back(rrps > 0 ? lrps / rrps : 0.0);
    pair_api_ratios.push_back(arps > 0 ? lrps / arps : 0.0);
    for (int q = 0; q < links::kLinkPhases; ++q) pair_phase_ticks[q] += l->stats.phase_ticks[q];
    // The share of the link run's wall time (on every thread) that its phases do not account
    // for: the output's page faults, the pipeline's waits, the threads' start.
    const double phase_seconds = double(l->stats.totalPhaseTicks()) / links::linkPhaseTicksPerSecond();
    const double busy = double(tbb::this_task_arena::max_concurrency()) * l->stats.seconds;
    pair_outside.push_back(busy > 0 ? 1.0 - phase_seconds / busy : 0.0);
    pair_rows.push_back({{"link_rays_per_second", lrps},
                         {"raw_rays_per_second", rrps},
                         {"ratio", pair_ratios.back()},
                         {"raw_ray_api_rays_per_second", arps},
                         {"ratio_to_ray_api", pair_api_ratios.back()},
                         {"outside_phases_share", pair_outside.back()}});
  }
  double phase_total = 0.0;
  for (const std::uint64_t t : pair_phase_ticks) phase_total += double(t);
  nlohmann::ordered_json pair_phase_share = nlohmann::ordered_json::object();
  for (int q = 0; q < links::kLinkPhases; ++q)
    pair_phase_share[links::kLinkPhaseNames[q]] = phase_total > 0 ? double(pair_phase_ticks[q]) / phase_total : 0.0;
  nlohmann::ordered_json pair_phase_ticks_per_cache = nlohmann::ordered_json::object();
  const double pair_caches = double(args.pairs) * double(sampled_position.size());
  for (int q = 0; q < links::kLinkPhases; ++q)
    pair_phase_ticks_per_cache[links::kLinkPhaseNames[q]] = pair_caches > 0 ? double(pair_phase_ticks[q]) / pair_caches : 0.0;
  const double pair_trace = double(pair_phase_ticks[links::kPhaseTrace]);
  const double pair_own_work = pair_trace > 0 ? (phase_total - pair_trace) / pair_trace : 0.0;
  const double median_ratio = bench::median(pair_ratios);
  const double median_api_ratio = bench::median(pair_api_ratios);


  // Tree builders on the same surfels.
  surfels::Surfels copy = p->surfels;
  t0 = std::chrono::steady_clock::now();
  auto kd = hierarchy::buildTree(copy, {.builder = hierarchy::Builder::kKdMedian});
  const double kd_s = seconds(t0);
  copy = p->surfels;
  t0 = std::chrono::steady_clock::now();
  auto hac = hierarchy::buildTree(copy, {.builder = hierarchy::Builder::kAgglomerative});
  const double hac_s = seconds(t0);

  nlohmann::ordered_json j;
  j["machine"] = {{"cpu", bench::cpuModel()}, {"threads", tbb::info::default_concurrency()}};
  j["scene"] = args.scene;
  j["pair_hit_credit_kernel"] = hitCreditName(args.hit_credit);
  j["subdivide"] = args.subdivide;
  j["triangles"] = triangles;
  j["precompute"] = report;
  j["link_generation_vs_raw_embree"] = {{"rays", rays.size()},
                                        {"raw_caches_sampled", sampled.size()},
                                        {"raw_cache_stride", stride},
                                        {"link_rays_per_second", link_rps},
                                        {"raw_rays_per_second", raw_rps},
                                        {"ratio", raw_rps > 0 ? link_rps / raw_rps : 0.0},
                                        {"raw_ray_api_rays_per_second", raw_api_rps},
                                        {"ratio_to_ray_api", raw_api_rps > 0 ? link_rps / raw_api_rps : 0.0},
                                        {"pairs", pair_rows},
                                        {"median_pair_ratio", median_ratio},
                                        {"median_pair_ratio_to_ray_api", median_api_ratio},
                                        {"pair_phase_share", pair_phase_share},
                                        {"pair_phase_ticks_per_cache", pair_phase_ticks_per_cache},
                                        {"pair_own_work_per_trace", pair_own_work},
                                        // What "raw" is: the very call link generation makes
                                        // per cache, with nothing else around it.
                                        {"baseline", "rt::Accel::intersectFan (rtcIntersect16 packets of 16 "
                                                     "consecutive rays of one cache, directions and hits as arrays), "
                                                     "closest hit with the full hit record into the task's own "
                                                     "arrays, same rays, tasks of 32 caches, all TBB threads"},
                                        {"baseline_ray_api", "rt::Accel::intersect, Coherence::kCoherent (the "
                                                             "Foundation benchmark's packet call: rt::Ray records "
                                                             "in, rt::Hit records out), same rays and tasks"},
                                        {"raw_passes", raw.passes},
                                        {"locator_build_seconds", locator_s},
                                        {"owner_raster_cells", locator.rasterCellCount()},
                                        {"owner_raster_factor", locator.rasterFactor()},
                                        {"owner_raster_cell_bytes", locator.rasterCellBytes()}};
  j["tree_build_seconds"] = {{"kd", kd_s}, {"hac", hac_s}, {"hac_over_kd", kd_s > 0 ? hac_s / kd_s : 0.0},
                             {"ok", bool(kd) && bool(hac)}};
  const auto& t = report["seconds"];
  fmt::print("scene {} ({} triangles, subdivide {}) on {} x {}\n", args.scene, triangles, args.subdivide, bench::cpuModel(),
             tbb::info::default_concurrency());
  fmt::print("caches: {} lightmap, {} grid; surfels {}; links/cache {:.1f}\n",
             report["counts"]["lightmap_caches"].get<std::size_t>(), report["counts"]["grid_caches"].get<std::size_t>(),
             report["counts"]["surfels"].get<std::size_t>(),
             report["links"]["lightmap"]["mean_links_per_cache"].get<double>());
  for (const auto& [stage, s] : t.items()) fmt::print("  {:<10} {:8.3f} s\n", stage, s.get<double>());
  fmt::print("link rays/s {:.3g}, raw Embree on the same rays {:.3g} as fans ({:.3g} as ray records): ratio {:.2f} "
             "({:.2f})",
             link_rps, raw_rps, raw_api_rps, raw_rps > 0 ? link_rps / raw_rps : 0.0,
             raw_api_rps > 0 ? link_rps / raw_api_rps : 0.0);
  if (stride > 1) fmt::print(" (raw on every {}th block of 32 caches: {} of {})", stride, sampled.size(), caches);
  fmt::print("\n");
  if (!pair_ratios.empty()) {
    fmt::print("back-to-back runs (links, raw fans, raw ray records):");
    for (std::size_t k = 0; k < pair_ratios.size(); ++k) fmt::print(" {:.2f} ({:.2f})", pair_ratios[k], pair_api_ratios[k]);
    fmt::print(": median ratio {:.2f} ({:.2f} to ray records)\n", median_ratio, median_api_ratio);
    fmt::print("share of each link run's wall time outside its phases:");
    for (const double o : pair_outside) fmt::print(" {:.1f} %", 100.0 * o);
    fmt::print("\n");
    fmt::print("link phases over the pairs (hit credit {}):", hitCreditName(args.hit_credit));
    for (const auto& [phase, share] : pair_phase_share.items()) fmt::print(" {} {:.1f} %", phase, 100.0 * share.get<double>());
    fmt::print("; own work per unit of tracing {:.2f}\n", pair_own_work);
    fmt::print("link phases, timer ticks per cache:");
    for (const auto& [phase, ticks] : pair_phase_ticks_per_cache.items()) fmt::print(" {} {:.0f}", phase, ticks.get<double>());
    fmt::print("\n");
  }
  fmt::print("owner lookup: {} raster cells of {} bytes ({} per cell side), built in {:.3f} s (stage \"owners\", not in "
             "the link time)\n",
             locator.rasterCellCount(), locator.rasterCellBytes(), locator.rasterFactor(), locator_s);
  fmt::print("tree build: kd {:.3f} s, hac {:.3f} s ({:.1f}x)\n", kd_s, hac_s, kd_s > 0 ? hac_s / kd_s : 0.0);
  for (const auto& [what, b] : report["memory_bytes"].items())
    fmt::print("  mem {:<26} {:10.2f} MiB\n", what, b.get<double>() / (1024.0 * 1024.0));
  if (!args.json.empty()) std::ofstream(args.json) << j.dump(2) << "\n";
  return 0;
}
