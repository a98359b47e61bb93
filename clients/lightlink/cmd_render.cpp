// `lightlink render`: a camera view lit only by a bake's outputs (lightmap, grid) plus
// direct light, to PNG — how people check that a bake looks right.
#include <cstdio>

#include <fmt/format.h>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "clients/lightlink/scene_access.h"
#include "clients/viewer/render.h"
#include "core/common/png.h"
#include "core/scene/load.h"

namespace lightlink::cli {

int runRender(const RenderArgs& args) {
  constexpr const char* kCmd = "render";
  scene::LoadOptions load;
  load.files = sceneFileAccess(args.allow_outside_scene);
  auto scene = scene::loadScene(args.scene_path, load);
  if (!scene) return reportError(kCmd, scene.status());
  bool any_uv1 = false;
  for (const auto& m : scene->meshes) any_uv1 |= m.is_static && m.hasLightmapUv();
  if (!any_uv1)
    return reportError(kCmd, invalidInput("{} has no static mesh with TEXCOORD_1: render the *_lm.gltf that "
                                          "`lightlink bake` wrote next to the lightmap",
                                          args.scene_path));
  auto baked = viewer::loadBakedLighting(args.bake_dir);
  if (!baked) return reportError(kCmd, baked.status());
  auto lights = relight::LightSet::fromSceneLights(scene->lights);
  if (!args.lights_path.empty())
    if (Status s = lights.applyFile(args.lights_path); !s) return reportError(kCmd, s);
  rt::AccelOptions accel_options;
  accel_options.static_only = false;  // dynamic objects are seen (and cast shadows) too
  auto accel = rt::Accel::build(*scene, accel_options);
  if (!accel) return reportError(kCmd, accel.status());

  viewer::Camera camera = viewer::defaultCamera(*scene);
  if (!args.eye.empty()) camera.eye = {args.eye[0], args.eye[1], args.eye[2]};
  if (!args.target.empty()) camera.target = {args.target[0], args.target[1], args.target[2]};
  camera.vertical_fov_deg = args.fov_deg;
  viewer::RenderOptions options{args.width, args.height, args.exposure};
  std::vector<std::uint8_t> rgb;
  auto stats = viewer::render(*scene, *accel, *baked, lights, camera, options, rgb);
  if (!stats) return reportError(kCmd, stats.status());
  if (Status s = writePngRgb8(args.output_png, args.width, args.height, rgb, "render"); !s)
    return reportError(kCmd, s);
  if (!args.quiet) {
    const std::string text = fmt::format(
        "rendered     {}x{} in {:.1f} ms: {} pixels from the lightmap, {} from the grid, {} unlit, {} shadow rays\n"
        "wrote        {}\n",
        args.width, args.height, stats->seconds * 1e3, stats->lightmap_pixels, stats->grid_pixels,
        stats->unlit_pixels, stats->shadow_rays, args.output_png);
    std::fwrite(text.data(), 1, text.size(), stdout);
  }
  return kExitOk;
}

}  // namespace lightlink::cli
