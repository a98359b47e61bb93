// ray_bench: raw Embree ray throughput through core/rt, the yardstick later stages
// (link generation) are compared against (DESIGN.md sec. 11).
//
// Measures rays/second for coherent primary rays (pinhole camera, 4x4-pixel tiles, so a
// 16-ray packet is 16 neighbouring pixels) and incoherent diffuse rays (area-uniform
// surface points, cosine directions, independent draws), for closest hit and occlusion,
// through each ray API (single rays, 16-wide packets, 1M streams), on one thread and on
// all TBB threads. Prints a table; --json writes the same figures with the machine.
//
//   ray_bench [--scene file.gltf|.glb] [--subdivide N] [--json out.json] [--width W]
//             [--height H] [--rays N] [--seconds S] [--threads N] [--seed N]
//             [--quality high|fast] [--no-robust]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/info.h>

#include "bench/rt/procedural.h"
#include "bench/rt/throughput.h"
#include "core/rt/accel.h"
#include "core/scene/load.h"

namespace {

using namespace lightlink;

struct Args {
  std::string scene_path;  // empty: the procedural city
  int subdivide = 0;
  std::string json_path;
  int width = 1024;
  int height = 1024;
  std::size_t diffuse_rays = std::size_t{1} << 20;
  double seconds = 0.5;
  int threads = 0;  // 0: all TBB threads
  std::uint32_t seed = 1;
  bool fast_build = false;
  bool robust = true;
};

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr,
               "ray_bench: %s\n"
               "usage: ray_bench [--scene file.gltf|.glb] [--subdivide N] [--json out.json]\n"
               "                 [--width W] [--height H] [--rays N] [--seconds S] [--threads N]\n"
               "                 [--seed N] [--quality high|fast] [--no-robust]\n",
               why);
  std::exit(2);
}

