// The daemon's budgets (docs/service.md "Limits"): abandoned opens stop, SIGTERM does not
// wait for a precompute, and requests that claim far more work than they carry are refused
// with RESOURCE_EXHAUSTED naming the limit. Scenes are uploaded (gltf_bytes), so these tests
// need no scene root.
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <chrono>
#include <fstream>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "tests/common/hostile_scenes.h"
#include "tests/common/testing.h"
#include "tests/service/daemon_harness.h"

namespace lightlink::testing {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::vector<std::string> flags() { return {"--backend", "cpu", "--bounces", "2", "--log-level", "debug"}; }

std::string demoBytes() {
  std::ifstream in(sourceDir() / "clients/demo/cornell_box.gltf", std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The demo box at the largest surfel count, links and rays the daemon accepts: its precompute
// runs for minutes (surfel relaxation, then the tree, then links), its open starts in ms.
v1::OpenSceneRequest expensiveRequest() {
  v1::OpenSceneRequest r;
  r.set_gltf_bytes(demoBytes());
  r.set_preset("draft");
  r.set_surfels(4000000);
  r.set_links(4096);
  r.set_rays(65536);
  r.set_backend(v1::BACKEND_CPU);
  return r;
}

// CPU seconds (user + system) the process has used.
double cpuSeconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::istringstream fields(text.substr(text.rfind(')') + 2));
  std::string f;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && fields >> f; ++i) {
    if (i == 14) utime = std::stoull(f);
    if (i == 15) stime = std::stoull(f);
  }
  return double(utime + stime) / double(::sysconf(_SC_CLK_TCK));
}

// Peak resident memory of the process (VmHWM), bytes.
std::uint64_t peakRss(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  return 0;
}

// Runs OpenScene to its end; returns the status. `stage_seen` is set once `stage` streams.
grpc::Status runOpen(LightlinkRpc& rpc, const v1::OpenSceneRequest& request, int deadline_ms,
                     const std::string& stage = "", std::atomic<bool>* stage_seen = nullptr) {
  auto ctx = context(deadline_ms);
  auto reader = rpc.OpenScene(ctx.get(), request);
  v1::OpenSceneProgress p;
  while (reader->Read(&p))
    if (stage_seen && p.stage() == stage) *stage_seen = true;
  return reader->Finish();
}

TEST(DaemonBudgets, AbandonedOpenStopsWithinTwoSeconds) {
  TempDir dir;
  DaemonProcess d(dir / "cache", flags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  const auto start = Clock::now();
  const grpc::Status st = runOpen(*rpc, expensiveRequest(), 500);
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(st.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED) << st.error_message();
  // Two seconds after the deadline the daemon must be idle: it used (almost) no CPU in the
  // following second. Before every stage polled cancellation, the surfel stage went on with
  // both cores for minutes.
  std::this_thread::sleep_until(start + std::chrono::milliseconds(2500));
  const double before = cpuSeconds(d.pid());
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const double used = cpuSeconds(d.pid()) - before;
  EXPECT_LT(used, 0.25) << "the daemon still computes for an abandoned open\n" << d.log();
  const std::string log = d.log();
  const auto at = log.find("open_abandoned");
  ASSERT_NE(at, std::string::npos) << log;
  std::printf("daemon CPU in the second from 2 s after the deadline: %.3f s\n%s\n", used,
              log.substr(log.rfind('\n', at) + 1, log.find('\n', at) - log.rfind('\n', at) - 1).c_str());
}

TEST(DaemonBudgets, SigtermDuringAnOpenExitsWithinTheDrainTime) {
  TempDir dir;
  DaemonProcess d(dir / "cache", [] {
    auto f = flags();
    f.insert(f.end(), {"--drain-seconds", "2"});
    return f;
  }());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  std::atomic<bool> computing{false};
  grpc::Status open_status;
  std::thread opener([&] { open_status = runOpen(*rpc, expensiveRequest(), 120000, "surfels", &computing); });
  const auto wait_until = Clock::now() + std::chrono::seconds(30);
  while (!computing && Clock::now() < wait_until) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_TRUE(computing) << "the open never reached the surfel stage\n" << d.log();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // well inside the stage

  const auto t0 = Clock::now();
  const int code = d.signalAndWait(SIGTERM, std::chrono::milliseconds(4000));  // drain 2 s + 2 s grace
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  if (code != 0) d.signalAndWait(SIGKILL, std::chrono::milliseconds(5000));  // do not wait out the open
  opener.join();
  EXPECT_EQ(code, 0) << "exit after SIGTERM took " << seconds << " s (or more than 4 s)\n" << d.log();
  EXPECT_LT(seconds, 4.0);
  std::printf("SIGTERM during the surfel stage: exit %d after %.3f s (drain 2 s)\n", code, seconds);
  EXPECT_FALSE(open_status.ok());
  EXPECT_NE(d.log().find("open_abandoned"), std::string::npos) << d.log();
}

TEST(DaemonBudgets, HostileOpensAreRefusedBeforeTheWork) {
  TempDir dir;
  DaemonProcess d(dir / "cache", flags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  const auto refused = [&](const v1::OpenSceneRequest& r, const std::string& limit) {
    const auto t0 = Clock::now();
    const grpc::Status st = runOpen(*rpc, r, 30000);
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << limit << ": " << st.error_message();
    EXPECT_NE(st.error_message().find(limit), std::string::npos) << st.error_message();
    EXPECT_LT(seconds, 10.0) << limit;
  };

  // 20,000 lights at open: the cap UpdateLights enforces (4,096) holds here too.
  v1::OpenSceneRequest lights;
  lights.set_gltf_bytes(demoBytes());
  lights.set_preset("draft");
  lights.set_lightset_json(manyLightsJson(20000));
  refused(lights, "limit of 4096 lights");

  // A ~150 KB PNG that claims 12000 x 12000 pixels.
  v1::OpenSceneRequest image;
  image.set_gltf_bytes(texturedQuadGltf(zeroPng(12000, 12000)));
  image.set_preset("draft");
  refused(image, "max_image_pixels");

  // One 2,000-triangle mesh placed by 10,001 nodes: 20 M triangles from ~500 KB.
  v1::OpenSceneRequest instances;
  instances.set_gltf_bytes(instancedGridGltf(2000, 10001));
  instances.set_preset("draft");
  refused(instances, "max_triangles");

  // None of them cost memory: the daemon's peak stays far below one decoded bomb (576 MB).
  EXPECT_LT(peakRss(d.pid()), std::uint64_t(400) << 20);
  const std::string log = d.log();
  EXPECT_NE(log.find("resource exhausted"), std::string::npos) << log;
}

}  // namespace
}  // namespace lightlink::testing
