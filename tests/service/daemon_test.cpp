// The daemon as clients see it: real lightlinkd processes on loopback, each test with its
// own cache directory, every call under a deadline. Scenes are the demo Cornell box at a
// tiny precompute (cornellRequest) so opening takes about a second.
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <set>
#include <sstream>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <grpcpp/generic/generic_stub.h>
#include <nlohmann/json.hpp>

#include "core/artifact/artifact.h"
#include "core/precompute/resident.h"
#include "core/relight/relight.h"
#include "core/scene/load.h"
#include "gpu/backend_factory.h"
#include "tests/common/testing.h"
#include "tests/service/daemon_harness.h"

namespace lightlink::testing {
namespace {

namespace fs = std::filesystem;
constexpr int kBounces = 2;  // every test daemon relights with this bounce cap

// CPU relights (deterministic, no GL context probed by Health), a small bounce cap, debug logs.
std::vector<std::string> quickFlags() {
  return {"--backend", "cpu", "--bounces", std::to_string(kBounces), "--log-level", "debug"};
}

v1::SceneRef refOf(const v1::SceneOpened& o) {
  v1::SceneRef r;
  r.set_scene_id(o.scene_id());
  r.set_token(o.scene_token());
  return r;
}

v1::Light pointLight(const std::string& id, float x, float y, float z, float intensity) {
  v1::Light l;
  l.set_id(id);
  l.set_type(v1::LIGHT_TYPE_POINT);
  l.mutable_position()->set_x(x);
  l.mutable_position()->set_y(y);
  l.mutable_position()->set_z(z);
  l.set_intensity(intensity);
  return l;
}

relight::LightEntry pointEntry(const std::string& id, float x, float y, float z, float intensity) {
  relight::LightEntry e;
  e.id = id;
  e.light.kind = scene::Light::Kind::kPoint;
  e.light.position = {x, y, z};
  e.light.intensity = intensity;
  return e;
}

// The same relight in this process: the artifact the daemon wrote, the same light set.
// One relight step of relightSequenceInProcess.
struct RelightStep {
  relight::LightSet lights;
  int bounces = kBounces;
  bool warm = false;  // RelightOptions::warm_start
};
enum class InProcessBackend { kCpu, kGpu };

// The daemon's relights done in process on the artifact it wrote, one relighter for the
// steps in order; the last step's result.
relight::RelightResult relightSequenceInProcess(const fs::path& cache, const std::vector<RelightStep>& steps,
                                                InProcessBackend backend = InProcessBackend::kCpu) {
  auto options = precompute::preset("draft");
  EXPECT_TRUE(options);
  options->surfels = 2048;
  options->links = 32;
  options->rays = 128;
  options->grid_spacing_m = 0.1f;
  options->grid = precompute::GridMode::kOn;
  precompute::ResidentRequest rr{(sourceDir() / "clients/demo/cornell_box.gltf").string(), *options, cache.string()};
  auto resident = precompute::ResidentScene::open(rr);
  EXPECT_TRUE(resident) << resident.status().message();
  EXPECT_TRUE(resident->reused()) << "the daemon's artifact should match this key: " << resident->note();
  auto r = gpu::makeBackend(backend == InProcessBackend::kGpu ? gpu::BackendChoice::kGpu : gpu::BackendChoice::kCpu,
                            resident->scene(), resident->accel(), resident->precomputation(), resident->lightmapLinks(),
                            resident->gridLinks());
  EXPECT_TRUE(r) << r.status().message();
  relight::RelightResult result;
  for (const RelightStep& step : steps) {
    relight::RelightOptions o;
    o.max_bounces = step.bounces;
    o.warm_start = step.warm;
    const Status s = (*r)->relightInto(step.lights, o, result);
    EXPECT_TRUE(s) << s.message();
  }
  return result;
}

relight::RelightResult relightInProcess(const fs::path& cache, const relight::LightSet& lights,
                                        int bounces = kBounces) {
  return relightSequenceInProcess(cache, {{lights, bounces, false}});
}

void expectClose(const std::vector<float>& got, const std::vector<float>& want, const char* what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  std::size_t bad = 0;
  for (std::size_t i = 0; i < got.size(); ++i)
    if (!(std::abs(got[i] - want[i]) <= 1e-5f * std::max(1.0f, std::abs(want[i])))) {
      if (bad++ < 5) ADD_FAILURE() << what << "[" << i << "]: daemon " << got[i] << ", in-process " << want[i];
    }
  EXPECT_EQ(bad, 0u) << what;
}

struct Fixture {
  TempDir tmp;
  fs::path cache = tmp / "cache";
};

// A daemon (quick flags) with the bundled Cornell box open: how most tests here begin.
// `auto& [f, d, rpc, opened] = cornell;` gives a test the usual names.
struct CornellDaemon {
  Fixture f;
  DaemonProcess d{f.cache, quickFlags()};
  std::unique_ptr<LightlinkRpc> rpc;
  v1::SceneOpened opened;

  // The failure message carries the daemon's log.
  ::testing::AssertionResult open() {
    if (!d.ok()) return ::testing::AssertionFailure() << d.error();
    rpc = d.rpc();
    const grpc::Status s = openScene(*rpc, cornellRequest(), &opened);
    if (!s.ok()) return ::testing::AssertionFailure() << s.error_message() << "\n" << d.log();
    return ::testing::AssertionSuccess();
  }
};

// The result of `version` through Relight, full precision.
void relightResult(LightlinkRpc& rpc, const v1::SceneOpened& opened, std::uint64_t version, Result& res) {
  v1::RelightRequest rq;
  *rq.mutable_scene() = refOf(opened);
  rq.set_version(version);
  rq.mutable_spec()->set_precision(v1::PRECISION_FLOAT);
  auto ctx = context();
  auto reader = rpc.Relight(ctx.get(), rq);
  std::string err;
  ASSERT_TRUE(readOne(reader.get(), res, &err).ok());
  ASSERT_TRUE(err.empty()) << err;
}

TEST(Daemon, RoundTripOpenUpdateRelightMatchesInProcess) {
  Fixture f;
  DaemonProcess d(f.cache, quickFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::SceneOpened opened;
  std::vector<std::string> stages;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened, &stages).ok()) << d.log();
  EXPECT_FALSE(opened.artifact_reused());
  EXPECT_EQ(opened.backend(), "cpu");
  EXPECT_EQ(opened.version(), 1u);
  EXPECT_EQ(opened.bands(), 3);
  EXPECT_EQ(opened.scene_token().size(), 32u);
  EXPECT_TRUE(opened.grid().present());
  EXPECT_GT(opened.lightmap().width(), 0);
  EXPECT_NE(std::find(stages.begin(), stages.end(), "surfels"), stages.end()) << "progress should show the precompute stages";

  v1::UpdateLightsRequest up;
  *up.mutable_scene() = refOf(opened);
  *up.add_add() = pointLight("key", 0.2f, 0.4f, 0.3f, 2.0f);
  up.set_wait_ms(15000);
  v1::UpdateLightsResponse ur;
  ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
  EXPECT_EQ(ur.version(), 2u);
  EXPECT_TRUE(ur.relit());

