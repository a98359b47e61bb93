// preview_bench: time from OpenScene to the instant preview (docs/service.md "Preview while the
// precompute runs"; DESIGN.md sec 11: first preview <= 1 s after OpenScene on a 60k-triangle
// level). Starts a lightlinkd (cache in a fresh temporary directory, so the precompute runs
// and is not reused), then per scene and run opens the scene through the client library with
// the preview on and measures, at the client:
//   preview_s   OpenScene sent -> the preview announced (OpenSceneProgress.preview)
//   texture_s   OpenScene sent -> the preview grid held by the client (GetTextures, float),
//               ResultKind checked to be RESULT_KIND_INSTANT_PREVIEW
//   update_s    a sky change sent right after the preview (UpdateLights, wait_ms) -> relit,
//               counted when the relit version was still a preview (the precompute runs meanwhile)
//   linked_s    OpenScene sent -> OpenScene done (the linked result published); only with
//               --wait-linked (else the open is abandoned after the preview by a deadline of
//               --timeout-s (default 5) and the daemon cancels its precompute and drops the scene)
// plus the preview's probes and rays from the daemon's log. Triangles are counted by loading
// the scene here. JSON to --json, a summary to stdout.
//
//   preview_bench --scene PATH [--lights JSON] [--scene PATH [--lights JSON]] ... [--runs 3]
//                 [--preset medium] [--wait-linked] [--timeout-s 5] [--json FILE]
// --lights applies to the --scene before it (a light-set JSON file, docs/lightset.md).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "clients/client/client.h"
#include "clients/client/local_daemon.h"
#include "core/scene/load.h"