Args parseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usage(("missing value after " + arg).c_str());
      return argv[++i];
    };
    try {
      if (arg == "--scene")
        a.scene_path = value();
      else if (arg == "--subdivide")
        a.subdivide = std::stoi(value());
      else if (arg == "--json")
        a.json_path = value();
      else if (arg == "--width")
        a.width = std::stoi(value());
      else if (arg == "--height")
        a.height = std::stoi(value());
      else if (arg == "--rays")
        a.diffuse_rays = std::stoull(value());
      else if (arg == "--seconds")
        a.seconds = std::stod(value());
      else if (arg == "--threads")
        a.threads = std::stoi(value());
      else if (arg == "--seed")
        a.seed = static_cast<std::uint32_t>(std::stoul(value()));
      else if (arg == "--quality") {
        const std::string q = value();
        if (q != "high" && q != "fast") usage("--quality is high or fast");
        a.fast_build = q == "fast";
      } else if (arg == "--no-robust")
        a.robust = false;
      else if (arg == "--help" || arg == "-h")
        usage("help");
      else
        usage(("unknown argument " + arg).c_str());
    } catch (const std::logic_error&) {  // std::stoi and friends on a non-number
      usage(("bad number after " + arg).c_str());
    }
  }
  if (a.width <= 0 || a.height <= 0 || a.width % 4 || a.height % 4)
    usage("--width/--height: positive multiples of 4");
  if (a.subdivide < 0 || a.subdivide > 6) usage("--subdivide: 0..6");
  if (a.threads < 0) usage("--threads: 0 (all) or more");
  return a;
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parseArgs(argc, argv);

  // ---- scene ----
  scene::Scene scene;
  if (args.scene_path.empty()) {
    scene = bench::makeCity(args.seed);
  } else {
    scene::LoadOptions load_options;
    load_options.load_textures = false;
    Expected<scene::Scene> loaded = scene::loadScene(args.scene_path, load_options);
    if (!loaded) {
      std::fprintf(stderr, "ray_bench: %s\n", loaded.status().toString().c_str());
      return 1;
    }
    scene = std::move(loaded).value();
  }
  bench::subdivide(scene, args.subdivide);

  rt::AccelOptions accel_options;
  accel_options.quality =
      args.fast_build ? rt::AccelOptions::Quality::kFast : rt::AccelOptions::Quality::kHigh;
  accel_options.robust = args.robust;
  const auto build_start = std::chrono::steady_clock::now();
  Expected<rt::Accel> built = rt::Accel::build(scene, accel_options);
  const double build_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - build_start).count();
  if (!built) {
    std::fprintf(stderr, "ray_bench: %s\n", built.status().toString().c_str());
    return 1;
  }
  const rt::Accel& accel = *built;

  // ---- rays (untimed) ----
  // Camera inside the bounds, above the middle of one quarter, looking towards the centre
  // and pitched 30 degrees down so the top of the 60-degree frame is level: in an open
  // scene (the city) it sees streets and facades rather than sky (cheap misses would
  // flatter the figures), in a closed level its interior.
  const Aabb& b = accel.bounds();
  const glm::vec3 ext = b.extent(), mid = b.center();
  const glm::vec3 eye = mid + glm::vec3(-0.35f, 0.3f, -0.35f) * ext;
  glm::vec3 ahead = glm::vec3(mid.x - eye.x, 0.0f, mid.z - eye.z);
  ahead = glm::dot(ahead, ahead) > 0.0f ? glm::normalize(ahead) : glm::vec3(1.0f, 0.0f, 0.0f);
  const float pitch = 30.0f * 3.14159265f / 180.0f;
  const glm::vec3 target = eye + std::cos(pitch) * ahead - glm::vec3(0.0f, std::sin(pitch), 0.0f);
  const std::vector<rt::Ray> camera = bench::cameraRays(eye, target, 60.0f, args.width, args.height);
  const std::vector<rt::Ray> diffuse = bench::diffuseRays(scene, accel, args.diffuse_rays, args.seed);

  const int all_threads = args.threads == 0 ? tbb::info::default_concurrency() : args.threads;
  const std::string cpu = bench::cpuModel();
  fmt::print("ray_bench  cpu: {}  hardware threads: {}  TBB threads used: {}\n", cpu,
             std::thread::hardware_concurrency(), all_threads);
  fmt::print("scene: {}{}  triangles: {}  scale: {:.4g} m  build: {:.3f} s ({} quality, robust {})\n",
             args.scene_path.empty() ? "procedural city" : args.scene_path,
             args.subdivide ? fmt::format(" (subdivided x4^{})", args.subdivide) : "",
             accel.triangleCount(), accel.sceneScale(), build_seconds, args.fast_build ? "fast" : "high",
             args.robust ? "on" : "off");
  fmt::print("rays: camera {} ({}x{}), diffuse {}; at least {} s per row after one warm-up pass\n\n",
             camera.size(), args.width, args.height, diffuse.size(), args.seconds);
  fmt::print("{:<8} {:<9} {:<9} {:>7} {:>12} {:>9} {:>9} {:>7}\n", "rays", "query", "api", "threads",
             "rays traced", "seconds", "Mrays/s", "hit %");

  nlohmann::json rows = nlohmann::json::array();
  struct RaySet {
    const char* name;
    const std::vector<rt::Ray>* rays;
  };
  for (const RaySet& set : {RaySet{"camera", &camera}, RaySet{"diffuse", &diffuse}}) {
    for (bench::Query query : {bench::Query::kClosestHit, bench::Query::kOcclusion}) {
      for (bench::RayApi api :
           {bench::RayApi::kSingle, bench::RayApi::kPacket16, bench::RayApi::kStream}) {
        std::vector<int> thread_counts{1};
        if (all_threads != 1) thread_counts.push_back(all_threads);
        for (int threads : thread_counts) {
          bench::ThroughputOptions options;
          options.query = query;
          options.api = api;
          options.threads = threads;
          options.min_seconds = args.seconds;
          const bench::ThroughputResult r = bench::measureThroughput(accel, *set.rays, options);
          const double mrays = r.raysPerSecond() * 1e-6;
          const double hit_pct = 100.0 * static_cast<double>(r.hits) / static_cast<double>(r.rays);
          fmt::print("{:<8} {:<9} {:<9} {:>7} {:>12} {:>9.3f} {:>9.2f} {:>7.1f}\n", set.name,
                     bench::queryName(query), bench::rayApiName(api), r.threads, r.rays * r.passes,
                     r.seconds, mrays, hit_pct);
          std::fflush(stdout);
          rows.push_back({{"rays", set.name},
                          {"query", bench::queryName(query)},
                          {"api", bench::rayApiName(api)},
                          {"threads", r.threads},
                          {"rays_per_pass", r.rays},
                          {"passes", r.passes},
                          {"seconds", r.seconds},
                          {"mrays_per_s", mrays},
                          {"hit_fraction", static_cast<double>(r.hits) / static_cast<double>(r.rays)}});
        }
      }
    }
  }

  if (!accel.deviceStatus().isOk()) {
    std::fprintf(stderr, "ray_bench: %s\n", accel.deviceStatus().toString().c_str());
    return 1;
  }
  if (!args.json_path.empty()) {
    nlohmann::json doc = {
        {"benchmark", "ray_bench"},
        {"machine",
         {{"cpu", cpu},
          {"hardware_threads", std::thread::hardware_concurrency()},
          {"tbb_threads", all_threads}}},
        {"scene",
         {{"source", args.scene_path.empty() ? "procedural:city" : args.scene_path},
          {"subdivide", args.subdivide},
          {"triangles", accel.triangleCount()},
          {"scale_m", accel.sceneScale()},
          {"build_seconds", build_seconds},
          {"build_quality", args.fast_build ? "fast" : "high"},
          {"robust", args.robust}}},
        {"camera", {{"width", args.width}, {"height", args.height}, {"vfov_deg", 60.0}}},
        {"diffuse_rays", diffuse.size()},
        {"seed", args.seed},
        {"min_seconds_per_row", args.seconds},
        {"results", rows}};
    std::ofstream out(args.json_path);
    out << doc.dump(2) << "\n";
    if (!out) {
      std::fprintf(stderr, "ray_bench: cannot write %s\n", args.json_path.c_str());
      return 1;
    }
    fmt::print("\nwrote {}\n", args.json_path);
  }
  return 0;
}
