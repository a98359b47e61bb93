// gpu_relight_bench: the GPU relight figures in one run (docs/gpu.md, docs/results.md).
//
//  1. Relight breakdown on the GPU at a precompute preset ("medium" by default, seed 000
//     Table 2 setting 2) on one scene: median GPU time per stage from GL timer queries
//     (shadow maps + surfel direct, pull, node radiosity, cache lighting, bounces, fill,
//     readback), for both link forms, with the CPU relight of the same run beside it.
//  2. The GPU's memory bandwidth, measured in the same context with a coalesced read and a
//     copy kernel, and cache lighting expressed as a ratio to the time to stream the link
//     bytes at that bandwidth.
//  3. The emitters' sampled light (surfels, lightmap caches, grid, direct layer), re-sampled
//     in every measured relight (invalidate()): device time of the GPU sampler (stages
//     `*_gpu`), the host wall time of the same stages on each backend, and shadow rays/s.
//  4. Shadow maps vs ray-traced shadows: for each --compare scene, CPU and GPU relights of
//     the scene's own lights (a sun when it has none), relative RMS difference of the
//     baked direct light, of the surfels' radiosity and of the indirect lightmap.
// Runs from any directory: every scene is a path argument. Usage:
//   gpu_relight_bench [--scene F] [--preset medium] [--repeats N] [--lanes N]
//                     [--stream-mb N] [--compare F]... [--compare-preset draft] [--json OUT]
//                     [--shadow-resolution N] [--normal-offset TEXELS] [--slope-bias TEXELS]
//                     [--bias-scene FRACTION] [--emitter-lanes N]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/info.h>

#include "bench/common/bench_common.h"
#include "bench/rt/throughput.h"
#include "core/precompute/precompute.h"
#include "core/relight/backend.h"
#include "core/scene/load.h"
#include "gpu/gpu_relight.h"

namespace {

using namespace lightlink;
using bench::Clock;
using bench::median;

struct Args {
  std::string scene = std::string(LIGHTLINK_SOURCE_DIR) + "/clients/demo/cornell_box.gltf";
  std::string preset = "medium";
  std::string compare_preset = "draft";
  std::vector<std::string> compare;
  std::string json;
  int repeats = 20;
  int lanes = 8;
  int stream_mb = 256;
  gpu::GpuOptions gpu;  // shadow-map resolution and biases (docs/gpu.md)
};

bool parse(int argc, char** argv, Args& a) {
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (i + 1 >= argc) return false;
    const char* v = argv[++i];
    if (k == "--scene") a.scene = v;
    else if (k == "--preset") a.preset = v;
    else if (k == "--compare") a.compare.push_back(v);
    else if (k == "--compare-preset") a.compare_preset = v;
    else if (k == "--json") a.json = v;
    else if (k == "--repeats") a.repeats = std::max(1, std::atoi(v));
    else if (k == "--lanes") a.lanes = std::atoi(v);
    else if (k == "--emitter-lanes") a.gpu.emitter_lanes = std::atoi(v);
    else if (k == "--stream-mb") a.stream_mb = std::max(1, std::atoi(v));
    else if (k == "--shadow-resolution") a.gpu.shadow_resolution = std::atoi(v);
    else if (k == "--normal-offset") a.gpu.normal_offset_texels = std::stof(v);
    else if (k == "--slope-bias") a.gpu.slope_bias_texels = std::stof(v);
    else if (k == "--bias-scene") a.gpu.bias_scene = std::stof(v);
    else return false;
  }
  return true;
}

struct Loaded {
  scene::Scene scene;
  precompute::Precomputation p;
  std::unique_ptr<rt::Accel> accel;
  double precompute_s = 0.0;
};

Expected<std::unique_ptr<Loaded>> load(const std::string& path, const std::string& preset) {
  auto l = std::make_unique<Loaded>();
  auto s = scene::loadScene(path);
  if (!s) return s.status();
  l->scene = std::move(*s);
  auto o = precompute::preset(preset);
  if (!o) return o.status();
  const auto t0 = Clock::now();
  auto p = precompute::run(l->scene, *o);
  if (!p) return p.status();
  l->precompute_s = std::chrono::duration<double>(Clock::now() - t0).count();
  l->p = std::move(*p);
  auto a = rt::Accel::build(l->scene);
  if (!a) return a.status();
  l->accel = std::make_unique<rt::Accel>(std::move(*a));
  return l;
}

