// Acknowledged light updates survive the daemon (docs/service.md "Artifacts and persistence"):
// kill -9 at random points of update bursts never loses an acknowledged version nor hands a
// number out again, and a full disk fails updates cleanly while reads go on.
//
// Every update replaces the punctual lights with one marker light "u<k>" (k unique in the
// test), so a version's content is its marker. After a restart the scene's content is read
// back by a `modify` of the expected marker: it succeeds only when that marker is the light
// there, and it is itself an update whose version must be above every acknowledged one.
#include <signal.h>
#include <sys/mount.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <thread>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "tests/common/testing.h"
#include "tests/service/daemon_harness.h"

namespace lightlink::testing {
namespace {

namespace fs = std::filesystem;

// No bounces: the relight worker stays cheap while the clients hammer the daemon.
std::vector<std::string> daemonFlags() { return {"--backend", "cpu", "--bounces", "0", "--log-level", "info"}; }

v1::SceneRef refOf(const v1::SceneOpened& o) {
  v1::SceneRef r;
  r.set_scene_id(o.scene_id());
  r.set_token(o.scene_token());
  return r;
}

// The usual small Cornell box, sent inline (it is self-contained): the daemon needs no scene
// root, and restores it from its cache.
v1::OpenSceneRequest cornellInline() {
  v1::OpenSceneRequest r = cornellRequest();
  std::ifstream in(sourceDir() / "clients/demo/cornell_box.gltf", std::ios::binary);
  r.set_gltf_bytes(std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()));
  return r;
}

std::string markerId(std::uint64_t k) { return fmt::format("u{}", k); }

// The update that makes marker k the scene's only punctual light.
v1::UpdateLightsRequest markerUpdate(const v1::SceneRef& scene, std::uint64_t k) {
  v1::UpdateLightsRequest up;
  *up.mutable_scene() = scene;
  up.set_replace_lights(true);
  v1::Light* l = up.add_add();
  l->set_id(markerId(k));
  l->set_type(v1::LIGHT_TYPE_POINT);
  l->mutable_position()->set_x(0.1f + 0.001f * static_cast<float>(k % 300));
  l->mutable_position()->set_y(0.4f);
  l->mutable_position()->set_z(0.3f);
  l->set_intensity(1.0f + 0.01f * static_cast<float>(k % 100));
  return up;
}

// A content-preserving update that succeeds only when marker k is in the scene.
grpc::Status probeMarker(LightlinkRpc& rpc, const v1::SceneRef& scene, std::uint64_t k, std::uint64_t* version) {
  v1::UpdateLightsRequest up;
  *up.mutable_scene() = scene;
  up.add_modify()->set_id(markerId(k));
  v1::UpdateLightsResponse r;
  const grpc::Status st = rpc.UpdateLights(context(10000).get(), up, &r);
  if (st.ok()) *version = r.version();
  return st;
}

std::uint64_t sceneVersion(LightlinkRpc& rpc, const std::string& id) {
  v1::ListScenesResponse list;
  if (!rpc.ListScenes(context(10000).get(), {}, &list).ok()) return 0;
  for (const auto& s : list.scenes())
    if (s.scene_id() == id) return s.version();
  return 0;
}

// What the clients were told: every acknowledged (version, marker), and the markers sent
// whose answer never came.
struct AckLog {
  std::mutex mutex;
  std::map<std::uint64_t, std::uint64_t> marker_of;  // version -> marker, over the whole test
  std::set<std::uint64_t> unanswered;               // markers of the last round without an answer
  std::uint64_t repeats = 0;                        // a version acknowledged twice
  std::string first_repeat;

