// The subcommands of the `lightlink` CLI. main.cpp parses the command line (CLI11) into
// these argument structs and calls run*(); each returns a process exit code
// (exit_codes.h). Keeping parsing apart from doing lets tests call commands directly.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace lightlink::cli {

// Bake options as given on the command line, (name without "--", value) in order: every
// command that bakes builds them through bake::BakeOptionsBuilder (core/bake/bake_options.h),
// so bake, compare, precompute and open accept the same options with the same ranges.
using BakeSettings = std::vector<std::pair<std::string, std::string>>;

struct InspectArgs {
  std::string scene_path;
  std::string surfaces_path;  // surface rules applied before the summary (bake's --surfaces)
  bool json = false;
  bool allow_outside_scene = false;  // read files the scene names outside its folder
};
int runInspect(const InspectArgs& args);

struct UnwrapArgs {
  std::string scene_path;
  std::string output_path;   // glTF with TEXCOORD_1
  std::string preview_png;
  std::string report_json;
  std::optional<float> texel_size_m;
  std::optional<int> resolution;
  int gutter_texels = 2;
  bool json = false;         // print the report as JSON instead of text
  bool allow_outside_scene = false;  // read files the scene names outside its folder
};
int runUnwrap(const UnwrapArgs& args);

struct PrecomputeArgs {
  std::string scene_path;
  std::string output_path;   // .llk artifact
  std::string report_json;
  BakeSettings options;           // over PrecomputeOptions' defaults (no preset unless given)
  int subdivide = 0;              // split every triangle into 4^N first (scale tests)
  std::string shard;              // "I/N": write shard I's part of the run (docs/farm.md)
  bool quiet = false;
  bool allow_outside_scene = false;  // read files the scene names outside its folder
};
int runPrecompute(const PrecomputeArgs& args);

// `merge PART... -o ARTIFACT`: the parts of a sharded precompute into its artifact.
struct MergeArgs {
  std::vector<std::string> part_paths;
  std::string output_path;
  std::string cache_dir;  // instead of output_path: CACHE_DIR/<key>.llk, where bake --cache-dir looks
  std::string report_json;
  bool quiet = false;
};
int runMerge(const MergeArgs& args);

struct BakeArgs {
  // One scene: its outputs in output_dir. Several (or batch): a batch bake, each scene's
  // outputs in output_dir/<stem>/, summary.json and summary.xml in output_dir.
  std::vector<std::string> scene_paths;
  bool batch = false;
  std::string output_dir;
  BakeSettings options;            // over the medium preset
  std::string lights_path;         // light-set JSON adding to / overriding the scene's lights
  std::string cache_dir;           // artifacts by cache key, shared by a batch; empty = <output_dir>/cache
  std::string backend = "cpu";     // cpu | gpu | auto (gpu/backend_factory.h)
  bool float_exr = false;
  std::string encoding = "l2";     // l0 | l1 | l2 (core/output/encoding.h)
  bool no_cache = false;           // recompute even when a matching artifact exists
  bool quiet = false;
  bool allow_outside_scene = false;  // read files the scene names outside its folder
  std::string fail_on = "never";   // never | dark | warning (docs/cli.md "Exit codes")
  std::vector<std::string> scenarios;  // NAME=LIGHTS.json: one more relight each, in scenarios/NAME/
};
int runBake(const BakeArgs& args);

struct RenderArgs {
  std::string scene_path;    // the *_lm.gltf a bake wrote (static meshes carry TEXCOORD_1)
  std::string bake_dir;      // lightmap_<c>.exr or irradiance.exr (+ grid.raw)
  std::string output_png;
  std::string lights_path;   // same light set as the bake
  std::vector<float> eye, target;  // 3 values each; empty = defaultCamera()
  float fov_deg = 40.0f;
  int width = 512, height = 512;
  float exposure = 0.0f;
  bool quiet = false;
  bool allow_outside_scene = false;  // read files the scene names outside its folder
};
int runRender(const RenderArgs& args);

