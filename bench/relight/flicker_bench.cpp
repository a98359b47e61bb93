// flicker_bench: docs/results.md "Temporal stability" figures (issue 48): does a light moving
// smoothly give smoothly changing lightmaps? One light moves along a short path (a line for a
// point or spot light, an arc of its direction for a directional one) in 2N equal steps; each
// frame is relit with the daemon's default options, and bench/common/flicker.h measures the
// roughness of the direct layer and of the indirect irradiance at steps s and s/2, finds the
// texels that pop, and says where the worst ones are. Runs that tell the causes apart:
//  --fixed-bounces: every frame relit with the same bounce count (the most of the default
//    run, no stop rule), so no frame stops a bounce earlier than its neighbour;
//  --unshadowed-surfels: as --fixed-bounces, and the surfels lit without shadow rays
//    (RelightOptions::surfel_irradiance): surfel light smooth in the light's position, so
//    what still pops in the indirect comes neither from the stop rule nor from surfel
//    visibility;
//  --no-bounce: relit without bounces, fully and incrementally, and the two compared.
// Usage:
//   flicker_bench [--scene F] [--lights FILE] [--light ID] [--path F] [--axis X,Y,Z] [--frames N]
//                 [--preset P] [--surfels N] [--links N] [--bands B] [--rays N] [--resolution R]
//                 [--fixed-bounces] [--unshadowed-surfels] [--no-bounce] [--surfel-shadow-rays N] [--json OUT]
// --path: the path's length as a fraction of the scene's size (a directional light: its
// angle in radians); --frames N: steps at s (2N + 1 frames are relit).
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>
#include <tbb/info.h>

#include "bench/common/bench_common.h"
#include "bench/common/flicker.h"
#include "bench/rt/throughput.h"
#include "core/common/half.h"
#include "core/precompute/precompute.h"
#include "core/relight/relight.h"
#include "core/scene/light_eval.h"
#include "core/scene/load.h"

namespace {

using namespace lightlink;

struct Args {
  std::string scene;
  std::string lights;
  std::string light;  // id of the light to move; empty: the first
  std::string preset;
  std::string json;
  float path = 0.05f;
  glm::vec3 axis{1.0f, 0.0f, 0.0f};
  int frames = 16;
  bool no_bounce = false;
  bool unshadowed_surfels = false;
  bool fixed_bounces = false;
  int surfel_shadow_rays = relight::RelightOptions{}.surfel_shadow_rays;  // --surfel-shadow-rays: every run's
  precompute::PrecomputeOptions options;
  bool options_given = false;
};

bool parseVec3(const char* v, glm::vec3& out) {
  return std::sscanf(v, "%f,%f,%f", &out.x, &out.y, &out.z) == 3 && glm::length(out) > 0.0f;
}

bool parse(int argc, char** argv, Args& a) {
  a.scene = std::string(LIGHTLINK_SOURCE_DIR) + "/clients/demo/cornell_box.gltf";
  a.options.lightmap_resolution = bench::kMediumResolution;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "--no-bounce" || k == "--unshadowed-surfels" || k == "--fixed-bounces") {
      (k == "--no-bounce" ? a.no_bounce : k == "--fixed-bounces" ? a.fixed_bounces : a.unshadowed_surfels) = true;
      continue;
    }
    if (i + 1 >= argc) return false;
    const char* v = argv[++i];
    if (k == "--scene") a.scene = v;
    else if (k == "--lights") a.lights = v;
    else if (k == "--light") a.light = v;
    else if (k == "--preset") a.preset = v;
    else if (k == "--json") a.json = v;
    else if (k == "--path") a.path = std::stof(v);
    else if (k == "--frames") a.frames = std::max(2, std::stoi(v));
    else if (k == "--surfel-shadow-rays") a.surfel_shadow_rays = std::stoi(v);
    else if (k == "--axis") {
      if (!parseVec3(v, a.axis)) return false;
      a.axis = glm::normalize(a.axis);
    } else if (bench::parsePrecomputeFlag(k, v, a.options)) a.options_given = true;
    else return false;
  }
  return !(a.options_given && !a.preset.empty());
}

