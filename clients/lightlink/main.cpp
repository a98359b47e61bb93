// lightlink: the command-line front end. Parsing only: every subcommand is a run*()
// function in its own file (commands.h), so CLI11 is compiled once, here.
#include <CLI/CLI.hpp>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"

int main(int argc, char** argv) {
  using namespace lightlink::cli;
  CLI::App app{"lightlink: lightmap and irradiance-volume baking (precomputed illuminance composition)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "lightlink 0.1.0");

  InspectArgs inspect;
  auto* inspect_cmd = app.add_subcommand("inspect", "Load and validate a glTF scene and print a summary");
  inspect_cmd->add_option("scene", inspect.scene_path, "glTF scene (.gltf or .glb)")->required();
  inspect_cmd->add_flag("--json", inspect.json, "Print the summary as JSON");

  UnwrapArgs unwrap;
  auto* unwrap_cmd = app.add_subcommand("unwrap", "Generate lightmap UVs (TEXCOORD_1) and write the glTF back");
  unwrap_cmd->add_option("scene", unwrap.scene_path, "glTF scene (.gltf or .glb)")->required();
  unwrap_cmd->add_option("-o,--output", unwrap.output_path, "Output glTF with TEXCOORD_1 (.gltf or .glb)");
  unwrap_cmd->add_option("--preview", unwrap.preview_png, "Write a PNG of the chart layout");
  unwrap_cmd->add_option("--report", unwrap.report_json, "Write the quality report as JSON");
  unwrap_cmd->add_option("--texel-size", unwrap.texel_size_m, "Metres of surface per texel");
  unwrap_cmd->add_option("--resolution", unwrap.resolution, "Atlas width = height in texels (1..16384)");
  unwrap_cmd->add_option("--gutter", unwrap.gutter_texels, "Empty texels between charts")->capture_default_str();
  unwrap_cmd->add_flag("--json", unwrap.json, "Print the report as JSON");

  PrecomputeArgs pre;
  auto* pre_cmd = app.add_subcommand("precompute", "Surfels, hierarchy, caches and links into one artifact (.llk)");
  pre_cmd->add_option("scene", pre.scene_path, "glTF scene (.gltf or .glb)")->required();
  pre_cmd->add_option("-o,--output", pre.output_path, "Artifact to write (.llk)")->required();
  pre_cmd->add_option("--report", pre.report_json, "Write the report (counts, times, memory) as JSON");
  pre_cmd->add_option("--surfels", pre.surfels, "nS: number of surfels")->capture_default_str();
  pre_cmd->add_option("--links", pre.links, "nL: most links per cache")->capture_default_str();
  pre_cmd->add_option("--bands", pre.bands, "SH bands of the links (1..4)")->capture_default_str();
  pre_cmd->add_option("--rays", pre.rays, "Link rays per cache")->capture_default_str();
  pre_cmd->add_option("--hierarchy", pre.hierarchy, "Tree builder: fast (kd median) or hac")->capture_default_str();
  pre_cmd->add_option("--grid", pre.grid, "Grid caches: auto (when dynamic meshes exist), on, off")
      ->capture_default_str();
  pre_cmd->add_option("--grid-spacing", pre.grid_spacing_m, "Grid spacing in metres (0 = 16 along the longest axis)");
  pre_cmd->add_option("--texel-size", pre.texel_size_m, "Lightmap texel size in metres");
  pre_cmd->add_option("--resolution", pre.resolution, "Lightmap resolution in texels");
  pre_cmd->add_option("--subdivide", pre.subdivide, "Split every triangle into 4^N first (0..4)");
  pre_cmd->add_flag("-q,--quiet", pre.quiet, "No progress bar, no summary");

  BakeArgs bake;
  auto* bake_cmd = app.add_subcommand("bake", "Unwrap, precompute (or reuse), relight and write lightmaps, grid, report");
  bake_cmd->add_option("scene", bake.scene_path, "glTF scene (.gltf or .glb)")->required();
  bake_cmd->add_option("-o,--output", bake.output_dir, "Output directory")->required();
  bake_cmd->add_option("--preset", bake.preset, "Quality: draft, medium or high")->capture_default_str();
  bake_cmd->add_option("--lights", bake.lights_path, "Light-set JSON adding to or overriding the scene's lights");
  bake_cmd->add_option("--cache-dir", bake.cache_dir, "Artifact cache directory (default OUTPUT/cache)");
  bake_cmd->add_option("--link-form", bake.link_form, "projected or runtime")->capture_default_str();
  bake_cmd->add_option("--bounces", bake.max_bounces, "Most indirect bounces")->capture_default_str();
  bake_cmd->add_flag("--float", bake.float_exr, "32-bit float EXR instead of half");
  bake_cmd->add_flag("--no-cache", bake.no_cache, "Recompute even when a matching artifact exists");
  bake_cmd->add_flag("-q,--quiet", bake.quiet, "No progress bar, no summary");

  RenderArgs render;
  auto* render_cmd = app.add_subcommand("render", "Render a camera view lit by a bake's lightmap and grid, to PNG");
  render_cmd->add_option("scene", render.scene_path, "The *_lm.gltf written by bake")->required();
  render_cmd->add_option("--bake", render.bake_dir, "Bake output directory (lightmap.exr, grid.raw)")->required();
  render_cmd->add_option("-o,--output", render.output_png, "PNG to write")->required();
  render_cmd->add_option("--lights", render.lights_path, "Light-set JSON (the one given to bake)");
  render_cmd->add_option("--eye", render.eye, "Camera position x,y,z (m)")->expected(3)->delimiter(',');
  render_cmd->add_option("--target", render.target, "Point looked at x,y,z (m)")->expected(3)->delimiter(',');
  render_cmd->add_option("--fov", render.fov_deg, "Vertical field of view, degrees")->capture_default_str();
  render_cmd->add_option("--width", render.width, "Image width")->capture_default_str();
  render_cmd->add_option("--height", render.height, "Image height")->capture_default_str();
  render_cmd->add_option("--exposure", render.exposure, "Exposure scale (0 = auto)");
  render_cmd->add_flag("-q,--quiet", render.quiet, "No summary");

  CompareArgs cmp;
  auto* cmp_cmd = app.add_subcommand("compare", "Bake a scene and measure its lightmap against the path-traced reference");
  cmp_cmd->add_option("scene", cmp.scene_path, "glTF scene (.gltf or .glb)")->required();
  cmp_cmd->add_option("--against", cmp.against, "What to compare with: reference")->capture_default_str();
  cmp_cmd->add_option("--preset", cmp.preset, "Bake quality: draft, medium or high")->capture_default_str();
  cmp_cmd->add_option("--lights", cmp.lights_path, "Light-set JSON adding to or overriding the scene's lights");
  cmp_cmd->add_option("-o,--output", cmp.output_dir, "Directory for compare.json and error heat maps");
  cmp_cmd->add_option("--max-points", cmp.max_points, "Most lightmap caches compared")->capture_default_str();
  cmp_cmd->add_option("--target-error", cmp.target_error, "Reference relative standard error per point")
      ->capture_default_str();
  cmp_cmd->add_option("--time-budget", cmp.time_budget_s, "Seconds for the reference (0 = none)");
  cmp_cmd->add_option("--bounces", cmp.max_bounces, "Baker's bounce cap")->capture_default_str();
  cmp_cmd->add_flag("-q,--quiet", cmp.quiet, "No progress bar, no summary");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  }
  if (*inspect_cmd) return runInspect(inspect);
  if (*unwrap_cmd) return runUnwrap(unwrap);
  if (*pre_cmd) return runPrecompute(pre);
  if (*bake_cmd) return runBake(bake);
  if (*render_cmd) return runRender(render);
  if (*cmp_cmd) return runCompare(cmp);
  return kExitUsage;
}