struct CompareArgs {
  std::string scene_path;
  std::string against = "reference";
  BakeSettings options;           // over the medium preset; the baker's bounce cap defaults to 64
  std::string lights_path;
  std::string output_dir;         // compare.json and error heat maps
  int max_points = 4096;          // valid lightmap caches compared (evenly strided)
  float target_error = 0.01f;     // the reference's relative standard error per point
  double time_budget_s = 0.0;     // for the reference; 0 = none
  double error_floor = 0.05;      // rel. error = |b - r| / max(r, error_floor * mean(r)) (docs/quality.md)
  bool quiet = false;
  bool allow_outside_scene = false;  // read files the scene names outside its folder
};
int runCompare(const CompareArgs& args);

// ---- Daemon commands (built with LIGHTLINK_BUILD_SERVICE; cmd_serve.cpp, cmd_remote.cpp).

// `serve`: the daemon in-process; `args` are lightlinkd's flags, passed through unchanged.
int runServe(const std::vector<std::string>& args);

// How a command reaches a daemon and names a scene: a session file (`open --session`), or
// --target with --scene/--scene-token.
struct RemoteArgs {
  std::string target;        // host:port; default: the session's, else 127.0.0.1:50051
  std::string token;         // --token: refused (argv is visible in ps)
  std::string token_file;    // daemon bearer token's file; default: $LIGHTLINK_TOKEN
  std::string tls_ca;        // PEM root certificate: TLS instead of plaintext
  std::string session;       // session file
  std::string scene_id, scene_token;
  int timeout_ms = 30000;    // per call
};

struct OpenArgs {
  RemoteArgs remote;         // remote.session: where to write the session file
  std::string scene_path;
  bool upload = false;       // send the file's bytes instead of its path
  BakeSettings options;      // sent as OpenScene `options` (daemon default preset: medium)
  std::string lights_path;   // light-set JSON applied over the scene's lights
  std::string name;
  std::string backend = "auto";  // auto | cpu | gpu
};
int runOpen(const OpenArgs& args);

struct SetLightArgs {
  RemoteArgs remote;
  std::string light_id;
  std::string json_path;     // a light-set file instead of the per-field flags
  std::string type;          // point | spot | directional
  std::vector<float> position, direction, color;  // 3 values each when given
  std::optional<float> intensity, range, inner_cone_angle, outer_cone_angle;
  std::string baked;         // "", "true" or "false"
  bool add = false;          // a new light (type required)
  bool remove = false;
  bool wait = false;         // wait for the relit lightmap and report the latency
  int wait_ms = 10000;
  bool json = false;
};
int runSetLight(const SetLightArgs& args);

// `lightlink scenario set NAME --lights FILE | --from-current | --remove`, and
// `lightlink scenario use NAME[=WEIGHT]...` (docs/cli.md "scenario").
struct ScenarioArgs {
  RemoteArgs remote;
  std::string action;              // set | use
  std::vector<std::string> names;  // set: one NAME; use: NAME[=WEIGHT] ...
  std::string lights_path;         // set: a light-set file over the scene's own lights
  bool from_current = false;       // set: the scene's current light set
  bool remove = false;             // set: forget the scenario
  bool wait = false;               // use: wait for the relit result
  int wait_ms = 10000;
};
int runScenario(const ScenarioArgs& args);

struct WatchArgs {
  RemoteArgs remote;
  int count = 0;             // stop after this many results (0 = until the stream ends)
  bool full = false;         // full results instead of tile deltas
  bool json = false;         // one JSON object per line
};
int runWatch(const WatchArgs& args);

// `lightlink close`: closes the scene on the daemon (its session forgotten, memory freed).
int runClose(const RemoteArgs& args);

struct PullArgs {
  RemoteArgs remote;
  std::string output_dir;
  std::uint64_t version = 0;  // 0 = newest
  bool float_exr = false;     // float32 payloads and EXR
  int bands = 0;
  std::string encoding = "l2";  // l0 | l1 | l2, as bake's --encoding
  bool quiet = false;
};
int runPull(const PullArgs& args);

struct LightsArgs {
  RemoteArgs remote;
  std::string output_path;  // empty: stdout
};
int runLights(const LightsArgs& args);

struct UvsArgs {
  RemoteArgs remote;
  std::string gltf_path;  // .glb with TEXCOORD_1
  std::string json_path;  // per-mesh UVs as JSON
};
int runUvs(const UvsArgs& args);

}  // namespace lightlink::cli