  void ack(std::uint64_t version, std::uint64_t k) {
    std::lock_guard lock(mutex);
    auto [it, fresh] = marker_of.emplace(version, k);
    if (!fresh && repeats++ == 0)
      first_repeat = fmt::format("version {} acknowledged for marker {} and again for marker {}", version, it->second, k);
  }
  std::pair<std::uint64_t, std::uint64_t> highest() {
    std::lock_guard lock(mutex);
    if (marker_of.empty()) return {0, 0};
    return {marker_of.rbegin()->first, marker_of.rbegin()->second};
  }
};

// Clients sending marker updates back to back, each on its own connection, until their
// daemon is gone.
class Burst {
 public:
  Burst(const DaemonProcess& d, const v1::SceneRef& scene, AckLog& log, std::atomic<std::uint64_t>& next_marker,
        int clients)
      : log_(log) {
    for (int c = 0; c < clients; ++c) {
      auto rpc = std::shared_ptr<LightlinkRpc>(d.rpc());
      threads_.emplace_back([this, rpc, scene, &next_marker] {
        std::uint64_t last = 0;
        while (true) {
          const std::uint64_t k = next_marker++;
          v1::UpdateLightsResponse r;
          const grpc::Status st = rpc->UpdateLights(context(5000).get(), markerUpdate(scene, k), &r);
          if (!st.ok()) {
            std::lock_guard lock(log_.mutex);
            log_.unanswered.insert(k);
            return;
          }
          log_.ack(r.version(), k);
          if (r.version() <= last) {
            std::lock_guard lock(log_.mutex);
            if (log_.repeats++ == 0) log_.first_repeat = fmt::format("a client got {} after {}", r.version(), last);
          }
          last = r.version();
          ++acks_;
        }
      });
    }
  }
  ~Burst() { join(); }
  void join() {
    for (auto& t : threads_)
      if (t.joinable()) t.join();
  }
  std::uint64_t acks() const { return acks_.load(); }

