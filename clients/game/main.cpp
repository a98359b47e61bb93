// lightlink_game_client: what a game does with a lightlink daemon (docs/clients.md).
//
// Once: load the level (the same glTF the daemon opened), give it the lightmap UVs the daemon
// baked on (the unwrap is deterministic: same scene and preset, same atlas), build the ray
// tracer the viewer uses. Then every frame: poll GetTextures with the last version seen. A
// "not modified" answer is one small message and costs next to nothing. With --wait-ms the
// poll is a long poll: the daemon holds it until a new version exists (or wait_ms passed),
// so a new version reaches the client one round trip after the relight, with no poll
// interval, and an idle scene costs one call per wait_ms (a game would keep such a poll on
// a thread of its own; this example renders between polls). A new version is
// decoded into the viewer's BakedLighting and a frame is rendered with `lightlink render`'s
// code and written as PNG. Each rendered frame prints its poll cost, and once a second a line
// summarises the not-modified polls.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <thread>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "clients/client/client.h"
#include "clients/client/core_bridge.h"
#include "clients/client/session.h"
#include "clients/viewer/render.h"
#include "core/common/png.h"
#include "core/precompute/precompute.h"
#include "core/scene/load.h"

namespace {

using namespace lightlink;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Args {
  std::string session, target, token, token_file, scene_id, scene_token;
  std::string scene_path;   // default: the source path the daemon reports (ListScenes)
  std::string preset = "medium";
  std::string lights_path;
  std::string output_dir = "frames";
  double fps = 30.0;
  int frames = 0;           // stop after this many rendered frames (0 = no limit)
  double duration_s = 0.0;  // stop after this long (0 = no limit)
  int width = 384, height = 384;
  int first_frame = 0;      // number of the first frame file (scripts call it repeatedly)
  std::uint32_t wait_ms = 0;  // > 0: long poll (GetTextures wait_ms)
  bool shared_memory = false; // results through shared memory when the daemon is on this machine
};

double ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

int fail(const Status& s) {
  std::fprintf(stderr, "lightlink_game_client: %s\n", s.toString().c_str());
  return s.code() == Code::kIoError ? 3 : s.code() == Code::kInternal ? 4 : 2;
}

int run(const Args& a) {
  if (a.fps <= 0.0 || a.fps > 1000.0) return fail(invalidInput("--fps {} is out of range (0, 1000]", a.fps));
  if (a.frames < 0 || a.duration_s < 0.0 || a.first_frame < 0)
    return fail(invalidInput("--frames, --duration and --first-frame must not be negative"));
  if (a.frames == 0 && a.duration_s == 0.0) return fail(invalidInput("give --frames N or --duration S"));
  if (a.wait_ms > 60000) return fail(invalidInput("--wait-ms {} is out of range (0..60000)", a.wait_ms));

  client::Session session;
  if (!a.session.empty()) {
    auto s = client::loadSession(a.session);
    if (!s) return fail(s.status());
    session = std::move(s).value();
  }
  if (!a.target.empty()) session.target = a.target;
  if (!a.scene_id.empty()) session.scene = client::SceneHandle::fromIdToken(a.scene_id, a.scene_token);
  if (session.target.empty() || session.scene.id.empty())
    return fail(invalidInput("give --session FILE, or --target with --scene and --scene-token"));
  client::ConnectOptions co;
  co.target = session.target;
  if (!a.token.empty()) return fail(invalidInput("{}", client::tokenInArgvMessage("--token")));
  auto bearer = client::bearerTokenFrom(a.token_file);
  if (!bearer) return fail(bearer.status());
  co.bearer_token = *bearer;
  co.shared_memory = a.shared_memory;
  auto c = client::Client::connect(co);
  if (!c) return fail(c.status());

  // The level on the client's side: the same file, unwrapped as the daemon did.
  std::string scene_path = a.scene_path;
  if (scene_path.empty()) {
    auto scenes = c->listScenes();
    if (!scenes) return fail(scenes.status());
    for (const auto& s : *scenes)
      if (s.scene_id() == session.scene.id) scene_path = s.source();
    if (scene_path.empty() || scene_path.starts_with("<inline"))
      return fail(invalidInput("--scene-file: required (the daemon has no path for scene '{}')", session.scene.id));
  }
  auto scene = scene::loadScene(scene_path);
  if (!scene) return fail(scene.status());
  auto options = precompute::preset(a.preset);
  if (!options) return fail(options.status());
  auto unwrapped = precompute::unwrapFor(*scene, *options);
  if (!unwrapped) return fail(unwrapped.status());
  rt::AccelOptions accel_options;
  accel_options.static_only = false;
  auto accel = rt::Accel::build(*scene, accel_options);
  if (!accel) return fail(accel.status());
  auto lights = relight::LightSet::fromSceneLights(scene->lights);
  if (!a.lights_path.empty())
    if (Status s = lights.applyFile(a.lights_path); !s) return fail(s);
  const viewer::Camera camera = viewer::defaultCamera(*scene);
  std::error_code ec;
  fs::create_directories(a.output_dir, ec);
  if (ec) return fail(ioError("cannot create {}: {}", a.output_dir, ec.message()));

  const auto frame_period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / a.fps));
  const auto start = Clock::now();
  auto next_frame = start;
  auto next_summary = start + std::chrono::seconds(1);
  std::uint64_t last_seen = 0;
  int rendered = 0;
  std::size_t idle_polls = 0;
  double idle_sum_ms = 0.0, idle_max_ms = 0.0;
  std::vector<std::uint8_t> rgb;
  for (;;) {
    const auto t0 = Clock::now();
    auto polled = c->getTextures(session.scene, last_seen, {}, a.wait_ms);
    const double poll_ms = ms(Clock::now() - t0);
    if (!polled) return fail(polled.status());
    if (polled->has_value() && (*polled)->info.kind == client::ResultKind::kInstantPreview) {
      // The scene's links are still being computed: the preview has a grid and no lightmap,
      // which this client renders with. Wait for the linked result.
      std::printf("version %6llu  instant preview (no lightmap yet): waiting for the linked result\n",
                  static_cast<unsigned long long>((*polled)->info.version));
      last_seen = (*polled)->info.version;
    } else if (polled->has_value()) {
      const client::Textures& t = **polled;
      if (t.info.width != unwrapped->atlas.resolution || t.info.height != unwrapped->atlas.resolution)
        return fail(invalidInput("the daemon's lightmap is {}x{}, this client's unwrap with preset '{}' is {}x{}: "
                                 "give the preset the scene was opened with (--preset)",
                                 t.info.width, t.info.height, a.preset, unwrapped->atlas.resolution,
                                 unwrapped->atlas.resolution));
      const auto t1 = Clock::now();
      auto baked = client::toBakedLighting(t);
      if (!baked) return fail(baked.status());
      auto stats = viewer::render(*scene, *accel, *baked, lights, camera, {a.width, a.height, 0.0f}, rgb);
      if (!stats) return fail(stats.status());
      const std::string png = (fs::path(a.output_dir) / fmt::format("frame_{:04d}.png", a.first_frame + rendered)).string();
      if (Status s = writePngRgb8(png, a.width, a.height, rgb, "frame"); !s) return fail(s);
      std::printf("frame %4d  version %6llu  poll %7.2f ms (%zu KiB%s)  decode+render %7.1f ms  -> %s\n",
                  a.first_frame + rendered, static_cast<unsigned long long>(t.info.version), poll_ms,
                  t.totalBytes() / 1024, t.info.shared ? " through shared memory" : "", ms(Clock::now() - t1),
                  png.c_str());
      std::fflush(stdout);
      last_seen = t.info.version;
      ++rendered;
    } else {
      ++idle_polls;
      idle_sum_ms += poll_ms;
      idle_max_ms = std::max(idle_max_ms, poll_ms);
    }
    const auto now = Clock::now();
    if (now >= next_summary) {
      if (idle_polls > 0)
        std::printf("polls       %zu not modified in the last second: mean %.3f ms, max %.3f ms\n", idle_polls,
                    idle_sum_ms / double(idle_polls), idle_max_ms);
      std::fflush(stdout);
      idle_polls = 0;
      idle_sum_ms = idle_max_ms = 0.0;
      next_summary = now + std::chrono::seconds(1);
    }
    if (a.frames > 0 && rendered >= a.frames) break;
    if (a.duration_s > 0.0 && ms(now - start) >= a.duration_s * 1e3) break;
    next_frame += frame_period;
    if (next_frame > now) std::this_thread::sleep_until(next_frame);
    else next_frame = now;  // rendering took longer than a frame: do not try to catch up
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  CLI::App app{"lightlink_game_client: polls a lightlink daemon and renders frames with its textures"};
  app.add_option("--session", a.session, "Session file written by `lightlink open --session`");
  app.add_option("--target", a.target, "Daemon address host:port");
  app.add_option("--token-file", a.token_file, "File holding the daemon bearer token (default: $LIGHTLINK_TOKEN)");
  app.add_option("--token", a.token,
                 "Refused: a token in argv is visible in ps; use --token-file or $LIGHTLINK_TOKEN");
  app.add_option("--scene", a.scene_id, "Scene id (instead of --session)");
  app.add_option("--scene-token", a.scene_token, "Scene token (with --scene)");
  app.add_option("--scene-file", a.scene_path, "The glTF the daemon opened (default: the path the daemon reports)");
  app.add_option("--preset", a.preset, "Preset the scene was opened with (same lightmap UVs)")->capture_default_str();
  app.add_option("--lights", a.lights_path, "Light-set JSON for realtime lights and dynamic objects");
  app.add_option("-o,--output", a.output_dir, "Directory for frame_NNNN.png")->capture_default_str();
  app.add_option("--fps", a.fps, "Polls per second (at most, with --wait-ms)")->capture_default_str();
  app.add_option("--wait-ms", a.wait_ms, "Long poll: the daemon answers when a new version exists or after this long")
      ->capture_default_str();
  app.add_flag("--shared-memory", a.shared_memory,
               "Ask for results through shared memory (the daemon on this machine writes each result once for all "
               "its clients; falls back to the stream)");
  app.add_option("--frames", a.frames, "Stop after N rendered frames");
  app.add_option("--duration", a.duration_s, "Stop after S seconds");
  app.add_option("--width", a.width, "Frame width")->capture_default_str();
  app.add_option("--height", a.height, "Frame height")->capture_default_str();
  app.add_option("--first-frame", a.first_frame, "Number of the first frame_NNNN.png")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  return run(a);
}
