// charts_figures: the issue-3 figures for docs/results.md. Unwraps every shared scene with
// default options (what `lightlink unwrap` does) and prints one markdown row each, then
// zdm2 subdivided 1-to-4 (~230k triangles) for the timing target. Times are the best of
// three runs (the build machine is shared). Usage: charts_figures <shared scenes dir>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>

#include "core/charts/test_meshes.h"
#include "core/charts/unwrap.h"
#include "core/scene/load.h"

using namespace lightlink;

namespace {

bool row(const std::string& label, const scene::Scene& loaded) {
  double best = 1e30;
  charts::UnwrapReport report;
  for (int run = 0; run < 3; ++run) {
    scene::Scene scene = loaded;
    Expected<charts::UnwrapResult> result = charts::unwrap(scene, {});
    if (!result) {
      std::printf("| %s | error: %s |\n", label.c_str(), result.status().toString().c_str());
      return false;
    }
    best = std::min(best, result->report.seconds);
    report = result->report;
  }
  if (!report.generated) {
    std::printf("| %s | %zu | kept TEXCOORD_1 | - | %.1f %% (centres) | - | %zu overlapping centres | %.3f |\n",
                label.c_str(), report.triangles, 100.0 * report.utilisation, report.overlaps, best);
    return true;
  }
  std::printf("| %s | %zu | %d | %dx%d, %.4g m | %.1f %% | %.2f / %.3f | %zu | %.3f |\n", label.c_str(),
              report.triangles, report.charts, report.resolution, report.resolution, report.texel_size_m,
              100.0 * report.utilisation, report.max_area_stretch, report.mean_area_stretch, report.overlaps, best);
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <shared scenes dir>\n", argv[0]);
    return 2;
  }
  const std::filesystem::path dir = argv[1];
  const std::pair<const char*, const char*> scenes[] = {
      {"cornell_box_original_gltf", "CornellBox-Original.gltf"},
      {"cornell_box_vinc3r_lightmapuv", "cornellBox-2.80-Eevee-gltf.gltf"},
      {"khronos_EmissiveStrengthTest", "EmissiveStrengthTest.gltf"},
      {"khronos_LightsPunctualLamp", "LightsPunctualLamp.gltf"},
      {"khronos_MultiUVTest", "MultiUVTest.gltf"},
      {"revelry_ShadowsSpot", "shadows-spot.gltf"},
      {"revelry_ShadowsDirectional", "shadows-directional.gltf"},
      {"sauerbraten_zdm2_level_gltf", "zdm2.glb"}};
  std::printf("| scene | static tris | charts | atlas, texel | utilisation | max / mean area stretch | overlaps | time s |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  bool ok = true;
  for (const auto& [folder, file] : scenes) {
    Expected<scene::Scene> scene = scene::loadGltf((dir / folder / file).string(), {.load_textures = false});
    if (!scene) {
      std::printf("| %s | load error: %s |\n", folder, scene.status().toString().c_str());
      ok = false;
      continue;
    }
    ok = row(folder, *scene) && ok;
    if (std::string(folder) == "sauerbraten_zdm2_level_gltf") {
      for (scene::MeshInstance& m : scene->meshes) m = charts::test_meshes::subdivided(m);
      ok = row("zdm2 subdivided 1-to-4", *scene) && ok;
    }
  }
  return ok ? 0 : 1;
}