 private:
  AckLog& log_;
  std::atomic<std::uint64_t> acks_{0};
  std::vector<std::thread> threads_;
};

// After a restart: the scene holds the newest acknowledged version with its content, or a
// later version whose update was sent but not answered; a new update gets a version above
// every acknowledged one. The probe's own version is acknowledged like any other.
::testing::AssertionResult restoredStateIsAcknowledged(LightlinkRpc& rpc, const v1::SceneRef& scene, AckLog& log,
                                                       int round) {
  const auto [acked_version, acked_marker] = log.highest();
  const std::uint64_t restored = sceneVersion(rpc, scene.scene_id());
  if (restored < acked_version)
    return ::testing::AssertionFailure() << "round " << round << ": restored version " << restored
                                         << " is below the acknowledged version " << acked_version;
  std::vector<std::uint64_t> candidates;
  if (restored == acked_version) {
    candidates.push_back(acked_marker);
  } else {
    std::lock_guard lock(log.mutex);
    candidates.assign(log.unanswered.begin(), log.unanswered.end());
  }
  for (std::uint64_t k : candidates) {
    std::uint64_t v = 0;
    const grpc::Status st = probeMarker(rpc, scene, k, &v);
    if (st.error_code() == grpc::StatusCode::NOT_FOUND) continue;
    if (!st.ok())
      return ::testing::AssertionFailure() << "round " << round << ": probe of u" << k << ": " << st.error_message();
    if (v <= acked_version)
      return ::testing::AssertionFailure() << "round " << round << ": a new update got version " << v
                                           << ", not above the acknowledged " << acked_version;
    log.ack(v, k);
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure() << "round " << round << ": restored version " << restored
                                       << " holds none of the expected markers (acknowledged: v" << acked_version
                                       << " = u" << acked_marker << ")";
}

TEST(Durability, KillNineDuringUpdateBurstsLosesNoAcknowledgedVersion) {
  constexpr int kRounds = 50, kClients = 4;
  TempDir tmp;
  const fs::path cache = tmp / "cache";
  std::mt19937 rng(44);  // fixed seed: the same kill points every run
  std::uniform_int_distribution<int> kill_after_ms(0, 60);
  AckLog log;
  std::atomic<std::uint64_t> next_marker{1};
  v1::SceneRef scene;
  std::uint64_t total_acks = 0;
  double start_ms = 0.0;  // the restarts' time to listening, summed
  for (int round = 0; round <= kRounds; ++round) {
    const auto t0 = std::chrono::steady_clock::now();
    DaemonProcess d(cache, daemonFlags());
    if (round > 0) start_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_TRUE(d.ok()) << "round " << round << ": " << d.error();
    auto rpc = d.rpc();
    if (round == 0) {
      v1::SceneOpened opened;
      const grpc::Status st = openScene(*rpc, cornellInline(), &opened);
      ASSERT_TRUE(st.ok()) << st.error_message() << "\n" << d.log();
      scene = refOf(opened);
      v1::UpdateLightsResponse r;  // a first marker, so "the newest acknowledged" always exists
      ASSERT_TRUE(rpc->UpdateLights(context().get(), markerUpdate(scene, next_marker), &r).ok()) << d.log();
      log.ack(r.version(), next_marker++);
    } else {
      ASSERT_TRUE(restoredStateIsAcknowledged(*rpc, scene, log, round)) << d.log();
      std::lock_guard lock(log.mutex);
      log.unanswered.clear();
    }
    if (round == kRounds) break;
    Burst burst(d, scene, log, next_marker, kClients);
    std::this_thread::sleep_for(std::chrono::milliseconds(kill_after_ms(rng)));
    ASSERT_EQ(d.signalAndWait(SIGKILL), 128 + SIGKILL);
    burst.join();
    total_acks += burst.acks();
  }
  EXPECT_EQ(log.repeats, 0u) << log.first_repeat;
  std::printf("kill -9 rounds: %d, acknowledged updates: %llu, every acknowledged version restored; "
              "restart to listening %.0f ms on average\n",
              kRounds, static_cast<unsigned long long>(total_acks), start_ms / kRounds);
  // The bursts did acknowledge updates before their kills (else nothing was tested).
  EXPECT_GT(total_acks, static_cast<std::uint64_t>(kRounds)) << "acknowledged updates over all rounds";
  RecordProperty("acknowledged_updates", static_cast<int>(total_acks));
}

// An acknowledged CloseScene is durable too: a kill -9 right after it never brings the scene
// (and its token) back after the restart.
TEST(Durability, AcknowledgedCloseSurvivesKillNine) {
  TempDir tmp;
  const fs::path cache = tmp / "cache";
  v1::SceneRef kept, closed;
  {
    DaemonProcess d(cache, daemonFlags());
    ASSERT_TRUE(d.ok()) << d.error();
    auto rpc = d.rpc();
    v1::SceneOpened a, b;
    ASSERT_TRUE(openScene(*rpc, cornellInline(), &a).ok()) << d.log();
    v1::OpenSceneRequest second = cornellInline();
    second.set_name("second");
    ASSERT_TRUE(openScene(*rpc, second, &b).ok()) << d.log();
    kept = refOf(a);
    closed = refOf(b);
    v1::CloseSceneRequest close;
    *close.mutable_scene() = closed;
    v1::CloseSceneResponse closed_answer;
    ASSERT_TRUE(rpc->CloseScene(context().get(), close, &closed_answer).ok()) << d.log();
    ASSERT_EQ(d.signalAndWait(SIGKILL), 128 + SIGKILL);
  }
  DaemonProcess d(cache, daemonFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::ListScenesResponse list;
  ASSERT_TRUE(rpc->ListScenes(context(10000).get(), {}, &list).ok()) << d.log();
  std::set<std::string> ids;
  for (const auto& s : list.scenes()) ids.insert(s.scene_id());
  EXPECT_EQ(ids.count(kept.scene_id()), 1u) << d.log();
  EXPECT_EQ(ids.count(closed.scene_id()), 0u) << "the acknowledged close was undone by the crash\n" << d.log();
}

// A small filesystem for the cache (tmpfs, mounted here: needs root or CAP_SYS_ADMIN) and a
// file that fills it.
class SmallDisk {
 public:
  explicit SmallDisk(const fs::path& at) : at_(at) {
    fs::create_directories(at_);
    if (::mount("tmpfs", at_.c_str(), "tmpfs", 0, "size=16m,mode=0700") != 0) error_ = std::strerror(errno);
  }
  ~SmallDisk() {
    if (error_.empty()) ::umount2(at_.c_str(), MNT_DETACH);
  }
  const std::string& error() const { return error_; }
  // Writes a filler until the filesystem is full.
  void fill() {
    std::ofstream f(at_ / "filler", std::ios::binary);
    const std::string block(4096, 'x');
    while (f.write(block.data(), static_cast<std::streamsize>(block.size()))) f.flush();
  }
  void free() { fs::remove(at_ / "filler"); }

 private:
  fs::path at_;
  std::string error_;
};

TEST(Durability, FullDiskFailsUpdatesCleanlyAndReadsGoOn) {
  TempDir tmp;
  SmallDisk disk(tmp / "small");
  if (!disk.error().empty()) GTEST_SKIP() << "cannot mount a tmpfs here (" << disk.error() << "): needs root";
  const fs::path cache = tmp / "small" / "cache";
  v1::SceneRef scene;
  std::uint64_t acked = 0, acked_marker = 0, k = 1;
  {
    DaemonProcess d(cache, daemonFlags());
    ASSERT_TRUE(d.ok()) << d.error();
    auto rpc = d.rpc();
    v1::SceneOpened opened;
    ASSERT_TRUE(openScene(*rpc, cornellInline(), &opened).ok()) << d.log();
    scene = refOf(opened);
    v1::UpdateLightsResponse r;
    ASSERT_TRUE(rpc->UpdateLights(context().get(), markerUpdate(scene, k), &r).ok());
    acked = r.version();
    acked_marker = k++;

    disk.fill();
    // The journal's last page may still hold a record or two; then the disk is full.
    grpc::Status failed;
    for (int i = 0; i < 200 && failed.ok(); ++i) {
      failed = rpc->UpdateLights(context().get(), markerUpdate(scene, k), &r);
      if (failed.ok()) {
        acked = r.version();
        acked_marker = k;
      }
      ++k;
    }
    ASSERT_FALSE(failed.ok()) << "updates on a full disk are still acknowledged";
    EXPECT_EQ(failed.error_code(), grpc::StatusCode::UNAVAILABLE) << failed.error_message();
    EXPECT_NE(failed.error_message().find("cannot persist the update: No space left on device"), std::string::npos)
        << failed.error_message();
    // Nothing changed: the version was not consumed, the result is the acknowledged one.
    EXPECT_EQ(sceneVersion(*rpc, scene.scene_id()), acked);
    EXPECT_FALSE(rpc->UpdateLights(context().get(), markerUpdate(scene, k++), &r).ok());
    v1::GetTexturesRequest g;
    *g.mutable_scene() = scene;
    auto ctx = context();
    auto reader = rpc->GetTextures(ctx.get(), g);
    Result result;
    std::string err;
    ASSERT_TRUE(readOne(reader.get(), result, &err).ok()) << err << "\n" << d.log();
    // The newest result may still be computing for `acked`: Relight waits for it.
    v1::RelightRequest rr;
    *rr.mutable_scene() = scene;
    rr.set_version(acked);
    auto rctx = context();
    auto rreader = rpc->Relight(rctx.get(), rr);
    ASSERT_TRUE(readOne(rreader.get(), result, &err).ok()) << err << "\n" << d.log();
    EXPECT_EQ(result.header.version(), acked);

    // Space again: the next update takes the next version.
    disk.free();
    ASSERT_TRUE(rpc->UpdateLights(context().get(), markerUpdate(scene, k), &r).ok()) << d.log();
    EXPECT_EQ(r.version(), acked + 1) << "failed updates must not consume versions";
    acked = r.version();
    acked_marker = k++;
    EXPECT_EQ(d.signalAndWait(SIGKILL), 128 + SIGKILL);
  }
  // Nothing stored is corrupt: the restart holds the last acknowledged update.
  DaemonProcess d(cache, daemonFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  EXPECT_EQ(sceneVersion(*rpc, scene.scene_id()), acked) << d.log();
  std::uint64_t v = 0;
  EXPECT_TRUE(probeMarker(*rpc, scene, acked_marker, &v).ok()) << d.log();
  EXPECT_EQ(v, acked + 1);
}

}  // namespace
}  // namespace lightlink::testing