  v1::RelightRequest rq;
  *rq.mutable_scene() = refOf(opened);
  rq.set_version(2);
  rq.mutable_spec()->set_precision(v1::PRECISION_FLOAT);
  auto ctx = context();
  auto reader = rpc->Relight(ctx.get(), rq);
  Result res;
  std::string err;
  ASSERT_TRUE(readOne(reader.get(), res, &err).ok());
  ASSERT_TRUE(err.empty()) << err;
  const auto& h = res.header;
  EXPECT_EQ(h.version(), 2u);
  EXPECT_EQ(h.backend(), "cpu");
  const std::size_t texels = std::size_t(h.lightmap().width()) * h.lightmap().height();
  const std::size_t points = std::size_t(h.grid().nx()) * h.grid().ny() * h.grid().nz();
  EXPECT_EQ(h.lightmap().width(), opened.lightmap().width());
  EXPECT_EQ(res.payloads[v1::PAYLOAD_LIGHTMAP_SH].size(), texels * 3 * 9 * 4);
  EXPECT_EQ(res.payloads[v1::PAYLOAD_LIGHTMAP_DIRECT].size(), texels * 3 * 4);
  EXPECT_EQ(res.payloads[v1::PAYLOAD_LIGHTMAP_VALID].size(), texels);
  EXPECT_EQ(res.payloads[v1::PAYLOAD_GRID_SH].size(), points * 3 * 9 * 4);
  EXPECT_EQ(res.payloads[v1::PAYLOAD_GRID_VALID].size(), points);

  // The same light set relit here: the daemon's values, bit for bit up to float noise.
  auto scene = scene::loadGltf((sourceDir() / "clients/demo/cornell_box.gltf").string());
  ASSERT_TRUE(scene);
  auto lights = relight::LightSet::fromSceneLights(scene->lights);
  ASSERT_TRUE(lights.add(pointEntry("key", 0.2f, 0.4f, 0.3f, 2.0f)));
  const auto want = relightInProcess(f.cache, lights);
  expectClose(decodeValues(res.payloads[v1::PAYLOAD_LIGHTMAP_SH], v1::PRECISION_FLOAT), want.lightmap_sh, "lightmap_sh");
  std::vector<float> direct;
  for (const auto& v : want.direct) direct.insert(direct.end(), {v.x, v.y, v.z});
  expectClose(decodeValues(res.payloads[v1::PAYLOAD_LIGHTMAP_DIRECT], v1::PRECISION_FLOAT), direct, "direct");
  expectClose(decodeValues(res.payloads[v1::PAYLOAD_GRID_SH], v1::PRECISION_FLOAT), want.grid_sh, "grid_sh");
  EXPECT_EQ(res.payloads[v1::PAYLOAD_LIGHTMAP_VALID],
            std::string(want.texel_valid.begin(), want.texel_valid.end()));

  // Half precision, 2 bands, indirect only, no grid: the spec shapes the payloads.
  rq.mutable_spec()->set_precision(v1::PRECISION_HALF);
  rq.mutable_spec()->set_bands(2);
  rq.mutable_spec()->set_component(v1::COMPONENT_INDIRECT);
  rq.mutable_spec()->set_skip_grid(true);
  auto ctx2 = context();
  auto reader2 = rpc->Relight(ctx2.get(), rq);
  Result half;
  ASSERT_TRUE(readOne(reader2.get(), half, &err).ok());
  EXPECT_EQ(half.payloads.count(v1::PAYLOAD_LIGHTMAP_DIRECT), 0u);
  EXPECT_EQ(half.payloads.count(v1::PAYLOAD_GRID_SH), 0u);
  ASSERT_EQ(half.payloads[v1::PAYLOAD_LIGHTMAP_SH].size(), texels * 3 * 4 * 2);
  const auto hv = decodeValues(half.payloads[v1::PAYLOAD_LIGHTMAP_SH], v1::PRECISION_HALF);
  for (std::size_t t = 0; t < texels; t += 97)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 4; ++k) {
        const float w = want.lightmap_sh[(t * 3 + c) * 9 + k];
        EXPECT_NEAR(hv[(t * 3 + c) * 4 + k], w, 2e-3f * std::max(1.0f, std::abs(w))) << "texel " << t;
      }
}

TEST(Daemon, SubscribeDeliversEveryVersionInOrderAndDeltasReassemble) {
  CornellDaemon cornell;
  ASSERT_TRUE(cornell.open());
  auto& [f, d, rpc, opened] = cornell;

  v1::SubscribeRequest full_req, delta_req;
  *full_req.mutable_scene() = refOf(opened);
  *delta_req.mutable_scene() = refOf(opened);
  delta_req.set_deltas(true);
  auto full_ctx = context(30000), delta_ctx = context(30000);
  auto full_stream = rpc->Subscribe(full_ctx.get(), full_req);
  auto delta_stream = rpc->Subscribe(delta_ctx.get(), delta_req);
  ResultReader full_reader(full_stream.get()), delta_reader(delta_stream.get());
  Result a, b;
  ASSERT_TRUE(full_reader.next(a)) << full_reader.error();
  ASSERT_TRUE(delta_reader.next(b)) << delta_reader.error();
  EXPECT_EQ(a.header.version(), 1u);
  EXPECT_FALSE(b.header.delta()) << "the first message of a delta stream is a full result";

  // A client that keeps up (reads each result before the next update) sees every version.
  for (int i = 0; i < 5; ++i) {
    v1::UpdateLightsRequest up;
    *up.mutable_scene() = refOf(opened);
    // Only the light on one side moves: a delta carries a subset of the tiles.
    *(i == 0 ? up.add_add() : up.add_modify()) = pointLight("moving", 0.1f + 0.05f * i, 0.1f, 0.1f, 0.3f);
    up.set_wait_ms(15000);
    v1::UpdateLightsResponse ur;
    ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
    ASSERT_TRUE(ur.relit());
    ASSERT_TRUE(full_reader.next(a)) << full_reader.error();
    ASSERT_TRUE(delta_reader.next(b)) << delta_reader.error();
    EXPECT_EQ(a.header.version(), ur.version());
    EXPECT_EQ(b.header.version(), ur.version());
    EXPECT_EQ(a.header.skipped_versions(), 0u);
    EXPECT_TRUE(b.header.delta());
    // The reassembled delta stream equals the full stream, payload by payload.
    for (const auto& [kind, bytes] : a.payloads) EXPECT_EQ(b.payloads[kind], bytes) << "payload " << kind;
    EXPECT_LE(b.header.payload_bytes(), a.header.payload_bytes());
  }
  full_ctx->TryCancel();
  delta_ctx->TryCancel();
}