// The moved light at u in [0, 1] along the path, centred on where the light set puts it.
lights::Light along(const lights::Light& start, const Args& a, float scene_scale, float u) {
  lights::Light l = start;
  const float s = u - 0.5f;
  if (l.kind == lights::Light::Kind::kDirectional) {
    glm::vec3 pivot = glm::cross(start.direction, glm::vec3(0.0f, 1.0f, 0.0f));
    if (glm::length(pivot) < 1e-3f) pivot = glm::vec3(1.0f, 0.0f, 0.0f);
    const glm::mat4 turn = glm::rotate(glm::mat4(1.0f), s * a.path, glm::normalize(pivot));
    l.direction = glm::normalize(glm::vec3(turn * glm::vec4(start.direction, 0.0f)));
  } else {
    l.position = start.position + s * a.path * scene_scale * a.axis;
  }
  return l;
}

struct Run {
  std::string name;
  relight::RelightOptions options;
  bool unshadowed_surfels = false;  // surfel light without shadow rays
  bool fixed_bounces = false;       // the default run's most bounces on every frame
  bench::FlickerFrames direct, indirect;
  std::vector<int> bounces;  // per frame
  std::vector<double> ms;
  int incremental = 0;       // frames relit incrementally
};

// Relights every frame of the path from a full relight of its first frame.
Status relightPath(relight::Relighter& relighter, const precompute::Precomputation& p, relight::LightSet lights,
                   const relight::LightEntry& moved, const Args& a, float scene_scale, Run& run) {
  relighter.invalidate(relight::Relighter::Forget::kLightState);
  relight::RelightResult res;
  std::vector<glm::vec3> surfel_light;
  const int frames = 2 * a.frames + 1;
  for (int t = 0; t < frames; ++t) {
    relight::LightEntry e = moved;
    e.light = along(moved.light, a, scene_scale, float(t) / float(frames - 1));
    if (Status s = lights.modify(e); !s) return s;
    relight::RelightOptions options = run.options;
    if (run.unshadowed_surfels) {
      surfel_light.assign(p.surfels.size(), glm::vec3(0.0f));
      for (const auto& l : lights.lights())
        for (std::size_t k = 0; k < p.surfels.size(); ++k)
          surfel_light[k] += scene::irradianceFrom(l.light, p.surfels.position[k], p.surfels.normal[k]);
      options.surfel_irradiance = surfel_light;
    }
    if (Status s = relighter.relightInto(lights, options, res); !s) return s;
    bench::appendFlickerFrame(res, p, run.direct, run.indirect);
    run.bounces.push_back(int(res.bounce_log.size()));
    run.ms.push_back(res.totalSeconds() * 1e3);
    run.incremental += res.passes.incremental;
  }
  return {};
}

nlohmann::ordered_json stepJson(const bench::StepRoughness& r) {
  return {{"rms_d1", r.rms_d1}, {"rms_d2", r.rms_d2}, {"roughness", r.roughness}, {"p999_d2", r.p999_d2}};
}

