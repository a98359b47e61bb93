// level_bench: the figures of docs/results.md "Game levels" for one level and preset: load
// (seconds, peak RSS), each precompute stage, the atlas (texel size, pages, caches,
// probe-lit objects), peak RSS after precompute, and relights on the CPU backend: the first
// (cold: its output arrays are touched for the first time) and the median of warm ones
// with one bounce (what a light change costs in the daemon, which reuses its result), and
// one with the preset's full bounce cap. `--tile N` repeats the level N x N side by side in
// memory (a ~1M-triangle level from a 60k one) before anything else.
//
//   level_bench SCENE [--preset P] [--lights FILE] [--tile N] [--repeats N] [--json OUT]
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "bench/common/bench_common.h"
#include "core/common/process_memory.h"
#include "core/precompute/precompute.h"
#include "core/relight/relight.h"
#include "core/rt/accel.h"
#include "core/scene/load.h"

using namespace lightlink;

namespace {

double peakRssMiB() { return double(peakResidentBytes()) / double(1 << 20); }

void tile(scene::Scene& scene, int n) {
  if (n <= 1) return;
  const glm::vec3 ext = scene.bounds.max - scene.bounds.min;
  const std::vector<scene::MeshInstance> one = scene.meshes;
  const std::vector<scene::Light> lights = scene.lights;
  scene.meshes.clear();
  scene.lights.clear();
  for (int z = 0; z < n; ++z)
    for (int x = 0; x < n; ++x) {
      const glm::vec3 offset(float(x) * ext.x * 1.05f, 0.0f, float(z) * ext.z * 1.05f);
      for (scene::MeshInstance m : one) {
        for (glm::vec3& p : m.positions) p += offset;
        m.name += "@" + std::to_string(x) + "," + std::to_string(z);
        scene.meshes.push_back(std::move(m));
      }
      for (scene::Light l : lights) {
        l.position += offset;
        scene.lights.push_back(l);
      }
    }
  scene.bounds = Aabb{};
  for (const auto& m : scene.meshes)
    for (const glm::vec3& p : m.positions) scene.bounds.grow(p);
  scene.scale = scene.bounds.diagonal();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: level_bench SCENE [--preset P] [--lights FILE] [--tile N] [--repeats N] [--json OUT]\n");
    return 1;
  }
  std::string preset = "medium", lights_path, json_path;
  int tiles = 1, repeats = 7;
  for (int i = 2; i + 1 < argc; i += 2) {
    const std::string k = argv[i];
    if (k == "--preset") preset = argv[i + 1];
    else if (k == "--lights") lights_path = argv[i + 1];
    else if (k == "--tile") tiles = std::max(1, std::atoi(argv[i + 1]));
    else if (k == "--repeats") repeats = std::max(1, std::atoi(argv[i + 1]));
    else if (k == "--json") json_path = argv[i + 1];
  }
  nlohmann::ordered_json out;
  out["scene"] = argv[1];
  out["preset"] = preset;
  out["tile"] = tiles;
  const auto t0 = bench::Clock::now();
  auto scene = scene::loadScene(argv[1]);
  if (bench::failed(scene)) return 2;
  out["load_seconds"] = bench::secondsSince(t0);
  out["load_peak_rss_mib"] = peakRssMiB();
  tile(*scene, tiles);
  out["triangles"] = scene->triangleCount();
  auto options = precompute::preset(preset);
  if (bench::failed(options)) return 2;
  auto p = precompute::run(*scene, *options);
  if (bench::failed(p)) return 2;
  const auto report = p->report();
  out["stages"] = report["seconds"];
  out["texel_size"] = p->atlas.texel_size_m;
  out["page"] = p->atlas.resolution;
  out["pages"] = p->atlas.pages;
  out["charts"] = p->atlas.chart_count;
  out["lightmap_caches"] = p->lightmap.size();
  out["probe_lit_objects"] = p->atlas.probe_lit.size();
  out["grid_caches"] = p->grid.size();
  out["direct_width"] = p->direct_texels.width;
  out["direct_height"] = p->direct_texels.height;
  out["direct_texels"] = p->direct_texels.size();
  out["precompute_peak_rss_mib"] = peakRssMiB();

  relight::LightSet lights = relight::LightSet::fromSceneLights(scene->lights);
  if (!lights_path.empty()) {
    if (Status s = lights.applyFile(lights_path); !s) {
      std::fprintf(stderr, "%s\n", s.toString().c_str());
      return 2;
    }
  }
  if (lights.lights().empty() && lights_path.empty()) lights = bench::lightsOrSun(*scene);
  auto accel = rt::Accel::build(*scene);
  if (bench::failed(accel)) return 2;
  auto relighter = relight::Relighter::create(*scene, *accel, *p);
  if (bench::failed(relighter)) return 2;
  relight::RelightOptions one;
  one.max_bounces = 1;
  one.incremental = false;
  relight::RelightResult result;
  auto t1 = bench::Clock::now();
  if (Status s = relighter->relightInto(lights, one, result); !s) {
    std::fprintf(stderr, "%s\n", s.toString().c_str());
    return 2;
  }
  out["relight_cold_ms"] = bench::secondsSince(t1) * 1e3;
  std::vector<double> warm;
  for (int r = 0; r < repeats; ++r) {
    relighter->invalidate(relight::Relighter::Forget::kEverything);
    t1 = bench::Clock::now();
    if (Status s = relighter->relightInto(lights, one, result); !s) return 2;
    warm.push_back(bench::secondsSince(t1) * 1e3);
  }
  out["relight_one_bounce_ms"] = bench::median(warm);
  out["relight_one_bounce_stages"] = result.report()["seconds"];
  out["seams"] = result.report()["seams"];
  relight::RelightOptions full;
  full.incremental = false;
  relighter->invalidate(relight::Relighter::Forget::kEverything);
  t1 = bench::Clock::now();
  if (Status s = relighter->relightInto(lights, full, result); !s) return 2;
  out["relight_full_ms"] = bench::secondsSince(t1) * 1e3;
  out["bounces"] = result.bounce_log.size();
  out["peak_rss_mib"] = peakRssMiB();
  const std::string text = out.dump(2);
  std::printf("%s\n", text.c_str());
  if (!json_path.empty()) std::ofstream(json_path) << text << "\n";
  return 0;
}
