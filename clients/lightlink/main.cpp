// lightlink: the command-line front end. Parsing only: every subcommand is a run*()
// function in its own file (commands.h), so CLI11 is compiled once, here.
#include <fstream>
#include <iterator>

#include <CLI/CLI.hpp>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"
#include "clients/lightlink/version.h"
#include "core/bake/bake_options.h"
#include "core/common/isa.h"

namespace {

// The text of a --surfaces file (at most 1 MiB); CLI11 reports the error naming the option.
std::string readSurfaceRulesFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CLI::ValidationError("--surfaces", "cannot open '" + path + "'");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (text.size() > (std::size_t(1) << 20)) throw CLI::ValidationError("--surfaces", "'" + path + "' exceeds 1 MiB");
  // A file without an object is passed on as is: the option's parser names what is wrong.
  return text.find('{') == std::string::npos ? path : text;
}

// Registers every bake option of the one table (core/bake/bake_options.h) as --name, in the
// same group with the same help on every command that bakes; values are recorded in
// command-line order and parsed, range-checked and validated by the run* function's builder.
void addBakeOptions(CLI::App* cmd, lightlink::cli::BakeSettings& settings) {
  for (const lightlink::bake::OptionInfo& o : lightlink::bake::optionTable()) {
    const std::string name(o.name);
    cmd->add_option_function<std::string>(
           "--" + name,
           [&settings, name](const std::string& v) {
             // --surfaces names a file; the option table takes the rules' text (what OpenScene sends).
             settings.emplace_back(name, name == "surfaces" ? readSurfaceRulesFile(v) : v);
           },
           std::string(o.help))
        ->type_name(std::string(o.value))
        ->group("Bake options")
        ->trigger_on_parse();
  }
}

#ifdef LIGHTLINK_WITH_SERVICE
// Options every daemon command shares (docs/cli.md "Daemon commands").
void addRemoteOptions(CLI::App* cmd, lightlink::cli::RemoteArgs& r) {
  cmd->add_option("--session", r.session, "Session file written by `lightlink open --session`");
  cmd->add_option("--target", r.target, "Daemon address host:port (default: the session's, else 127.0.0.1:50051)");
  cmd->add_option("--token-file", r.token_file, "File holding the daemon bearer token (default: $LIGHTLINK_TOKEN)");
  cmd->add_option("--token", r.token,
                  "Refused: a token in argv is visible in ps; use --token-file or $LIGHTLINK_TOKEN");
  cmd->add_option("--tls-ca", r.tls_ca, "PEM root certificate: connect with TLS");
  cmd->add_option("--scene", r.scene_id, "Scene id (instead of --session)");
  cmd->add_option("--scene-token", r.scene_token, "Scene token (with --scene)");
  cmd->add_option("--timeout", r.timeout_ms, "Per-call deadline in ms (0 = none)")->capture_default_str();
}
#endif

}  // namespace