TEST(Daemon, BurstOfUpdatesIsCoalescedAndSubscribersEndAtTheNewest) {
  CornellDaemon cornell;
  ASSERT_TRUE(cornell.open());
  auto& [f, d, rpc, opened] = cornell;
  v1::SubscribeRequest sub;
  *sub.mutable_scene() = refOf(opened);
  sub.mutable_spec()->set_skip_grid(true);
  auto ctx = context(30000);
  auto stream = rpc->Subscribe(ctx.get(), sub);
  ResultReader reader(stream.get());
  Result r;
  ASSERT_TRUE(reader.next(r)) << reader.error();

  // 60 updates as fast as one client can send them: the worker folds those that arrive
  // during a relight into the next one.
  constexpr int kBurst = 60;
  std::uint64_t last = 0;
  for (int i = 0; i < kBurst; ++i) {
    v1::UpdateLightsRequest up;
    *up.mutable_scene() = refOf(opened);
    *(i == 0 ? up.add_add() : up.add_modify()) = pointLight("burst", 0.1f + 0.005f * i, 0.3f, 0.3f, 0.5f);
    v1::UpdateLightsResponse ur;
    ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
    EXPECT_EQ(ur.version(), last == 0 ? 2u : last + 1) << "versions are consecutive";
    last = ur.version();
  }
  // The subscriber sees increasing versions and ends at the newest one.
  std::uint64_t seen = r.header.version(), results = 1, skipped = 0;
  while (seen < last) {
    ASSERT_TRUE(reader.next(r)) << reader.error();
    ASSERT_GT(r.header.version(), seen) << "versions must increase on a stream";
    seen = r.header.version();
    skipped += r.header.skipped_versions();
    ++results;
  }
  EXPECT_EQ(seen, last);
  ctx->TryCancel();

  v1::StatsRequest sr;
  *sr.mutable_scene() = refOf(opened);
  v1::StatsResponse stats;
  ASSERT_TRUE(rpc->Stats(context().get(), sr, &stats).ok());
  const auto& st = stats.scene(0);
  EXPECT_EQ(st.relights() + st.coalesced(), last) << "every version is either relit or folded into a later relight";
  EXPECT_GT(st.coalesced(), 0u) << "a burst of " << kBurst << " updates should coalesce";
  EXPECT_EQ(results + skipped, st.relights()) << "each result was either sent or counted as skipped";
}

TEST(Daemon, GetTexturesAnswersNotModifiedCheaply) {
  CornellDaemon cornell;
  ASSERT_TRUE(cornell.open());
  auto& [f, d, rpc, opened] = cornell;
  v1::GetTexturesRequest g;
  *g.mutable_scene() = refOf(opened);
  Result first;
  std::string err;
  auto c1 = context();
  auto r1 = rpc->GetTextures(c1.get(), g);
  ASSERT_TRUE(readOne(r1.get(), first, &err).ok()) << err;
  EXPECT_FALSE(first.header.not_modified());
  EXPECT_GT(first.header.payload_bytes(), 0u);

  g.set_last_seen_version(first.header.version());
  Result again;
  auto c2 = context();
  auto r2 = rpc->GetTextures(c2.get(), g);
  ASSERT_TRUE(readOne(r2.get(), again, &err).ok()) << err;
  EXPECT_TRUE(again.header.not_modified());
  EXPECT_EQ(again.header.payload_bytes(), 0u);
  EXPECT_EQ(again.chunks, 0u);
  EXPECT_EQ(again.header.version(), first.header.version());

  v1::UpdateLightsRequest up;
  *up.mutable_scene() = refOf(opened);
  *up.add_add() = pointLight("extra", 0.3f, 0.3f, 0.3f, 1.0f);
  up.set_wait_ms(15000);
  v1::UpdateLightsResponse ur;
  ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
  Result changed;
  auto c3 = context();
  auto r3 = rpc->GetTextures(c3.get(), g);
  ASSERT_TRUE(readOne(r3.get(), changed, &err).ok()) << err;
  EXPECT_FALSE(changed.header.not_modified());
  EXPECT_EQ(changed.header.version(), ur.version());
}

// One GetTextures call read to its end: the result, its status and how long it took.
struct Polled {
  grpc::Status status;
  Result result;
  std::string error;
  double ms = 0.0;
};

Polled getTextures(LightlinkRpc& rpc, const v1::GetTexturesRequest& g, int deadline_ms = 30000) {
  Polled p;
  const auto t0 = std::chrono::steady_clock::now();
  auto ctx = context(deadline_ms);
  auto reader = rpc.GetTextures(ctx.get(), g);
  p.status = readOne(reader.get(), p.result, &p.error);
  p.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return p;
}