// The layer's figures, printed and as JSON: roughness at both steps, the popping texels by
// the step they jump at (and how many of those steps change the bounce count: the stop rule
// ends a frame's bounces one earlier or later than its neighbour's), and the worst texels
// with their place in the scene.
nlohmann::ordered_json report(const char* layer, const bench::FlickerLayer& m, int width,
                              const caches::LightmapCaches& texels, const std::vector<int>& bounces) {
  std::vector<std::size_t> per_step(bounces.size() > 0 ? bounces.size() - 1 : 0, 0);
  std::size_t at_bounce_change = 0;
  for (std::size_t k : m.popping_step) {
    if (k < per_step.size()) ++per_step[k];
    if (k + 1 < bounces.size() && bounces[k] != bounces[k + 1]) ++at_bounce_change;
  }
  fmt::print("  {:<8} lit {:>7} of {:>7}  R(s) {:.4f}  R(s/2) {:.4f}  ratio {:.3f}  p99.9 |d2|/rms d1 {:.3f} -> {:.3f}"
             "  popping {} ({:.3f} %, {} where the bounce count changes)  ratio without them {:.3f}\n",
             layer, m.lit_texels, m.texels_with_value, m.coarse.roughness, m.fine.roughness, m.ratio, m.coarse.p999_d2,
             m.fine.p999_d2, m.popping_texels,
             m.lit_texels ? 100.0 * double(m.popping_texels) / double(m.lit_texels) : 0.0, at_bounce_change,
             m.ratio_smooth);
  if (m.popping_texels)
    fmt::print("    popping texels per step: {}; a popping texel jumps by {:.1f} % of its mean (median), {:.0f} % at "
               "most\n",
               fmt::join(per_step, " "), 100.0 * m.popping_jump_median, 100.0 * m.popping_jump_max);
  nlohmann::ordered_json j;
  j["texels_with_value"] = m.texels_with_value;
  j["lit_texels"] = m.lit_texels;
  j["step"] = stepJson(m.coarse);
  j["half_step"] = stepJson(m.fine);
  j["ratio"] = m.ratio;
  j["popping_texels"] = m.popping_texels;
  j["popping_per_step"] = per_step;
  j["popping_at_bounce_change"] = at_bounce_change;
  j["popping_jump"] = {{"median", m.popping_jump_median}, {"max", m.popping_jump_max}};
  j["without_popping"] = {{"step", stepJson(m.coarse_smooth)}, {"half_step", stepJson(m.fine_smooth)},
                          {"ratio", m.ratio_smooth}};
  j["worst"] = nlohmann::ordered_json::array();
  for (const auto& w : m.worst) {
    const int x = int(w.texel % std::size_t(width)), y = int(w.texel / std::size_t(width));
    const std::int32_t c = texels.cache_of_texel[w.texel];
    const glm::vec3 pos = c >= 0 ? texels.position[std::size_t(c)] : glm::vec3(0.0f);
    const glm::vec3 n = c >= 0 ? texels.normal[std::size_t(c)] : glm::vec3(0.0f);
    fmt::print("    texel ({:>4}, {:>4}) frame {:>3}: |d2| {:7.2f}, largest |d1| {:6.2f} at s/2, {:6.2f} at s (x rms d1)"
               "{}  at ({:.3f}, {:.3f}, {:.3f}) n ({:.2f}, {:.2f}, {:.2f})\n",
               x, y, w.frame, w.d2, w.d1_half_step, w.d1_step, w.pops ? " pops" : "     ", pos.x, pos.y, pos.z, n.x,
               n.y, n.z);
    j["worst"].push_back({{"x", x},
                          {"y", y},
                          {"frame", w.frame},
                          {"d2", w.d2},
                          {"d1_half_step", w.d1_half_step},
                          {"d1_step", w.d1_step},
                          {"pops", w.pops},
                          {"position", {pos.x, pos.y, pos.z}},
                          {"normal", {n.x, n.y, n.z}}});
  }
  return j;
}