// Median seconds per stage over `repeats` relights (after one warm-up), bounce stages
// summed into "bounces_*" so runs with different bounce counts compare.
std::map<std::string, double> breakdown(const std::function<Status(relight::RelightResult&)>& relight, int repeats,
                                        relight::RelightResult& last) {
  std::map<std::string, std::vector<double>> per;
  std::vector<double> wall;
  for (int r = 0; r <= repeats; ++r) {
    const auto t0 = Clock::now();
    if (Status s = relight(last); !s) {
      std::fprintf(stderr, "relight failed: %s\n", s.toString().c_str());
      std::exit(2);
    }
    const double w = std::chrono::duration<double>(Clock::now() - t0).count();
    if (r == 0) continue;
    wall.push_back(w);
    std::map<std::string, double> run;
    for (const auto& st : last.timings) {
      std::string name = st.stage;
      if (name.rfind("bounce", 0) == 0) name = "bounces_" + name.substr(name.find('_') + 1);
      run[name] += st.seconds;
    }
    double total = 0.0;
    for (auto& [k, v] : run) {
      per[k].push_back(v);
      // A `*_gpu` stage is the device time inside the host stage of the same name: not added twice.
      if (!(k.size() > 4 && k.compare(k.size() - 4, 4, "_gpu") == 0)) total += v;
    }
    per["sum_of_stages"].push_back(total);
  }
  std::map<std::string, double> out;
  for (auto& [k, v] : per) out[k] = median(v);
  out["wall"] = median(wall);
  return out;
}