TEST(Daemon, LongPollAnswersTheMomentANewVersionExists) {
  CornellDaemon cornell;
  ASSERT_TRUE(cornell.open());
  auto& [f, d, rpc, opened] = cornell;
  v1::GetTexturesRequest g;
  *g.mutable_scene() = refOf(opened);
  const Polled first = getTextures(*rpc, g);
  ASSERT_TRUE(first.status.ok()) << first.status.error_message() << first.error;
  const std::uint64_t seen = first.result.header.version();

  // An old client's request (no wait_ms on the wire) is the plain poll: not modified at once.
  g.set_last_seen_version(seen);
  const Polled plain = getTextures(*rpc, g);
  ASSERT_TRUE(plain.status.ok());
  EXPECT_TRUE(plain.result.header.not_modified());
  EXPECT_LT(plain.ms, 2000.0) << "a poll without wait_ms must not wait";

  // A long poll is held while nothing changes, then answered with the new version.
  g.set_wait_ms(20000);
  std::atomic<bool> answered{false};
  Polled held;
  std::thread poller([&] {
    held = getTextures(*rpc, g);
    answered = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  EXPECT_FALSE(answered.load()) << "the long poll returned before anything changed";
  v1::UpdateLightsRequest up;
  *up.mutable_scene() = refOf(opened);
  *up.add_add() = pointLight("late", 0.3f, 0.3f, 0.3f, 1.0f);
  v1::UpdateLightsResponse ur;
  const auto t_update = std::chrono::steady_clock::now();
  ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
  poller.join();
  const double after_update_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_update).count();
  ASSERT_TRUE(held.status.ok()) << held.status.error_message() << held.error;
  EXPECT_FALSE(held.result.header.not_modified());
  EXPECT_EQ(held.result.header.version(), ur.version());
  EXPECT_GT(held.result.payloads[v1::PAYLOAD_LIGHTMAP_SH].size(), 0u);
  // Answered with the relight (milliseconds at this size), far from the 20 s wait.
  EXPECT_LT(after_update_ms, 5000.0) << d.log();

  // Something newer than last_seen already exists: answered at once, wait or not.
  g.set_last_seen_version(seen);
  const Polled behind = getTextures(*rpc, g);
  ASSERT_TRUE(behind.status.ok());
  EXPECT_EQ(behind.result.header.version(), ur.version());
  EXPECT_LT(behind.ms, 5000.0);
}

TEST(Daemon, LongPollEndsNotModifiedAtItsWaitAndBeforeTheCallDeadline) {
  CornellDaemon cornell;
  ASSERT_TRUE(cornell.open());
  auto& [f, d, rpc, opened] = cornell;
  v1::RelightRequest rq;
  *rq.mutable_scene() = refOf(opened);
  rq.set_version(opened.version());
  rq.mutable_spec()->set_skip_lightmap(true);
  rq.mutable_spec()->set_skip_grid(true);
  Result initial;
  std::string err;
  auto rctx = context();
  auto rr = rpc->Relight(rctx.get(), rq);
  ASSERT_TRUE(readOne(rr.get(), initial, &err).ok()) << err;

  v1::GetTexturesRequest g;
  *g.mutable_scene() = refOf(opened);
  g.set_last_seen_version(initial.header.version());
  g.set_wait_ms(600);
  const Polled waited = getTextures(*rpc, g);
  ASSERT_TRUE(waited.status.ok()) << waited.status.error_message();
  EXPECT_TRUE(waited.result.header.not_modified());
  EXPECT_EQ(waited.result.chunks, 0u);
  EXPECT_GE(waited.ms, 550.0) << "answered before its wait";
  EXPECT_LT(waited.ms, 10000.0);

  // A call deadline shorter than wait_ms: not modified just before the deadline, not
  // DEADLINE_EXCEEDED.
  g.set_wait_ms(30000);
  const Polled cut = getTextures(*rpc, g, 1500);
  ASSERT_TRUE(cut.status.ok()) << cut.status.error_message();
  EXPECT_TRUE(cut.result.header.not_modified());
  EXPECT_GE(cut.ms, 1000.0);
}

TEST(Daemon, LongPollRejectsAbsurdWaits) {
  CornellDaemon cornell;
  ASSERT_TRUE(cornell.open());
  auto& [f, d, rpc, opened] = cornell;
  v1::GetTexturesRequest g;
  *g.mutable_scene() = refOf(opened);
  for (std::uint32_t wait : {60001u, 4000000000u}) {
    g.set_wait_ms(wait);
    const Polled p = getTextures(*rpc, g);
    EXPECT_EQ(p.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << wait;
    EXPECT_NE(p.status.error_message().find("wait_ms"), std::string::npos) << p.status.error_message();
  }
  // The limit itself is accepted, and the daemon keeps serving.
  g.set_wait_ms(60000);
  const Polled ok = getTextures(*rpc, g);
  ASSERT_TRUE(ok.status.ok()) << ok.status.error_message();
  EXPECT_FALSE(ok.result.header.not_modified()) << "last_seen 0: the newest result at once";
}

// The daemon on the GPU backend (llvmpipe in CI): Health and the scene say so, and its
// results are the GPU backend's own, relit in process from the same artifact.
TEST(Daemon, GpuBackendServesTheGpuRelight) {
  const gpu::GpuProbe& probe = gpu::probeGpu();
  if (!probe.available) GTEST_SKIP() << "no usable EGL display / GL 4.5: " << probe.error;
  Fixture f;
  auto flags = quickFlags();
  flags[1] = "gpu";  // --backend gpu
  DaemonProcess d(f.cache, flags);
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::HealthResponse health;
  ASSERT_TRUE(rpc->Health(context().get(), v1::HealthRequest{}, &health).ok());
  EXPECT_TRUE(health.gpu_available());
  EXPECT_EQ(health.gpu_renderer(), probe.renderer);
  auto open = cornellRequest();
  open.set_backend(v1::BACKEND_AUTO);  // the daemon's default, --backend gpu
  v1::SceneOpened opened;
  ASSERT_TRUE(openScene(*rpc, open, &opened).ok()) << d.log();
  EXPECT_EQ(opened.backend(), "gpu");

  v1::UpdateLightsRequest up;
  *up.mutable_scene() = refOf(opened);
  *up.add_add() = pointLight("key", 0.2f, 0.4f, 0.3f, 2.0f);
  up.set_wait_ms(30000);
  v1::UpdateLightsResponse ur;
  ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
  ASSERT_TRUE(ur.relit());
  Result res;
  ASSERT_NO_FATAL_FAILURE(relightResult(*rpc, opened, ur.version(), res));
  EXPECT_EQ(res.header.backend(), "gpu");

  v1::StatsRequest sr;
  *sr.mutable_scene() = refOf(opened);
  v1::StatsResponse stats;
  ASSERT_TRUE(rpc->Stats(context().get(), sr, &stats).ok());
  EXPECT_EQ(stats.scene(0).backend(), "gpu");
  EXPECT_FALSE(stats.scene(0).backend_note().empty());

  auto scene = scene::loadGltf((sourceDir() / "clients/demo/cornell_box.gltf").string());
  ASSERT_TRUE(scene);
  const auto before = relight::LightSet::fromSceneLights(scene->lights);
  auto lights = before;
  ASSERT_TRUE(lights.add(pointEntry("key", 0.2f, 0.4f, 0.3f, 2.0f)));
  // The daemon's relighter saw the initial set, then the update.
  const auto want = relightSequenceInProcess(f.cache, {{before}, {lights}}, InProcessBackend::kGpu);
  EXPECT_EQ(want.backend, "gpu");
  expectClose(decodeValues(res.payloads[v1::PAYLOAD_LIGHTMAP_SH], v1::PRECISION_FLOAT), want.lightmap_sh, "lightmap_sh");
  expectClose(decodeValues(res.payloads[v1::PAYLOAD_GRID_SH], v1::PRECISION_FLOAT), want.grid_sh, "grid_sh");
}

// Results of a Subscribe stream until one that is not a preview with version >= `version`.
std::vector<Result> readUntilConverged(ResultReader& reader, std::uint64_t version) {
  std::vector<Result> seen;
  Result r;
  while (reader.next(r)) {
    seen.push_back(r);
    if (r.header.version() >= version && !r.header.preview()) break;
  }
  EXPECT_TRUE(reader.error().empty()) << reader.error();
  return seen;
}

TEST(Daemon, ProgressivePublishesAWarmIterationThenTheConvergedResultAsTheNextVersion) {
  Fixture f;
  auto flags = quickFlags();
  flags.push_back("--progressive");
  DaemonProcess d(f.cache, flags);
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::SceneOpened opened;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();
  v1::SubscribeRequest sub;
  *sub.mutable_scene() = refOf(opened);
  sub.mutable_spec()->set_precision(v1::PRECISION_FLOAT);
  auto ctx = context(60000);
  auto stream = rpc->Subscribe(ctx.get(), sub);
  ResultReader reader(stream.get());
  // The initial light set too: one iteration (version 1), then, the cap of kBounces being
  // near, the cold relight as its converged result (version 2).
  auto initial = readUntilConverged(reader, 1);
  ASSERT_FALSE(initial.empty());
  const std::uint64_t converged0 = initial.back().header.version();
  EXPECT_EQ(converged0, 2u);
  EXPECT_EQ(initial.back().header.iterations(), std::uint32_t(kBounces));

  v1::UpdateLightsRequest up;
  *up.mutable_scene() = refOf(opened);
  *up.add_add() = pointLight("key", 0.2f, 0.4f, 0.3f, 2.0f);
  v1::UpdateLightsResponse ur;
  ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
  EXPECT_EQ(ur.version(), converged0 + 1) << "the converged result took a version of its own";
  auto results = readUntilConverged(reader, ur.version());
  ASSERT_FALSE(results.empty());
  std::uint64_t last = converged0;
  for (const auto& r : results) {
    EXPECT_GT(r.header.version(), last) << "versions increase";
    last = r.header.version();
  }
  const Result& converged = results.back();
  EXPECT_EQ(converged.header.version(), ur.version() + 1);
  EXPECT_FALSE(converged.header.preview());
  // The worker relit the update's version as a one-iteration preview first (its log says
  // so); a stream still sending it when the converged result is published skips it.
  bool logged_preview = false;
  std::istringstream log(d.log());
  for (std::string line; std::getline(log, line);)
    logged_preview |= line.find(" relight ") != std::string::npos &&
                      line.find(fmt::format("version={} ", ur.version())) != std::string::npos &&
                      line.find("preview=true") != std::string::npos && line.find("iterations=1 ") != std::string::npos;
  EXPECT_TRUE(logged_preview) << d.log();
  if (results.size() == 1) {
    EXPECT_EQ(converged.header.skipped_versions(), 1u);
  }

  // The same sequence in process: the converged result is the cold relight of the new lights,
  // the preview one warm iteration from the initial set's converged solution.
  auto scene = scene::loadGltf((sourceDir() / "clients/demo/cornell_box.gltf").string());
  ASSERT_TRUE(scene);
  const auto before = relight::LightSet::fromSceneLights(scene->lights);
  auto lights = before;
  ASSERT_TRUE(lights.add(pointEntry("key", 0.2f, 0.4f, 0.3f, 2.0f)));
  const auto full = relightInProcess(f.cache, lights);
  expectClose(decodeValues(converged.payloads.at(v1::PAYLOAD_LIGHTMAP_SH), v1::PRECISION_FLOAT), full.lightmap_sh,
              "converged lightmap_sh");
  expectClose(decodeValues(converged.payloads.at(v1::PAYLOAD_GRID_SH), v1::PRECISION_FLOAT), full.grid_sh,
              "converged grid_sh");
  if (results.size() >= 2) {
    const Result& preview = results.front();
    EXPECT_EQ(preview.header.version(), ur.version());
    EXPECT_TRUE(preview.header.preview());
    EXPECT_EQ(preview.header.iterations(), 1u);
    EXPECT_GT(preview.header.residual(), 0.0f);
    const auto warm = relightSequenceInProcess(f.cache, {{before, 1, false}, {before, kBounces, false}, {lights, 1, true}});
    expectClose(decodeValues(preview.payloads.at(v1::PAYLOAD_LIGHTMAP_SH), v1::PRECISION_FLOAT), warm.lightmap_sh,
                "preview lightmap_sh");
  }
  ctx->TryCancel();

  v1::StatsRequest sr;
  *sr.mutable_scene() = refOf(opened);
  v1::StatsResponse stats;
  ASSERT_TRUE(rpc->Stats(context().get(), sr, &stats).ok());
  EXPECT_EQ(stats.scene(0).previews(), 2u);
  EXPECT_EQ(stats.scene(0).version(), ur.version() + 1);

  // The converged version is the session's own (no client sent it), and clients have seen it:
  // it is durable before it is published, so a daemon killed now resumes at it.
  EXPECT_EQ(d.signalAndWait(SIGKILL), 128 + SIGKILL);
  DaemonProcess again(f.cache, quickFlags());
  ASSERT_TRUE(again.ok()) << again.error();
  v1::ListScenesResponse list;
  ASSERT_TRUE(again.rpc()->ListScenes(context().get(), {}, &list).ok());
  ASSERT_EQ(list.scenes_size(), 1);
  EXPECT_EQ(list.scenes(0).version(), ur.version() + 1);
}

// Bounces to convergence: once the initial set converged (by the threshold, not the cap), a
// change of one light is propagated incrementally and published converged at once, as the
// update's own version; no preview, no version taken by the session.
TEST(Daemon, ProgressivePublishesAnIncrementalChangeConvergedAtOnce) {
  Fixture f;
  DaemonProcess d(f.cache, {"--backend", "cpu", "--bounces", "100", "--progressive", "--log-level", "debug"});
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::SceneOpened opened;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();
  v1::SubscribeRequest sub;
  *sub.mutable_scene() = refOf(opened);
  auto ctx = context(60000);
  auto stream = rpc->Subscribe(ctx.get(), sub);
  ResultReader reader(stream.get());
  auto initial = readUntilConverged(reader, 1);
  ASSERT_FALSE(initial.empty());
  ASSERT_LT(initial.back().header.iterations(), 100u) << "the initial set converged by the threshold";

  v1::UpdateLightsRequest up;
  *up.mutable_scene() = refOf(opened);
  *up.add_add() = pointLight("key", 0.2f, 0.4f, 0.3f, 2.0f);
  v1::UpdateLightsResponse ur;
  ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
  auto results = readUntilConverged(reader, ur.version());
  ASSERT_FALSE(results.empty());
  const Result& r = results.back();
  EXPECT_EQ(r.header.version(), ur.version());
  EXPECT_FALSE(r.header.preview());
  EXPECT_GT(r.header.iterations(), 0u);
  bool logged = false;
  std::istringstream log(d.log());
  for (std::string line; std::getline(log, line);)
    logged |= line.find(" relight ") != std::string::npos &&
              line.find(fmt::format("version={} ", ur.version())) != std::string::npos &&
              line.find("incremental=true") != std::string::npos && line.find("preview=false") != std::string::npos;
  EXPECT_TRUE(logged) << d.log();
  ctx->TryCancel();
  v1::StatsRequest sr;
  *sr.mutable_scene() = refOf(opened);
  v1::StatsResponse stats;
  ASSERT_TRUE(rpc->Stats(context().get(), sr, &stats).ok());
  EXPECT_EQ(stats.scene(0).version(), ur.version());
}

TEST(Daemon, TwentyConcurrentClientsLoseNoUpdateAndSeeNoTornResult) {
  Fixture f;
  DaemonProcess d(f.cache, quickFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  v1::SceneOpened opened;
  {
    auto rpc = d.rpc();
    ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();
  }
  constexpr int kClients = 20, kUpdates = 4;
  std::vector<std::vector<std::uint64_t>> acked(kClients);
  std::vector<std::string> errors(kClients);
  std::vector<std::thread> threads;
  for (int c = 0; c < kClients; ++c) {
    threads.emplace_back([&, c] {
      auto rpc = d.rpc();  // one connection per client
      std::uint64_t last_seen = 0, last_polled = 0;
      for (int u = 0; u < kUpdates; ++u) {
        v1::UpdateLightsRequest up;
        *up.mutable_scene() = refOf(opened);
        const auto l = pointLight(fmt::format("c{}", c), 0.05f + 0.02f * c, 0.2f + 0.05f * u, 0.3f, 0.1f * (u + 1));
        *(u == 0 ? up.add_add() : up.add_modify()) = l;
        v1::UpdateLightsResponse ur;
        auto st = rpc->UpdateLights(context().get(), up, &ur);
        if (!st.ok()) {
          errors[c] = "update: " + st.error_message();
          return;
        }
        acked[c].push_back(ur.version());
        v1::GetTexturesRequest g;
        *g.mutable_scene() = refOf(opened);
        g.set_last_seen_version(last_seen);
        g.mutable_spec()->set_skip_grid(true);
        Result r;
        std::string err;
        auto ctx = context();
        auto reader = rpc->GetTextures(ctx.get(), g);
        st = readOne(reader.get(), r, &err);
        if (!st.ok() || !err.empty()) {
          errors[c] = fmt::format("poll: {} {}", st.error_message(), err);
          return;
        }
        if (r.header.version() < last_polled) {
          errors[c] = "result version went backwards";
          return;
        }
        last_polled = r.header.version();
        if (!r.header.not_modified()) {
          last_seen = r.header.version();
          const std::size_t texels = std::size_t(r.header.lightmap().width()) * r.header.lightmap().height();
          if (r.payloads[v1::PAYLOAD_LIGHTMAP_VALID].size() != texels ||
              r.payloads[v1::PAYLOAD_LIGHTMAP_SH].size() != texels * 3 * 9 * 2) {
            errors[c] = "payload sizes do not match the header";
            return;
          }
        }
      }
    });
  }
  for (auto& t : threads) t.join();
  for (int c = 0; c < kClients; ++c) ASSERT_TRUE(errors[c].empty()) << "client " << c << ": " << errors[c];

  // Every acknowledged update got its own version: 2 .. 1 + kClients * kUpdates.
  std::set<std::uint64_t> versions;
  for (const auto& a : acked) {
    EXPECT_TRUE(std::is_sorted(a.begin(), a.end()));
    versions.insert(a.begin(), a.end());
  }
  ASSERT_EQ(versions.size(), std::size_t(kClients * kUpdates));
  EXPECT_EQ(*versions.begin(), 2u);
  EXPECT_EQ(*versions.rbegin(), std::uint64_t(1 + kClients * kUpdates));

  // The result for the newest version reflects every client's last update.
  auto rpc = d.rpc();
  v1::RelightRequest rq;
  *rq.mutable_scene() = refOf(opened);
  rq.set_version(*versions.rbegin());
  rq.mutable_spec()->set_precision(v1::PRECISION_FLOAT);
  rq.mutable_spec()->set_skip_grid(true);
  auto ctx = context(30000);
  auto reader = rpc->Relight(ctx.get(), rq);
  Result final_result;
  std::string err;
  ASSERT_TRUE(readOne(reader.get(), final_result, &err).ok()) << err;
  EXPECT_EQ(final_result.header.version(), *versions.rbegin());

  auto scene = scene::loadGltf((sourceDir() / "clients/demo/cornell_box.gltf").string());
  ASSERT_TRUE(scene);
  auto lights = relight::LightSet::fromSceneLights(scene->lights);
  for (int c = 0; c < kClients; ++c)
    ASSERT_TRUE(lights.add(pointEntry(fmt::format("c{}", c), 0.05f + 0.02f * c, 0.2f + 0.05f * (kUpdates - 1), 0.3f,
                                      0.1f * kUpdates)));
  const auto want = relightInProcess(f.cache, lights);
  expectClose(decodeValues(final_result.payloads[v1::PAYLOAD_LIGHTMAP_SH], v1::PRECISION_FLOAT), want.lightmap_sh,
              "lightmap_sh after 20 clients");

  v1::StatsRequest sr;
  *sr.mutable_scene() = refOf(opened);
  v1::StatsResponse stats;
  ASSERT_TRUE(rpc->Stats(context().get(), sr, &stats).ok());
  ASSERT_EQ(stats.scene_size(), 1);
  EXPECT_EQ(stats.scene(0).updates(), std::uint64_t(kClients * kUpdates));
  EXPECT_GT(stats.rss_bytes(), 0u);
  EXPECT_GT(stats.scene(0).resident_bytes(), stats.scene(0).artifact_bytes());
  // Coalescing: fewer relights than versions when updates arrived during a relight.
  EXPECT_EQ(stats.scene(0).relights() + stats.scene(0).coalesced(), std::uint64_t(1 + kClients * kUpdates));
}

TEST(Daemon, HostileRequestsGetTheRightStatusAndTheDaemonKeepsServing) {
  CornellDaemon cornell;
  ASSERT_TRUE(cornell.open());
  auto& [f, d, rpc, opened] = cornell;

  // Oversized: a 65 MiB inline scene is beyond the 64 MiB receive limit.
  {
    v1::OpenSceneRequest big;
    big.set_gltf_bytes(std::string((65u << 20), 'x'));
    auto st = openScene(*rpc, big, nullptr, nullptr, "", 30000);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  }
  auto update = [&](const v1::UpdateLightsRequest& up) {
    v1::UpdateLightsResponse ur;
    return rpc->UpdateLights(context().get(), up, &ur);
  };
  // NaN and negative intensities, named by field.
  {
    v1::UpdateLightsRequest up;
    *up.mutable_scene() = refOf(opened);
    *up.add_add() = pointLight("ok", 0.1f, 0.1f, 0.1f, 1.0f);
    *up.add_add() = pointLight("bad", 0.1f, 0.1f, 0.1f, std::nanf(""));
    auto st = update(up);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("add[1].intensity"), std::string::npos) << st.error_message();
    up.mutable_add(1)->set_intensity(-3.0f);
    st = update(up);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("add[1].intensity"), std::string::npos) << st.error_message();
    up.mutable_add(1)->set_intensity(1e30f);
    EXPECT_EQ(update(up).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    up.mutable_add(1)->set_intensity(1.0f);
    up.mutable_add(1)->mutable_position()->set_y(std::numeric_limits<float>::infinity());
    st = update(up);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("add[1].position"), std::string::npos) << st.error_message();
  }
  // All or nothing: the valid "ok" light of the rejected requests was not added.
  {
    v1::UpdateLightsRequest up;
    *up.mutable_scene() = refOf(opened);
    up.add_remove("ok");
    EXPECT_EQ(update(up).error_code(), grpc::StatusCode::NOT_FOUND);
  }
  // Unknown scene, wrong scene token.
  {
    v1::UpdateLightsRequest up;
    up.mutable_scene()->set_scene_id("no-such-scene");
    up.mutable_scene()->set_token(opened.scene_token());
    EXPECT_EQ(update(up).error_code(), grpc::StatusCode::NOT_FOUND);
    *up.mutable_scene() = refOf(opened);
    up.mutable_scene()->set_token(std::string(32, '0'));
    auto st = update(up);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED);
    EXPECT_NE(st.error_message().find("token"), std::string::npos);
    v1::GetTexturesRequest g;
    *g.mutable_scene() = up.scene();
    auto ctx = context();
    auto reader = rpc->GetTextures(ctx.get(), g);
    Result r;
    EXPECT_EQ(readOne(reader.get(), r, nullptr).error_code(), grpc::StatusCode::PERMISSION_DENIED);
  }
  // Absurd precompute parameters and a missing file.
  {
    v1::OpenSceneRequest r = cornellRequest();
    r.set_surfels(1000000000u);
    auto st = openScene(*rpc, r, nullptr);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(st.error_message().find("surfels"), std::string::npos) << st.error_message();
    r = cornellRequest();
    r.set_links(-5);
    EXPECT_EQ(openScene(*rpc, r, nullptr).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    r = cornellRequest();
    r.set_grid_spacing(std::nanf(""));
    EXPECT_EQ(openScene(*rpc, r, nullptr).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    r = cornellRequest();
    r.set_path((f.tmp / "missing.gltf").string());
    EXPECT_EQ(openScene(*rpc, r, nullptr).error_code(), grpc::StatusCode::NOT_FOUND);
    r = cornellRequest();
    r.set_gltf_bytes("{ this is not gltf");
    EXPECT_EQ(openScene(*rpc, r, nullptr).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    // Inline bytes may not make the daemon read files of its own machine.
    r = cornellRequest();
    r.set_gltf_bytes(R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "/etc/passwd", "byteLength": 4}]})");
    const grpc::Status external = openScene(*rpc, r, nullptr);
    EXPECT_EQ(external.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(external.error_message().find("buffers[0].uri"), std::string::npos) << external.error_message();
  }
  // A result spec beyond the result, a version from the future.
  {
    v1::RelightRequest rq;
    *rq.mutable_scene() = refOf(opened);
    rq.mutable_spec()->set_bands(7);
    auto ctx = context();
    auto reader = rpc->Relight(ctx.get(), rq);
    Result r;
    EXPECT_EQ(readOne(reader.get(), r, nullptr).error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    rq.mutable_spec()->set_bands(0);
    rq.set_version(1000);
    auto ctx2 = context();
    auto reader2 = rpc->Relight(ctx2.get(), rq);
    EXPECT_EQ(readOne(reader2.get(), r, nullptr).error_code(), grpc::StatusCode::OUT_OF_RANGE);
  }
  // Still serving: health, and a valid update goes through.
  v1::HealthResponse health;
  ASSERT_TRUE(rpc->Health(context().get(), {}, &health).ok());
  EXPECT_EQ(health.status(), v1::HealthResponse::STATUS_SERVING);
  v1::UpdateLightsRequest up;
  *up.mutable_scene() = refOf(opened);
  *up.add_add() = pointLight("fine", 0.2f, 0.2f, 0.2f, 1.0f);
  v1::UpdateLightsResponse ur;
  ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
  EXPECT_EQ(ur.version(), 2u) << "rejected updates must not consume versions";
}

// The result calls take their request as bytes (raw callback methods): bytes that are no
// request message are INVALID_ARGUMENT naming the call, and the daemon keeps serving.
TEST(Daemon, ResultCallsRefuseBytesThatAreNoRequest) {
  Fixture f;
  DaemonProcess d(f.cache, quickFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  grpc::GenericStub generic(grpc::CreateChannel(d.target(), grpc::InsecureChannelCredentials()));
  const std::string garbage("\x0a\xff\xff\xff\xff\x0f", 6);  // field 1, a length past the end
  const grpc::Slice slice(garbage);
  for (const char* rpc : {"Relight", "GetTextures", "Subscribe"}) {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    const grpc::ByteBuffer request(&slice, 1);
    grpc::ByteBuffer response;
    std::promise<grpc::Status> done;
    generic.UnaryCall(&ctx, fmt::format("/lightlink.v1.Lightlink/{}", rpc), grpc::StubOptions(), &request, &response,
                      [&](grpc::Status st) { done.set_value(std::move(st)); });
    const grpc::Status st = done.get_future().get();
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << rpc << ": " << st.error_message();
    EXPECT_NE(st.error_message().find(rpc), std::string::npos) << st.error_message();
  }
  v1::HealthResponse health;
  EXPECT_TRUE(d.rpc()->Health(context().get(), v1::HealthRequest{}, &health).ok());
}

TEST(Daemon, BearerTokenIsRequiredWhenConfigured) {
  Fixture f;
  auto flags = quickFlags();
  flags.insert(flags.end(), {"--token-file", writeFile(f.tmp / "token", "s3cret-token-0123456789\n")});
  DaemonProcess d(f.cache, flags);
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::HealthResponse h;
  EXPECT_EQ(rpc->Health(context().get(), {}, &h).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(rpc->Health(context(20000, "wrong").get(), {}, &h).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(openScene(*rpc, cornellRequest(), nullptr).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_TRUE(rpc->Health(context(20000, "s3cret-token-0123456789").get(), {}, &h).ok());
  EXPECT_EQ(h.protocol_version(), 1u);
}

TEST(Daemon, ConfigFileJsonLogsAndSceneLimit) {
  Fixture f;
  const std::string config = writeFile(f.tmp / "lightlinkd.json",
                                       R"({"token": "from-file-0123456789", "log_format": "json", "max_scenes": 1,
                                           "bounces": 2, "log_level": "debug", "scene_roots": [")" +
                                           (sourceDir() / "clients/demo").string() + R"("]})");
  DaemonProcess d(f.cache, {"--config", config});
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::HealthResponse h;
  EXPECT_EQ(rpc->Health(context().get(), {}, &h).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  ASSERT_TRUE(rpc->Health(context(20000, "from-file-0123456789").get(), {}, &h).ok());
  v1::SceneOpened opened;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened, nullptr, "from-file-0123456789").ok()) << d.log();
  const auto st = openScene(*rpc, cornellRequest(), nullptr, nullptr, "from-file-0123456789");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  // Every log line is one JSON object with a timestamp and an event name.
  std::istringstream lines(d.log());
  std::string line;
  int events = 0;
  while (std::getline(lines, line)) {
    if (line.empty()) continue;
    const auto j = nlohmann::json::parse(line, nullptr, false);
    ASSERT_TRUE(j.is_object()) << line;
    EXPECT_TRUE(j.contains("ts") && j.contains("event") && j.contains("level")) << line;
    ++events;
  }
  EXPECT_GE(events, 2);
  // A config key that does not exist stops the daemon at start.
  const std::string bad = writeFile(f.tmp / "bad.json", R"({"tokn": "typo"})");
  std::string out;
  EXPECT_EQ(runDaemonToExit({"--config", bad, "--cache-dir", f.cache.string()}, &out), 2);
  EXPECT_NE(out.find("tokn"), std::string::npos) << out;
}

TEST(Daemon, ServesTlsWithTheGivenCertificate) {
  TempDir tmp;
  const std::string key = (tmp / "key.pem").string(), cert = (tmp / "cert.pem").string();
  const std::string make = "openssl req -x509 -newkey rsa:2048 -nodes -keyout " + key + " -out " + cert +
                           " -days 1 -subj /CN=localhost -addext subjectAltName=DNS:localhost,IP:127.0.0.1"
                           " > /dev/null 2>&1";
  if (std::system(make.c_str()) != 0) GTEST_SKIP() << "openssl not available to make a test certificate";
  DaemonProcess d(tmp / "cache", {"--tls-cert", cert, "--tls-key", key, "--token-file",
                                  writeFile(tmp / "token", "tls-token-0123456789\n")});
  ASSERT_TRUE(d.ok()) << d.error();
  std::ifstream in(cert);
  std::stringstream pem;
  pem << in.rdbuf();
  grpc::SslCredentialsOptions o;
  o.pem_root_certs = pem.str();
  auto tls = v1::Lightlink::NewStub(grpc::CreateChannel(d.target(), grpc::SslCredentials(o)));
  v1::HealthResponse h;
  const auto st = tls->Health(context(20000, "tls-token-0123456789").get(), {}, &h);
  EXPECT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(h.status(), v1::HealthResponse::STATUS_SERVING);
  // A plaintext client cannot talk to a TLS daemon.
  EXPECT_FALSE(d.rpc(std::chrono::milliseconds(0))->Health(context(3000, "tls-token-0123456789").get(), {}, &h).ok());
}

TEST(Daemon, RefusesToListenBeyondLoopbackWithoutToken) {
  TempDir tmp;
  std::string out;
  const int code = runDaemonToExit({"--listen", "0.0.0.0:0", "--cache-dir", (tmp / "c").string()}, &out);
  EXPECT_EQ(code, 2) << out;
  EXPECT_NE(out.find("--token-file"), std::string::npos) << out;
}

TEST(Daemon, HelpDocumentsEveryFlag) {
  std::string out;
  EXPECT_EQ(runDaemonToExit({"--help"}, &out), 0);
  for (const char* flag : {"--listen", "--port-file", "--cache-dir", "--token", "--token-file", "--tls-cert",
                           "--tls-key", "--backend", "--log-format", "--max-streams-per-client", "--config",
                           "--drain-seconds", "--bounces", "--progressive"})
    EXPECT_NE(out.find(flag), std::string::npos) << flag;
}

TEST(Daemon, PerClientStreamLimit) {
  Fixture f;
  auto flags = quickFlags();
  flags.insert(flags.end(), {"--max-streams-per-client", "2"});
  DaemonProcess d(f.cache, flags);
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::SceneOpened opened;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();
  v1::SubscribeRequest s;
  *s.mutable_scene() = refOf(opened);
  auto c1 = context(), c2 = context(), c3 = context();
  auto s1 = rpc->Subscribe(c1.get(), s);
  auto s2 = rpc->Subscribe(c2.get(), s);
  ResultReader r1(s1.get()), r2(s2.get());
  Result r;
  ASSERT_TRUE(r1.next(r));
  ASSERT_TRUE(r2.next(r));
  auto s3 = rpc->Subscribe(c3.get(), s);
  v1::ResultMessage m;
  EXPECT_FALSE(s3->Read(&m));
  EXPECT_EQ(s3->Finish().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  // Another connection is another client.
  auto other = d.rpc();
  auto c4 = context();
  auto s4 = other->Subscribe(c4.get(), s);
  ResultReader r4(s4.get());
  EXPECT_TRUE(r4.next(r)) << r4.error();
  for (auto* c : {c1.get(), c2.get(), c4.get()}) c->TryCancel();
}

TEST(Daemon, KillDuringPrecomputeThenRestartServesNoCorruptArtifact) {
  Fixture f;
  // A precompute long enough (about a second) that the kill lands inside it even when the
  // test reads the progress stream late on a loaded machine.
  v1::OpenSceneRequest slow = cornellRequest();
  slow.set_surfels(4096);
  slow.set_rays(512);
  {
    DaemonProcess d(f.cache, quickFlags());
    ASSERT_TRUE(d.ok()) << d.error();
    auto rpc = d.rpc();
    auto ctx = context(60000);
    auto reader = rpc->OpenScene(ctx.get(), slow);
    v1::OpenSceneProgress p;
    bool killed = false;
    while (reader->Read(&p)) {
      if (p.stage() == "surfels") {
        EXPECT_EQ(d.signalAndWait(SIGKILL), 128 + SIGKILL);
        killed = true;
        break;
      }
    }
    ASSERT_TRUE(killed) << "no precompute stage seen before the end";
  }
  // No artifact under its final name.
  for (const auto& e : fs::directory_iterator(f.cache))
    EXPECT_NE(e.path().extension(), ".llk") << e.path() << " should not exist after a kill during precompute";

  DaemonProcess d(f.cache, quickFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  // The killed daemon's temp files are gone.
  for (const auto& e : fs::directory_iterator(f.cache))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
  auto rpc = d.rpc();
  v1::SceneOpened reopened;
  ASSERT_TRUE(openScene(*rpc, slow, &reopened).ok()) << d.log();
  EXPECT_FALSE(reopened.artifact_reused());

  // A damaged artifact: the next open recomputes it instead of serving it.
  v1::SceneOpened opened;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();
  const fs::path artifact = f.cache / (opened.cache_key() + ".llk");
  ASSERT_TRUE(fs::exists(artifact));
  {
    std::fstream io(artifact, std::ios::in | std::ios::out | std::ios::binary);
    io.seekp(static_cast<std::streamoff>(fs::file_size(artifact) / 2));
    const char junk[8] = {'d', 'a', 'm', 'a', 'g', 'e', 'd', '!'};
    io.write(junk, sizeof junk);
  }
  v1::SceneOpened again;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &again).ok()) << d.log();
  EXPECT_FALSE(again.artifact_reused()) << "a damaged artifact must be recomputed";
  EXPECT_NE(again.scene_id(), opened.scene_id());
  v1::SceneOpened third;
  ASSERT_TRUE(openScene(*rpc, cornellRequest(), &third).ok());
  EXPECT_TRUE(third.artifact_reused()) << "the recomputed artifact replaced the damaged one";
}

TEST(Daemon, RestartReopensPersistedSessionsWithoutRecomputing) {
  Fixture f;
  v1::SceneOpened opened;
  Result before;
  {
    DaemonProcess d(f.cache, quickFlags());
    ASSERT_TRUE(d.ok()) << d.error();
    auto rpc = d.rpc();
    ASSERT_TRUE(openScene(*rpc, cornellRequest(), &opened).ok()) << d.log();
    v1::UpdateLightsRequest up;
    *up.mutable_scene() = refOf(opened);
    *up.add_add() = pointLight("kept", 0.3f, 0.2f, 0.25f, 1.5f);
    up.set_wait_ms(15000);
    v1::UpdateLightsResponse ur;
    ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
    ASSERT_EQ(ur.version(), 2u);
    v1::GetTexturesRequest g;
    *g.mutable_scene() = refOf(opened);
    auto ctx = context();
    auto reader = rpc->GetTextures(ctx.get(), g);
    std::string err;
    ASSERT_TRUE(readOne(reader.get(), before, &err).ok()) << err;
    ASSERT_EQ(before.header.version(), 2u);
    EXPECT_EQ(d.signalAndWait(SIGTERM), 0) << d.log();
  }
  ASSERT_TRUE(fs::exists(f.cache / "sessions.json"));
  DaemonProcess d(f.cache, quickFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::ListScenesResponse list;
  ASSERT_TRUE(rpc->ListScenes(context().get(), {}, &list).ok());
  ASSERT_EQ(list.scenes_size(), 1);
  EXPECT_EQ(list.scenes(0).scene_id(), opened.scene_id());
  EXPECT_EQ(list.scenes(0).version(), 2u);
  // Same id and token, same light set: the same result, and the artifact was reused.
  v1::GetTexturesRequest g;
  *g.mutable_scene() = refOf(opened);
  auto ctx = context();
  auto reader = rpc->GetTextures(ctx.get(), g);
  Result after;
  std::string err;
  ASSERT_TRUE(readOne(reader.get(), after, &err).ok()) << err;
  EXPECT_EQ(after.header.version(), 2u);
  EXPECT_EQ(after.payloads, before.payloads);
  const std::string log = d.log();
  EXPECT_NE(log.find("scene_restored"), std::string::npos) << log;
  EXPECT_NE(log.find("artifact_reused=true"), std::string::npos) << log;
  // Versions keep growing after the restart.
  v1::UpdateLightsRequest up;
  *up.mutable_scene() = refOf(opened);
  up.add_remove("kept");
  v1::UpdateLightsResponse ur;
  ASSERT_TRUE(rpc->UpdateLights(context().get(), up, &ur).ok());
  EXPECT_EQ(ur.version(), 3u);
}

TEST(Daemon, SigtermDrainsStreamsAndExitsZero) {
  CornellDaemon cornell;
  ASSERT_TRUE(cornell.open());
  auto& [f, d, rpc, opened] = cornell;
  v1::SubscribeRequest s;
  *s.mutable_scene() = refOf(opened);
  auto ctx = context(30000);
  auto stream = rpc->Subscribe(ctx.get(), s);
  ResultReader reader(stream.get());
  Result r;
  ASSERT_TRUE(reader.next(r)) << reader.error();

  std::atomic<int> code{-2};
  std::thread stopper([&] { code = d.signalAndWait(SIGTERM, std::chrono::milliseconds(15000)); });
  // The subscriber sees its stream end cleanly (OK), not cut.
  EXPECT_FALSE(reader.next(r));
  EXPECT_TRUE(reader.error().empty()) << reader.error();
  const grpc::Status st = stream->Finish();
  EXPECT_TRUE(st.ok()) << st.error_code() << " " << st.error_message();
  stopper.join();
  EXPECT_EQ(code.load(), 0) << d.log();
  EXPECT_NE(d.log().find("draining"), std::string::npos);
}

}  // namespace
}  // namespace lightlink::testing