int main(int argc, char** argv) {
  using namespace lightlink::cli;
  CLI::App app{"lightlink: lightmap and irradiance-volume baking (precomputed illuminance composition)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("lightlink ") + lightlinkVersion() + " (commit " + lightlinkCommit() + ")");
  // Before the subcommand: `lightlink --isa avx2 bake ...`. Every tier gives the same bits.
  app.add_option_function<std::string>(
         "--isa",
         [](const std::string& v) {
           auto isa = lightlink::parseIsa(v);
           if (!isa) throw CLI::ValidationError("--isa", isa.status().message());
           lightlink::setIsaLimit(*isa);
         },
         "Highest SIMD tier to run: baseline, avx2 or avx512 (default: the CPU's best; also LIGHTLINK_ISA)");

  InspectArgs inspect;
  auto* inspect_cmd = app.add_subcommand("inspect", "Load and validate a glTF scene and print a summary");
  inspect_cmd->add_option("scene", inspect.scene_path, "Scene file (.gltf, .glb, .obj or .fbx)")->required();
  inspect_cmd->add_flag("--json", inspect.json, "Print the summary as JSON");
  inspect_cmd->add_option("--surfaces", inspect.surfaces_path, "Surface rules JSON applied first, as bake's --surfaces");
  inspect_cmd->add_flag("--allow-outside-scene", inspect.allow_outside_scene, "Read files the scene names outside its own folder (only for scenes you trust)");

  UnwrapArgs unwrap;
  auto* unwrap_cmd = app.add_subcommand("unwrap", "Generate lightmap UVs (TEXCOORD_1) and write the glTF back");
  unwrap_cmd->add_option("scene", unwrap.scene_path, "Scene file (.gltf, .glb, .obj or .fbx)")->required();
  unwrap_cmd->add_option("-o,--output", unwrap.output_path, "Output glTF with TEXCOORD_1 (.gltf or .glb)");
  unwrap_cmd->add_option("--preview", unwrap.preview_png, "Write a PNG of the chart layout");
  unwrap_cmd->add_option("--report", unwrap.report_json, "Write the quality report as JSON");
  unwrap_cmd->add_option("--texel-size", unwrap.texel_size_m, "Metres of surface per texel");
  unwrap_cmd->add_option("--resolution", unwrap.resolution, "Atlas width = height in texels (1..16384)");
  unwrap_cmd->add_option("--gutter", unwrap.gutter_texels, "Empty texels between charts")->capture_default_str();
  unwrap_cmd->add_flag("--json", unwrap.json, "Print the report as JSON");
  unwrap_cmd->add_flag("--allow-outside-scene", unwrap.allow_outside_scene, "Read files the scene names outside its own folder (only for scenes you trust)");

  PrecomputeArgs pre;
  auto* pre_cmd = app.add_subcommand("precompute", "Surfels, hierarchy, caches and links into one artifact (.llk)");
  pre_cmd->add_option("scene", pre.scene_path, "Scene file (.gltf, .glb, .obj or .fbx)")->required();
  pre_cmd->add_option("-o,--output", pre.output_path, "Artifact to write (.llk)")->required();
  pre_cmd->add_option("--report", pre.report_json, "Write the report (counts, times, memory) as JSON");
  addBakeOptions(pre_cmd, pre.options);
  pre_cmd->add_option("--subdivide", pre.subdivide, "Split every triangle into 4^N first (0..4)");
  pre_cmd->add_option("--shard", pre.shard,
                      "I/N: link only shard I of N (from 0) and write a part for `lightlink merge` (docs/farm.md)");
  pre_cmd->add_flag("-q,--quiet", pre.quiet, "No progress bar, no summary");
  pre_cmd->add_flag("--allow-outside-scene", pre.allow_outside_scene, "Read files the scene names outside its own folder (only for scenes you trust)");

  MergeArgs merge;
  auto* merge_cmd = app.add_subcommand("merge", "Assemble the parts of a sharded precompute into its artifact (.llk)");
  merge_cmd->add_option("parts", merge.part_paths, "Shard parts written by `precompute --shard I/N`, all N")->required();
  auto* merge_out = merge_cmd->add_option("-o,--output", merge.output_path, "Artifact to write (.llk)");
  merge_cmd->add_option("--cache-dir", merge.cache_dir,
                        "Write CACHE_DIR/<cache key>.llk instead, where `bake --cache-dir` finds and reuses it")
      ->excludes(merge_out);
  merge_cmd->add_option("--report", merge.report_json, "Write what was merged (parts, key, bytes, seconds) as JSON");
  merge_cmd->add_flag("-q,--quiet", merge.quiet, "No summary");

  BakeArgs bake;
  auto* bake_cmd = app.add_subcommand("bake", "Unwrap, precompute (or reuse), relight and write lightmaps, grid, report");
  bake_cmd->add_option("scenes", bake.scene_paths,
                       "Scene files (.gltf, .glb, .obj or .fbx); several: a batch, one folder each under OUTPUT")
      ->required();
  bake_cmd->add_flag("--batch", bake.batch, "Batch layout and summary (OUTPUT/<stem>/, summary.json, summary.xml) for one scene too");
  bake_cmd->add_option("-o,--output", bake.output_dir, "Output directory")->required();
  addBakeOptions(bake_cmd, bake.options);
  bake_cmd->add_option("--lights", bake.lights_path, "Light-set JSON adding to or overriding the scene's lights");
  bake_cmd->add_option("--cache-dir", bake.cache_dir, "Artifact cache directory, shared by every scene of a batch (default OUTPUT/cache)");
  bake_cmd->add_option("--backend", bake.backend, "Relight backend: cpu, gpu, or auto (GPU when a headless EGL context works)")
      ->capture_default_str();
  bake_cmd->add_flag("--float", bake.float_exr, "32-bit float EXR instead of half");
  bake_cmd->add_option("--encoding", bake.encoding,
                       "Lightmap and grid encoding: l0 (RGB irradiance), l1 (4 SH coefficients) or l2 (all bands); "
                       "irradiance.exr is written for every encoding")
      ->capture_default_str();
  bake_cmd->add_flag("--no-cache", bake.no_cache, "Recompute even when a matching artifact exists");
  bake_cmd->add_flag("-q,--quiet", bake.quiet, "No progress bar, no summary");
  bake_cmd->add_flag("--allow-outside-scene", bake.allow_outside_scene, "Read files the scene names outside its own folder (only for scenes you trust)");
  bake_cmd->add_option("--scenario", bake.scenarios,
                       "NAME=LIGHTS.json: also relight with this light-set file over the base lights and write "
                       "its lighting to scenarios/NAME/ (repeatable; docs/outputs.md \"Lighting scenarios\")");
  bake_cmd->add_option("--fail-on", bake.fail_on, "Exit non-zero after writing the outputs: never, dark (no light or an all-black lightmap: exit 7) or warning (any warning: exit 6)")->capture_default_str();

  RenderArgs render;
  auto* render_cmd = app.add_subcommand("render", "Render a camera view lit by a bake's lightmap and grid, to PNG");
  render_cmd->add_option("scene", render.scene_path, "The *_lm.gltf written by bake")->required();
  render_cmd->add_option("--bake", render.bake_dir, "Bake output directory (lightmap_<c>.exr or irradiance.exr, grid.raw)")->required();
  render_cmd->add_option("-o,--output", render.output_png, "PNG to write")->required();
  render_cmd->add_option("--lights", render.lights_path, "Light-set JSON (the one given to bake)");
  render_cmd->add_option("--eye", render.eye, "Camera position x,y,z (m)")->expected(3)->delimiter(',');
  render_cmd->add_option("--target", render.target, "Point looked at x,y,z (m)")->expected(3)->delimiter(',');
  render_cmd->add_option("--fov", render.fov_deg, "Vertical field of view, degrees")->capture_default_str();
  render_cmd->add_option("--width", render.width, "Image width")->capture_default_str();
  render_cmd->add_option("--height", render.height, "Image height")->capture_default_str();
  render_cmd->add_option("--exposure", render.exposure, "Exposure scale (0 = auto)");
  render_cmd->add_flag("-q,--quiet", render.quiet, "No summary");
  render_cmd->add_flag("--allow-outside-scene", render.allow_outside_scene, "Read files the scene names outside its own folder (only for scenes you trust)");

  CompareArgs cmp;
  auto* cmp_cmd = app.add_subcommand("compare", "Bake a scene and measure its lightmap against the path-traced reference");
  cmp_cmd->add_option("scene", cmp.scene_path, "Scene file (.gltf, .glb, .obj or .fbx)")->required();
  cmp_cmd->add_option("--against", cmp.against, "What to compare with: reference")->capture_default_str();
  addBakeOptions(cmp_cmd, cmp.options);
  cmp_cmd->add_option("--lights", cmp.lights_path, "Light-set JSON adding to or overriding the scene's lights");
  cmp_cmd->add_option("-o,--output", cmp.output_dir, "Directory for compare.json and error heat maps");
  cmp_cmd->add_option("--max-points", cmp.max_points, "Most lightmap caches compared")->capture_default_str();
  cmp_cmd->add_option("--target-error", cmp.target_error, "Reference relative standard error per point")
      ->capture_default_str();
  cmp_cmd->add_option("--time-budget", cmp.time_budget_s, "Seconds for the reference (0 = none)");
  cmp_cmd->add_option("--error-floor", cmp.error_floor,
                      "Absolute error floor as a fraction of the mean reference: rel. error = |b - r| / max(r, floor)")
      ->capture_default_str();
  cmp_cmd->add_flag("-q,--quiet", cmp.quiet, "No progress bar, no summary");
  cmp_cmd->add_flag("--allow-outside-scene", cmp.allow_outside_scene, "Read files the scene names outside its own folder (only for scenes you trust)");

#ifdef LIGHTLINK_WITH_SERVICE
  auto* serve_cmd = app.add_subcommand("serve", "Run the lightlink daemon in this process (same flags as lightlinkd)");
  serve_cmd->prefix_command();  // every argument after `serve` is lightlinkd's
  serve_cmd->set_help_flag();   // so that `serve --help` prints the daemon's help

  OpenArgs open;
  auto* open_cmd = app.add_subcommand("open", "Open a scene on a daemon and print its id, token and info as JSON");
  open_cmd->add_option("scene", open.scene_path, "Scene file (.gltf, .glb, .obj or .fbx)")->required();
  addRemoteOptions(open_cmd, open.remote);
  open_cmd->add_flag("--upload", open.upload, "Send the file's bytes instead of its path");
  addBakeOptions(open_cmd, open.options);
  open_cmd->add_option("--lights", open.lights_path, "Light-set JSON applied over the scene's lights");
  open_cmd->add_option("--name", open.name, "Name shown by ListScenes (default: the file's stem)");
  open_cmd->add_option("--backend", open.backend, "Relight backend: auto, cpu or gpu")->capture_default_str();

  SetLightArgs setl;
  auto* setl_cmd = app.add_subcommand("set-light", "Change, add or remove a light of an open scene");
  setl_cmd->add_option("light", setl.light_id, "Light id");
  addRemoteOptions(setl_cmd, setl.remote);
  setl_cmd->add_option("--json", setl.json_path, "Apply a light-set file (docs/lightset.md) instead");
  setl_cmd->add_option("--type", setl.type, "point, spot or directional");
  setl_cmd->add_option("--position", setl.position, "x,y,z (m)")->expected(3)->delimiter(',');
  setl_cmd->add_option("--direction", setl.direction, "x,y,z (non-zero)")->expected(3)->delimiter(',');
  setl_cmd->add_option("--color", setl.color, "r,g,b linear")->expected(3)->delimiter(',');
  setl_cmd->add_option("--intensity", setl.intensity, "cd (point, spot) or lux (directional)");
  setl_cmd->add_option("--range", setl.range, "m (0 = infinite)");
  setl_cmd->add_option("--inner-cone", setl.inner_cone_angle, "Spot inner cone angle, radians");
  setl_cmd->add_option("--outer-cone", setl.outer_cone_angle, "Spot outer cone angle, radians");
  setl_cmd->add_option("--baked", setl.baked, "true or false: direct light written into the lightmap");
  setl_cmd->add_flag("--add", setl.add, "Add a new light (--type required)");
  setl_cmd->add_flag("--remove", setl.remove, "Remove the light");
  setl_cmd->add_flag("--wait", setl.wait, "Wait for the relit lightmap and print the light-change-to-texture latency");
  setl_cmd->add_option("--wait-ms", setl.wait_ms, "Longest wait for the relight")->capture_default_str();
  setl_cmd->add_flag("--json-output", setl.json, "Print the result as JSON");

  ScenarioArgs scen;
  auto* scen_cmd = app.add_subcommand("scenario", "Define lighting scenarios of an open scene, switch and blend them");
  scen_cmd->add_option("action", scen.action, "set (define, replace or remove one) or use (switch to or blend)")->required();
  scen_cmd->add_option("names", scen.names, "set: NAME; use: NAME[=WEIGHT] ... (weight 1 when omitted)")->required();
  addRemoteOptions(scen_cmd, scen.remote);
  scen_cmd->add_option("--lights", scen.lights_path, "set: a light-set file applied over the scene's own lights");
  scen_cmd->add_flag("--from-current", scen.from_current, "set: the scene's current light set");
  scen_cmd->add_flag("--remove", scen.remove, "set: forget the scenario");
  scen_cmd->add_flag("--wait", scen.wait, "use: wait for the relit result");
  scen_cmd->add_option("--wait-ms", scen.wait_ms, "Longest wait for the relight")->capture_default_str();

  WatchArgs watch;
  lightlink::cli::RemoteArgs close_args;
  auto* close_cmd = app.add_subcommand("close", "Close a scene on the daemon (it leaves memory and sessions.json)");
  addRemoteOptions(close_cmd, close_args);

  auto* watch_cmd = app.add_subcommand("watch", "Subscribe to a scene and print one line per new version");
  addRemoteOptions(watch_cmd, watch.remote);
  watch_cmd->add_option("--count", watch.count, "Stop after N results (0 = until the stream ends)");
  watch_cmd->add_flag("--full", watch.full, "Full results instead of tile deltas");
  watch_cmd->add_flag("--json", watch.json, "One JSON object per line");

  PullArgs pull;
  auto* pull_cmd = app.add_subcommand("pull", "Fetch a result once and write lightmap EXR + PNG preview + grid");
  addRemoteOptions(pull_cmd, pull.remote);
  pull_cmd->add_option("-o,--output", pull.output_dir, "Output directory")->required();
  pull_cmd->add_option("--version", pull.version, "Light-set version (0 = newest)");
  pull_cmd->add_option("--bands", pull.bands, "SH bands to fetch (0 = all)");
  pull_cmd->add_flag("--float", pull.float_exr, "32-bit float instead of half");
  pull_cmd->add_option("--encoding", pull.encoding, "Written encoding: l0, l1 or l2, as bake's --encoding")
      ->capture_default_str();
  pull_cmd->add_flag("-q,--quiet", pull.quiet, "No summary");

  LightsArgs lights;
  auto* lights_cmd =
      app.add_subcommand("lights", "Print a scene's current light set as a light-set JSON document (docs/lightset.md)");
  addRemoteOptions(lights_cmd, lights.remote);
  lights_cmd->add_option("-o,--output", lights.output_path, "Write the document to this file instead of stdout");

  UvsArgs uvs;
  auto* uvs_cmd = app.add_subcommand("uvs", "Fetch the lightmap UVs a resident scene is lit with");
  addRemoteOptions(uvs_cmd, uvs.remote);
  uvs_cmd->add_option("--gltf", uvs.gltf_path, "Write the scene with its lightmap UVs as TEXCOORD_1 (.glb)");
  uvs_cmd->add_option("--json", uvs.json_path,
                      "Write every mesh's UVs as JSON (node, mesh, primitive, source_vertex, uv, indices)");
#endif

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  }
  if (*inspect_cmd) return runGuarded("inspect", [&] { return runInspect(inspect); });
  if (*unwrap_cmd) return runGuarded("unwrap", [&] { return runUnwrap(unwrap); });
  if (*pre_cmd) return runGuarded("precompute", [&] { return runPrecompute(pre); });
  if (*merge_cmd) return runGuarded("merge", [&] { return runMerge(merge); });
  if (*bake_cmd) return runGuarded("bake", [&] { return runBake(bake); });
  if (*render_cmd) return runGuarded("render", [&] { return runRender(render); });
  if (*cmp_cmd) return runGuarded("compare", [&] { return runCompare(cmp); });
#ifdef LIGHTLINK_WITH_SERVICE
  if (*serve_cmd) return runServe(serve_cmd->remaining());
  if (*open_cmd) return runOpen(open);
  if (*setl_cmd) return runSetLight(setl);
  if (*scen_cmd) return runScenario(scen);
  if (*watch_cmd) return runWatch(watch);
  if (*close_cmd) return runClose(close_args);
  if (*pull_cmd) return runPull(pull);
  if (*lights_cmd) return runLights(lights);
  if (*uvs_cmd) return runUvs(uvs);
#endif
  return kExitUsage;
}
