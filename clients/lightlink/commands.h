// The subcommands of the `lightlink` CLI. main.cpp parses the command line (CLI11) into
// these argument structs and calls run*(); each returns a process exit code
// (exit_codes.h). Keeping parsing apart from doing lets tests call commands directly.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace lightlink::cli {

struct InspectArgs {
  std::string scene_path;
  bool json = false;
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
};
int runUnwrap(const UnwrapArgs& args);

struct PrecomputeArgs {
  std::string scene_path;
  std::string output_path;   // .llk artifact
  std::string report_json;
  std::uint32_t surfels = 32768;
  int links = 128;
  int bands = 3;
  int rays = 1024;
  std::string hierarchy = "hac";  // fast | hac
  std::string grid = "auto";      // auto | on | off
  float grid_spacing_m = 0.0f;
  std::optional<float> texel_size_m;
  std::optional<int> resolution;
  int subdivide = 0;              // split every triangle into 4^N first (scale tests)
  bool quiet = false;
};
int runPrecompute(const PrecomputeArgs& args);

struct BakeArgs {
  std::string scene_path;
  std::string output_dir;
  std::string preset = "medium";   // draft | medium | high
  std::string lights_path;         // light-set JSON adding to / overriding the scene's lights
  std::string cache_dir;           // artifacts by cache key; empty = <output_dir>/cache
  std::string link_form = "projected";  // projected | runtime
  int max_bounces = 8;
  bool float_exr = false;
  bool no_cache = false;           // recompute even when a matching artifact exists
  bool quiet = false;
};
int runBake(const BakeArgs& args);

struct RenderArgs {
  std::string scene_path;    // the *_lm.gltf a bake wrote (static meshes carry TEXCOORD_1)
  std::string bake_dir;      // lightmap.exr (+ grid.raw)
  std::string output_png;
  std::string lights_path;   // same light set as the bake
  std::vector<float> eye, target;  // 3 values each; empty = defaultCamera()
  float fov_deg = 40.0f;
  int width = 512, height = 512;
  float exposure = 0.0f;
  bool quiet = false;
};
int runRender(const RenderArgs& args);

struct CompareArgs {
  std::string scene_path;
  std::string against = "reference";
  std::string preset = "medium";
  std::string lights_path;
  std::string output_dir;         // compare.json and error heat maps
  int max_points = 4096;          // valid lightmap caches compared (evenly strided)
  float target_error = 0.01f;     // the reference's relative standard error per point
  double time_budget_s = 0.0;     // for the reference; 0 = none
  int max_bounces = 64;           // the baker's bounce cap (threshold 1e-4)
  bool quiet = false;
};
int runCompare(const CompareArgs& args);

}  // namespace lightlink::cli