double relRms(std::span<const float> a, std::span<const float> b) {
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    num += double(a[i] - b[i]) * (a[i] - b[i]);
    den += double(b[i]) * b[i];
  }
  return den > 0.0 ? std::sqrt(num / den) : 0.0;
}
std::span<const float> floats(const std::vector<glm::vec3>& v) {
  return {reinterpret_cast<const float*>(v.data()), 3 * v.size()};
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (!parse(argc, argv, args)) {
    std::fprintf(stderr,
                 "usage: gpu_relight_bench [--scene F] [--preset medium] [--repeats N] [--lanes N] [--stream-mb N]\n"
                 "                         [--compare F]... [--compare-preset draft] [--json OUT]\n"
                 "                         [--shadow-resolution N] [--normal-offset T] [--slope-bias T] [--bias-scene F]\n"
                 "                         [--emitter-lanes N]\n");
    return 1;
  }
  if (!std::getenv("MESA_SHADER_CACHE_DIR")) setenv("MESA_SHADER_CACHE_DISABLE", "true", 0);
  nlohmann::ordered_json j;
  auto l = load(args.scene, args.preset);
  if (!l) {
    std::fprintf(stderr, "%s: %s\n", args.scene.c_str(), l.status().toString().c_str());
    return 2;
  }
  Loaded& d = **l;
  gpu::GpuOptions go = args.gpu;
  go.lanes = args.lanes;
  auto gpu = gpu::GpuRelighter::create(d.scene, *d.accel, d.p, d.p.lightmap_links.view(), d.p.grid_links.view(), go);
  if (!gpu) {
    std::fprintf(stderr, "GPU backend: %s\n", gpu.status().toString().c_str());
    return 3;
  }
  auto cpu = relight::Relighter::create(d.scene, *d.accel, d.p);
  if (!cpu) return 2;
  const auto& info = (*gpu)->info();
  j["machine"] = {{"gpu", info.renderer}, {"gl", info.version}, {"egl_platform", info.platform},
                  {"cpu", bench::cpuModel()}, {"threads", tbb::info::default_concurrency()}};
  j["scene"] = args.scene;
  j["preset"] = args.preset;
  j["precompute_seconds"] = d.precompute_s;
  j["counts"] = {{"surfels", d.p.surfels.size()}, {"nodes", d.p.tree.nodeCount()},
                 {"tree_levels", d.p.tree.levelCount()}, {"lightmap_caches", d.p.lightmap.size()},
                 {"grid_caches", d.p.has_grid ? d.p.grid.size() : 0}, {"links", d.p.lightmap_links.linkCount()},
                 {"grid_links", d.p.grid_links.linkCount()}, {"link_bands", d.p.lightmap_links.bands},
                 {"lanes", args.lanes}, {"emitter_lanes", args.gpu.emitter_lanes}};
  fmt::print("GPU {} ({}, EGL {}), CPU {} x {}\n", info.renderer, info.version, info.platform, bench::cpuModel(),
             tbb::info::default_concurrency());
  fmt::print("scene {} preset {}: {} surfels, {} nodes ({} levels), {} + {} caches, {} + {} links, {} bands\n",
             args.scene, args.preset, d.p.surfels.size(), d.p.tree.nodeCount(), d.p.tree.levelCount(),
             d.p.lightmap.size(), d.p.has_grid ? d.p.grid.size() : 0, d.p.lightmap_links.linkCount(),
             d.p.grid_links.linkCount(), d.p.lightmap_links.bands);

  // ---- bandwidth ------------------------------------------------------------------------
  const std::size_t stream_bytes = std::size_t(args.stream_mb) << 20;
  auto t_read = (*gpu)->measureStream(stream_bytes, false, 10);
  auto t_copy = (*gpu)->measureStream(stream_bytes, true, 10);
  if (!t_read || !t_copy) {
    std::fprintf(stderr, "bandwidth: %s\n", (!t_read ? t_read : t_copy).status().toString().c_str());
    return 3;
  }
  const double read_bw = double(stream_bytes) / *t_read;
  const double copy_bw = 2.0 * double(stream_bytes) / *t_copy;  // read + write
  j["bandwidth"] = {{"bytes", stream_bytes}, {"read_GBps", read_bw * 1e-9}, {"copy_GBps", copy_bw * 1e-9}};
  fmt::print("GPU memory bandwidth: read {:.1f} GB/s, copy {:.1f} GB/s (read + write), {} MiB\n\n", read_bw * 1e-9,
             copy_bw * 1e-9, args.stream_mb);

  // ---- breakdown, both link forms, GPU and CPU ---------------------------------------
  const relight::LightSet lights = bench::lightsOrSun(d.scene);
  const int ncl = d.p.lightmap_links.bands * d.p.lightmap_links.bands;
  const std::size_t links = d.p.lightmap_links.linkCount() + d.p.grid_links.linkCount();
  const std::size_t caches = d.p.lightmap.size() + (d.p.has_grid ? d.p.grid.size() : 0);
  j["relight"] = nlohmann::ordered_json::array();
  for (relight::LinkForm form : {relight::LinkForm::kProjected, relight::LinkForm::kRuntime}) {
    const std::string form_name(relight::linkFormName(form));
    for (int bounces : {0, 8}) {
      relight::RelightOptions o;
      o.link_form = form;
      o.max_bounces = bounces;
      relight::RelightResult rg, rc;
      const auto g = breakdown(
          [&](relight::RelightResult& r) {
            (*gpu)->invalidate();
            return (*gpu)->relightInto(lights, o, r);
          },
                               args.repeats, rg);
      // invalidate(): the CPU would otherwise answer an unchanged light set from its kept state.
      const auto c = breakdown(
          [&](relight::RelightResult& r) {
            cpu->invalidate();
            return cpu->relightInto(lights, o, r);
          },
                               std::max(3, args.repeats / 4), rc);
      // Link bytes one cache-lighting pass streams: node index + coefficients (projected) or
      // direction + solid angle (runtime) per link, plus the per-cache offsets.
      const std::size_t link_bytes = links * (form == relight::LinkForm::kProjected ? 4 + 2 * std::size_t(ncl) : 10) +
                                     (caches + 2) * 4;
      const double stream_s = double(link_bytes) / read_bw;
      const double cl = g.count("cache_lighting") ? g.at("cache_lighting") : 0.0;
      nlohmann::ordered_json e;
      e["link_form"] = form_name;
      e["max_bounces"] = bounces;
      e["bounces_run"] = rg.bounce_log.size();
      e["bounce_stop"] = rg.bounce_stop;
      e["gpu_seconds"] = g;
      e["cpu_seconds"] = c;
      e["link_bytes"] = link_bytes;
      e["link_stream_seconds_at_read_bw"] = stream_s;
      e["cache_lighting_over_stream"] = stream_s > 0 ? cl / stream_s : 0.0;
      e["cache_lighting_GBps"] = cl > 0 ? double(link_bytes) / cl * 1e-9 : 0.0;
      // Emitter sampling: the GPU sampler's device time, and the host stages that hold it
      // (on the GPU backend they add rotations, uploads, the read-back and the layer sums).
      double em_device = 0.0, em_gpu_wall = 0.0, em_cpu = 0.0;
      for (const char* st : {"surfel_emitter", "emissive_direct", "grid_emitter", "direct_layer_emitter"}) {
        const std::string k(st);
        if (g.count(k + "_gpu")) em_device += g.at(k + "_gpu");
        if (g.count(k)) em_gpu_wall += g.at(k);
        if (c.count(k)) em_cpu += c.at(k);
      }
      const double em_rays = double(rc.counts.shadow_rays);  // texel + grid rays, the same on both
      e["emitter_sampling"] = {{"gpu_device_seconds", em_device}, {"gpu_backend_wall_seconds", em_gpu_wall},
                               {"cpu_seconds", em_cpu}, {"shadow_rays", rc.counts.shadow_rays},
                               {"gpu_rays_per_second", em_device > 0 ? em_rays / em_device : 0.0},
                               {"cpu_rays_per_second", em_cpu > 0 ? em_rays / em_cpu : 0.0}};
      j["relight"].push_back(e);
      fmt::print("{} links, max bounces {} (ran {}, {}):\n", form_name, bounces, rg.bounce_log.size(), rg.bounce_stop);
      fmt::print("  {:<26} {:>10} {:>10}\n", "stage (median)", "GPU ms", "CPU ms");
      for (const auto& [k, v] : g) {
        const auto it = c.find(k);
        fmt::print("  {:<26} {:>10.3f} {:>10}\n", k, v * 1e3, it == c.end() ? "" : fmt::format("{:.3f}", it->second * 1e3));
      }
      fmt::print("  cache lighting: {:.3f} ms for {:.1f} MB of links = {:.2f} x the {:.3f} ms to stream them at {:.0f} GB/s\n",
                 cl * 1e3, link_bytes * 1e-6, stream_s > 0 ? cl / stream_s : 0.0, stream_s * 1e3, read_bw * 1e-9);
      fmt::print("  emitter sampling: GPU {:.3f} ms device ({:.3f} ms in the backend's stages), CPU {:.3f} ms; "
                 "{} shadow rays at lightmap/grid points\n\n",
                 em_device * 1e3, em_gpu_wall * 1e3, em_cpu * 1e3, rc.counts.shadow_rays);
    }
  }

  // ---- shadow maps vs ray-traced shadows --------------------------------------------------
  j["shadow_comparison"] = nlohmann::ordered_json::array();
  for (const auto& path : args.compare) {
    auto cl = load(path, args.compare_preset);
    if (!cl) {
      std::fprintf(stderr, "%s: %s\n", path.c_str(), cl.status().toString().c_str());
      j["shadow_comparison"].push_back({{"scene", path}, {"error", cl.status().message()}});
      continue;
    }
    Loaded& c = **cl;
    auto g = gpu::GpuRelighter::create(c.scene, *c.accel, c.p, c.p.lightmap_links.view(), c.p.grid_links.view(), go);
    auto r = relight::Relighter::create(c.scene, *c.accel, c.p);
    if (!g || !r) {
      std::fprintf(stderr, "%s: %s\n", path.c_str(), (!g ? g.status() : r.status()).toString().c_str());
      continue;
    }
    relight::LightSet ls = bench::lightsOrSun(c.scene);
    (void)ls.setEmissiveBaked(false);  // the direct light compared is the punctual lights'
    relight::RelightOptions o;
    o.max_bounces = 2;
    relight::RelightResult rg, rc;
    if (!(*g)->relightInto(ls, o, rg) || !r->relightInto(ls, o, rc)) {
      std::fprintf(stderr, "%s: relight failed\n", path.c_str());
      continue;
    }
    // Texels valid on both: the baked direct light of the punctual lights.
    const double direct = relRms(floats(rg.direct), floats(rc.direct));
    const double surf = relRms(floats(rg.surfel_radiosity), floats(rc.surfel_radiosity));
    const double ind = relRms(rg.lightmap_sh, rc.lightmap_sh);
    // Texels lit on one backend and in shadow on the other (direct < 10 % of the other's).
    std::size_t lit_cpu = 0, only_cpu = 0, only_gpu = 0;
    for (std::size_t t = 0; t < rc.direct.size() && t < rg.direct.size(); ++t) {
      const float c_lum = rc.direct[t].x + rc.direct[t].y + rc.direct[t].z;
      const float g_lum = rg.direct[t].x + rg.direct[t].y + rg.direct[t].z;
      lit_cpu += c_lum > 0.0f;
      only_cpu += c_lum > 0.0f && g_lum < 0.1f * c_lum;
      only_gpu += g_lum > 0.0f && c_lum < 0.1f * g_lum;
    }
    fmt::print("shadow maps vs ray traced, {} ({} lights, preset {}): direct rel RMS {:.4f}, surfel radiosity {:.4f}, "
               "indirect lightmap {:.4f}\n",
               path, ls.lights().size(), args.compare_preset, direct, surf, ind);
    fmt::print("  texels lit by the CPU {}: dark on the GPU {}, lit only on the GPU {}\n", lit_cpu, only_cpu, only_gpu);
    j["shadow_comparison"].push_back({{"scene", path}, {"preset", args.compare_preset},
                                      {"lights", ls.lights().size()}, {"direct_rel_rms", direct},
                                      {"surfel_radiosity_rel_rms", surf}, {"indirect_lightmap_rel_rms", ind},
                                      {"texels_lit_cpu", lit_cpu}, {"texels_dark_on_gpu_only", only_cpu},
                                      {"texels_lit_on_gpu_only", only_gpu}});
  }
  if (!args.json.empty()) {
    std::ofstream(args.json) << j.dump(2) << "\n";
    fmt::print("\nwrote {}\n", args.json);
  }
  return 0;
}
