// charts_bench: what `lightlink unwrap` does to every shared scene (default options) and to
// zdm2 subdivided 1-to-4 (~230k triangles, the timing target): charts, atlas, utilisation,
// stretch, overlaps and the best of three wall times (the machine may be shared). Prints a
// table; --json writes the same rows with the machine (docs/results.md renders it).
//   charts_bench <shared scenes dir> [--json OUT]
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <utility>

#include <nlohmann/json.hpp>

#include "bench/rt/throughput.h"
#include "core/charts/test_meshes.h"
#include "core/charts/unwrap.h"
#include "core/scene/load.h"

using namespace lightlink;

namespace {


bool row(const std::string& label, const scene::Scene& loaded, nlohmann::ordered_json& rows) {
  double best = 1e30;
  charts::UnwrapReport report;
  for (int run = 0; run < 3; ++run) {
    scene::Scene scene = loaded;
    Expected<charts::UnwrapResult> result = charts::unwrap(scene, {});
    if (!result) {
      std::printf("%-32s error: %s\n", label.c_str(), result.status().toString().c_str());
      rows.push_back({{"scene", label}, {"error", result.status().toString()}});
      return false;
    }
    best = std::min(best, result->report.seconds);
    report = result->report;
  }
  std::printf("%-32s %8zu tris  %6d charts  %4d²  texel %.4g m  %5.1f %%  stretch %.2f / %.3f  overlaps %zu  %.3f s%s\n",
              label.c_str(), report.triangles, report.generated ? report.charts : 0, report.resolution,
              report.texel_size_m, 100.0 * report.utilisation, report.max_area_stretch, report.mean_area_stretch,
              report.overlaps, best, report.generated ? "" : "  (kept TEXCOORD_1)");
  rows.push_back({{"scene", label},
                  {"triangles", report.triangles},
                  {"generated", report.generated},
                  {"charts", report.charts},
                  {"resolution", report.resolution},
                  {"texel_size_m", report.texel_size_m},
                  {"utilisation", report.utilisation},
                  {"max_area_stretch", report.max_area_stretch},
                  {"mean_area_stretch", report.mean_area_stretch},
                  {"overlaps", report.overlaps},
                  {"seconds_best_of_3", best}});
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::string json_path;
  std::filesystem::path dir;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--json" && i + 1 < argc) json_path = argv[++i];
    else if (dir.empty() && arg.rfind("--", 0) != 0) dir = arg;
    else {
      std::fprintf(stderr, "usage: charts_bench <shared scenes dir> [--json OUT]\n");
      return 2;
    }
  }
  if (dir.empty()) {
    std::fprintf(stderr, "usage: charts_bench <shared scenes dir> [--json OUT]\n");
    return 2;
  }
  const std::pair<const char*, const char*> scenes[] = {
      {"cornell_box_original_gltf", "CornellBox-Original.gltf"},
      {"cornell_box_vinc3r_lightmapuv", "cornellBox-2.80-Eevee-gltf.gltf"},
      {"khronos_EmissiveStrengthTest", "EmissiveStrengthTest.gltf"},
      {"khronos_LightsPunctualLamp", "LightsPunctualLamp.gltf"},
      {"khronos_MultiUVTest", "MultiUVTest.gltf"},
      {"revelry_ShadowsSpot", "shadows-spot.gltf"},
      {"revelry_ShadowsDirectional", "shadows-directional.gltf"},
      {"sauerbraten_zdm2_level_gltf", "zdm2.glb"}};
  bool ok = true;
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  for (const auto& [folder, file] : scenes) {
    Expected<scene::Scene> scene = scene::loadGltf((dir / folder / file).string(), {.load_textures = false});
    if (!scene) {
      std::printf("%-32s load error: %s\n", folder, scene.status().toString().c_str());
      rows.push_back({{"scene", folder}, {"error", scene.status().toString()}});
      ok = false;
      continue;
    }
    ok = row(folder, *scene, rows) && ok;
    if (std::string(folder) == "sauerbraten_zdm2_level_gltf") {
      for (scene::MeshInstance& m : scene->meshes) m = charts::test_meshes::subdivided(m);
      ok = row("zdm2 subdivided 1-to-4", *scene, rows) && ok;
    }
  }
  if (!json_path.empty()) {
    nlohmann::ordered_json doc = {
        {"benchmark", "charts_bench"},
        {"machine", {{"cpu", bench::cpuModel()}, {"hardware_threads", std::thread::hardware_concurrency()}}},
        {"rows", rows}};
    std::ofstream out(json_path);
    out << doc.dump(2) << "\n";
    if (!out) {
      std::fprintf(stderr, "charts_bench: cannot write %s\n", json_path.c_str());
      return 1;
    }
  }
  return ok ? 0 : 1;
}