// The largest share of a cache's view one surfel holds: over its links, the link's L00 form
// factor over the node's surfel count, as a fraction of the cache's total. A surfel whose
// shadow ray flips moves the cache by that much of its light, so caches with fine cuts next
// to a surface jump most. Medians over the popping texels and over every texel with a cache.
nlohmann::ordered_json cutReport(const precompute::Precomputation& p, const bench::FlickerLayer& m) {
  const links::LinksView links = p.lightmap_links.view();
  const std::size_t nc = std::size_t(links.bands * links.bands);
  auto share = [&](std::size_t texel) {
    const std::int32_t c = p.lightmap.cache_of_texel[texel];
    if (c < 0) return 0.0;
    double total = 0.0, most = 0.0;
    for (std::uint32_t k = links.offsets[std::size_t(c)]; k < links.offsets[std::size_t(c) + 1]; ++k) {
      const double f = fromHalf(links.coeffs[k * nc]);
      const std::uint32_t node = links.node[k];
      total += f;
      most = std::max(most, f / double(p.tree.end[node] - p.tree.begin[node]));
    }
    return total > 0.0 ? most / total : 0.0;
  };
  std::vector<double> popping, all;
  for (std::size_t t : m.popping) popping.push_back(share(t));
  for (std::size_t t = 0; t < p.lightmap.cache_of_texel.size(); ++t)
    if (p.lightmap.cache_of_texel[t] >= 0) all.push_back(share(t));
  fmt::print("    largest share of a cache's view one surfel holds (median): {:.2f} % at popping texels, {:.2f} % at "
             "every texel\n",
             100.0 * bench::median(popping), 100.0 * bench::median(all));
  return {{"popping_median", bench::median(popping)}, {"all_median", bench::median(all)}};
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  if (!parse(argc, argv, args)) {
    std::fprintf(stderr,
                 "usage: flicker_bench [--scene F] [--lights FILE] [--light ID] [--path F] [--axis X,Y,Z] "
                 "[--frames N] [--preset P | --surfels N --links N --bands B --rays N --resolution R] "
                 "[--fixed-bounces] [--unshadowed-surfels] [--no-bounce] [--surfel-shadow-rays N] [--json OUT]\n");
    return 1;
  }
  auto scene = scene::loadScene(args.scene);
  if (bench::failed(scene)) return 2;
  precompute::PrecomputeOptions options = args.options;
  if (!args.preset.empty()) {
    auto preset = precompute::preset(args.preset);
    if (bench::failed(preset)) return 2;
    options = *preset;
  }
  const auto t_pre = bench::Clock::now();
  auto p = precompute::run(*scene, options);
  if (bench::failed(p)) return 2;
  const double precompute_s = bench::secondsSince(t_pre);
  auto accel = rt::Accel::build(*scene);
  if (bench::failed(accel)) return 2;
  auto relighter = relight::Relighter::create(*scene, *accel, *p);
  if (bench::failed(relighter)) return 2;

  relight::LightSet lights = relight::LightSet::fromSceneLights(scene->lights);
  if (!args.lights.empty()) {
    if (Status s = lights.applyFile(args.lights); !s) {
      std::fprintf(stderr, "%s\n", s.toString().c_str());
      return 2;
    }
  }
  if (lights.lights().empty()) lights = bench::lightsOrSun(*scene);
  const relight::LightEntry* moved = args.light.empty() ? &lights.lights().front() : lights.find(args.light);
  if (!moved) {
    std::fprintf(stderr, "--light %s: no such light\n", args.light.c_str());
    return 2;
  }
  const relight::LightEntry start = *moved;
  const bool directional = start.light.kind == lights::Light::Kind::kDirectional;
  const double step = double(args.path) * (directional ? 1.0 : double(scene->scale)) / double(args.frames);

  nlohmann::ordered_json j;
  j["machine"] = {{"cpu", bench::cpuModel()}, {"threads", tbb::info::default_concurrency()}};
  j["scene"] = args.scene;
  j["triangles"] = scene->triangleCount();
  j["preset"] = args.preset.empty() ? "bench medium (kMediumResolution)" : args.preset;
  j["precompute_options"] = options.canonical();
  j["precompute_seconds"] = precompute_s;
  j["counts"] = p->report()["counts"];
  j["light"] = {{"id", start.id}, {"kind", enumName(lights::kLightKindNames, start.light.kind)}};
  if (directional)
    j["path"] = {{"kind", "arc"}, {"angle_rad", args.path}, {"steps", args.frames}, {"step_rad", step}};
  else
    j["path"] = {{"kind", "line"},
                 {"axis", {args.axis.x, args.axis.y, args.axis.z}},
                 {"length_m", double(args.path) * double(scene->scale)},
                 {"scene_size_m", scene->scale},
                 {"steps", args.frames},
                 {"step_m", step}};
  fmt::print("scene {} ({} triangles), lightmap {} x {}, direct {} x {}; precompute {:.2f} s\n", args.scene,
             scene->triangleCount(), p->lightmap.width, p->lightmap.height,
             p->hasDirectLayer() ? p->direct_texels.width : p->lightmap.width,
             p->hasDirectLayer() ? p->direct_texels.height : p->lightmap.height, precompute_s);
  fmt::print("light '{}' ({}) moved along {} in {} steps of {:.4g}{} ({} frames at half that step)\n\n", start.id,
             enumName(lights::kLightKindNames, start.light.kind),
             directional ? fmt::format("an arc of {:.3f} rad", args.path)
                         : fmt::format("a line of {:.3f} m", double(args.path) * double(scene->scale)),
             args.frames, step, directional ? " rad" : " m", 2 * args.frames + 1);

  std::vector<Run> runs;
  runs.push_back({.name = "default", .options = {}});
  if (args.fixed_bounces) runs.push_back({.name = "fixed_bounces", .fixed_bounces = true});
  if (args.unshadowed_surfels)
    runs.push_back({.name = "surfels_unshadowed", .unshadowed_surfels = true, .fixed_bounces = true});
  if (args.no_bounce) {
    runs.push_back({.name = "no_bounce_full", .options = {.max_bounces = 0, .incremental = false}});
    runs.push_back({.name = "no_bounce_incremental", .options = {.max_bounces = 0, .incremental = true}});
  }
  const caches::LightmapCaches& direct_texels = p->hasDirectLayer() ? p->direct_texels : p->lightmap;
  const int direct_width = p->hasDirectLayer() ? p->direct_texels.width : p->lightmap.width;
  j["runs"] = nlohmann::ordered_json::array();
  for (Run& run : runs) {
    run.options.surfel_shadow_rays = args.surfel_shadow_rays;
    if (run.fixed_bounces) {
      run.options.max_bounces = *std::max_element(runs.front().bounces.begin(), runs.front().bounces.end());
      run.options.bounce_threshold = 0.0f;
    }
    if (Status s = relightPath(*relighter, *p, lights, start, args, scene->scale, run); !s) {
      std::fprintf(stderr, "%s\n", s.toString().c_str());
      return 2;
    }
    const auto [lo, hi] = std::minmax_element(run.bounces.begin(), run.bounces.end());
    fmt::print("{}: max_bounces {}, bounce_threshold {}, incremental {}{}; bounces per frame {}-{}, {} frames incremental, relight {:.1f} ms "
               "(median)\n",
               run.name, run.options.max_bounces, run.options.bounce_threshold, run.options.incremental,
               run.unshadowed_surfels ? ", surfels lit without shadow rays" : "", *lo, *hi, run.incremental,
               bench::median(run.ms));
    nlohmann::ordered_json r;
    r["name"] = run.name;
    r["options"] = {{"max_bounces", run.options.max_bounces},
                    {"bounce_threshold", run.options.bounce_threshold},
                    {"incremental", run.options.incremental},
                    {"surfel_shadow_rays", run.options.surfel_shadow_rays},
                    {"surfels_unshadowed", run.unshadowed_surfels}};
    r["relight_ms_median"] = bench::median(run.ms);
    r["incremental_frames"] = run.incremental;
    r["bounces"] = run.bounces;
    r["direct"] = report("direct", bench::measureFlicker(run.direct), direct_width, direct_texels, run.bounces);
    const bench::FlickerLayer indirect = bench::measureFlicker(run.indirect);
    r["indirect"] = report("indirect", indirect, p->lightmap.width, p->lightmap, run.bounces);
    if (indirect.popping_texels) r["indirect"]["surfel_share"] = cutReport(*p, indirect);
    j["runs"].push_back(r);
    fmt::print("\n");
  }
  if (args.no_bounce) {
    // The incremental path promises a full relight's result: the largest difference, relative
    // to the layer's largest value, over every frame.
    auto diff = [](const bench::FlickerFrames& a, const bench::FlickerFrames& b) {
      double d = 0.0, top = 0.0;
      for (std::size_t k = 0; k < a.values.size(); ++k) {
        d = std::max(d, double(std::abs(a.values[k] - b.values[k])));
        top = std::max(top, double(std::abs(a.values[k])));
      }
      return top > 0.0 ? d / top : d;
    };
    const Run& full = runs[runs.size() - 2];
    const Run& incremental = runs.back();
    const double dd = diff(full.direct, incremental.direct), di = diff(full.indirect, incremental.indirect);
    fmt::print("incremental vs full (no bounce): largest difference direct {:.3g}, indirect {:.3g} (of the largest "
               "value)\n",
               dd, di);
    j["incremental_vs_full"] = {{"direct", dd}, {"indirect", di}};
  }
  if (!args.json.empty()) std::ofstream(args.json) << j.dump(2) << "\n";
  return 0;
}