namespace {

using namespace lightlink;
using namespace lightlink::client;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

struct SceneArg {
  std::string path, lights;
};

struct Args {
  std::vector<SceneArg> scenes;
  int runs = 3;
  std::string preset = "medium";
  bool wait_linked = false;
  double timeout_s = 5.0;
  std::string json;
};

int usage(const std::string& why) {
  std::fprintf(stderr, "preview_bench: %s\nusage: preview_bench --scene PATH [--lights JSON] ... [--runs N] "
               "[--preset NAME] [--wait-linked] [--timeout-s S] [--json FILE]\n", why.c_str());
  return 2;
}

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string f = argv[i];
    auto value = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (f == "--scene") a.scenes.push_back({fs::absolute(value()).string(), ""});
    else if (f == "--lights") {
      if (a.scenes.empty()) return usage("--lights before any --scene");
      a.scenes.back().lights = value();
    } else if (f == "--runs") a.runs = std::max(1, std::atoi(value().c_str()));
    else if (f == "--preset") a.preset = value();
    else if (f == "--wait-linked") a.wait_linked = true;
    else if (f == "--timeout-s") a.timeout_s = std::atof(value().c_str());
    else if (f == "--json") a.json = value();
    else return usage("unknown flag " + f);
  }
  if (a.scenes.empty()) return usage("give at least one --scene");

  const fs::path tmp = fs::temp_directory_path() / fmt::format("preview_bench.{}", ::getpid());
  fs::create_directories(tmp);
  LocalDaemon::Options d;
  d.binary = LIGHTLINK_DAEMON_PATH;
  d.cache_dir = tmp / "cache";
  d.extra = {"--no-restore", "--backend", "cpu", "--preview", "on", "--log-level", "info"};
  for (const auto& s : a.scenes) d.extra.insert(d.extra.end(), {"--scene-root", fs::path(s.path).parent_path().string()});
  auto daemon = LocalDaemon::start(d);
  if (!daemon) {
    std::fprintf(stderr, "preview_bench: %s\n", daemon.status().toString().c_str());
    return 1;
  }
  ConnectOptions co;
  co.target = (*daemon)->target();
  co.call_timeout = std::chrono::milliseconds(60000);
  auto client = Client::connect(co);
  if (!client) {
    std::fprintf(stderr, "preview_bench: %s\n", client.status().toString().c_str());
    return 1;
  }

  nlohmann::ordered_json out;
  out["machine_cpus"] = std::thread::hardware_concurrency();
  out["preset"] = a.preset;
  out["scenes"] = nlohmann::json::array();
  int failures = 0;
  for (const auto& s : a.scenes) {
    std::size_t triangles = 0;
    if (auto sc = scene::loadScene(s.path)) triangles = sc->stats.triangles_in;
    std::vector<double> preview_s, texture_s, linked_s, update_s;
    int probes = 0;
    for (int run = 0; run < a.runs; ++run) {
      OpenOptions o;
      o.path = s.path;
      o.options["preset"] = a.preset;
      o.backend = v1::BACKEND_CPU;
      if (!s.lights.empty()) o.lightset_json = readText(s.lights);
      o.preview = true;
      if (!a.wait_linked) o.timeout = std::chrono::milliseconds(static_cast<long long>(a.timeout_s * 1000));
      const auto t0 = Clock::now();
      double p = -1.0, t = -1.0, update = -1.0;
      bool kind_ok = false, update_was_preview = false;
      auto opened = client->openScene(o, {}, [&](const SceneHandle& h) {
        p = std::chrono::duration<double>(Clock::now() - t0).count();
        ResultSpec spec;
        spec.precision = Precision::kFloat;
        auto tex = client->relight(h, h.info.version(), spec);
        t = std::chrono::duration<double>(Clock::now() - t0).count();
        kind_ok = tex && tex->info.kind == ResultKind::kInstantPreview;
        if (tex) probes = int(tex->info.gridPoints());
        // A light change while the links are computed (the precompute shares the cores): the
        // UpdateLights round trip until its version is relit, and whether that was a preview.
        SceneHandle scene = h;
        LightUpdate sky;
        (void)sky.sky({0.2f, 0.3f, 0.5f});
        const auto t1 = Clock::now();
        auto up = client->updateLights(scene, sky, 10000);
        if (up && up->relit) {
          update = std::chrono::duration<double>(Clock::now() - t1).count();
          auto now = client->relight(scene, up->version, spec);
          update_was_preview = now && now->info.kind == ResultKind::kInstantPreview;
        }
      });
      const double total = std::chrono::duration<double>(Clock::now() - t0).count();
      if (p < 0.0 || !kind_ok) {
        std::fprintf(stderr, "preview_bench: %s run %d: no preview%s (%s)\n", s.path.c_str(), run,
                     kind_ok ? "" : " of kind INSTANT_PREVIEW", opened ? "opened" : opened.status().toString().c_str());
        ++failures;
        continue;
      }
      preview_s.push_back(p);
      texture_s.push_back(t);
      if (update >= 0.0 && update_was_preview) update_s.push_back(update);
      if (a.wait_linked) {
        if (opened) linked_s.push_back(total), (void)client->closeScene(*opened);
        else std::fprintf(stderr, "preview_bench: %s: %s\n", s.path.c_str(), opened.status().toString().c_str());
      }
      // The daemon forgets the scene (closed, or the open abandoned); the next run starts cold
      // once the cancelled precompute has stopped.
      std::this_thread::sleep_for(std::chrono::milliseconds(1000));
    }
    nlohmann::ordered_json j;
    j["scene"] = s.path;
    j["lights"] = s.lights;
    j["triangles"] = triangles;
    j["grid_points"] = probes;
    j["runs"] = preview_s.size();
    j["preview_s"] = preview_s;
    j["texture_s"] = texture_s;
    j["preview_s_median"] = median(preview_s);
    j["texture_s_median"] = median(texture_s);
    j["update_s"] = update_s;
    j["update_s_median"] = median(update_s);
    if (a.wait_linked) j["linked_s"] = linked_s, j["linked_s_median"] = median(linked_s);
    std::printf("%-24s %7zu tris %6d grid points: preview %.3f s, at the client %.3f s, a light change re-lit "
                "in %.3f s (%zu of the runs during the preview) (median of %zu)%s\n",
                fs::path(s.path).filename().string().c_str(), triangles, probes, median(preview_s),
                median(texture_s), median(update_s), update_s.size(), preview_s.size(),
                a.wait_linked ? fmt::format(", linked {:.2f} s", median(linked_s)).c_str() : "");
    out["scenes"].push_back(j);
  }
  // The daemon's own account of each preview (probes, rays per probe, its seconds).
  nlohmann::ordered_json logged = nlohmann::json::array();
  std::istringstream log((*daemon)->log());
  for (std::string line; std::getline(log, line);)
    if (line.find("preview_published") != std::string::npos) logged.push_back(line);
  out["daemon_preview_log"] = logged;
  if (!a.json.empty()) std::ofstream(a.json) << out.dump(2) << "\n";
  daemon->reset();
  std::error_code ec;
  fs::remove_all(tmp, ec);
  return failures == 0 ? 0 : 1;
}
