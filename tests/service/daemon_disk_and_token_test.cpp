// The daemon's disk and token rules through real lightlinkd processes: a restart listens
// while its scenes are restored in the background; uploads are stored only once they load;
// cache files are private; the cache quota evicts closed scenes' files; tokens never come
// from argv, are long enough, need TLS beyond loopback, guard the health services and
// are rate limited after repeated failures.
#include <signal.h>
#include <sys/stat.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/common/testing.h"
#include "tests/service/daemon_harness.h"

namespace lightlink::testing {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

const std::string kToken = "0123456789abcdef-test-token";

std::vector<std::string> quickFlags(std::vector<std::string> more = {}) {
  std::vector<std::string> f = {"--backend", "cpu", "--bounces", "1", "--log-level", "debug"};
  f.insert(f.end(), more.begin(), more.end());
  return f;
}

unsigned modeOf(const fs::path& p) {
  struct stat st {};
  if (::lstat(p.c_str(), &st) != 0) return 0xffff;
  return st.st_mode & 07777;
}

std::vector<fs::path> filesIn(const fs::path& dir, const std::string& suffix) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
      out.push_back(e.path());
  }
  return out;
}

std::string readAll(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// One call of grpc.health.v1.Health/Check (an empty HealthCheckRequest: the whole server).
grpc::Status standardHealthCheck(const std::shared_ptr<grpc::Channel>& channel, const std::string& bearer) {
  grpc::GenericStub stub(channel);
  auto ctx = context(5000, bearer);
  grpc::Slice empty(std::string{});
  grpc::ByteBuffer request(&empty, 1), response;
  grpc::Status result;
  bool done = false;
  std::mutex m;
  std::condition_variable cv;
  stub.UnaryCall(ctx.get(), "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                 [&](grpc::Status s) {
                   std::lock_guard lock(m);
                   result = s;
                   done = true;
                   cv.notify_all();
                 });
  std::unique_lock lock(m);
  cv.wait(lock, [&] { return done; });
  return result;
}

TEST(DaemonTokens, ArgvTokenShortTokenAndPlaintextBeyondLoopbackAreRefused) {
  TempDir tmp;
  const std::string cache = (tmp / "cache").string();
  std::string out;
  EXPECT_EQ(runDaemonToExit({"--cache-dir", cache, "--token", kToken}, &out), 2) << out;
  EXPECT_NE(out.find("--token-file"), std::string::npos) << out;
  EXPECT_NE(out.find("LIGHTLINKD_TOKEN"), std::string::npos) << out;
  const std::string short_token = writeFile(tmp / "short", "abc\n");
  EXPECT_EQ(runDaemonToExit({"--cache-dir", cache, "--token-file", short_token}, &out), 2) << out;
  EXPECT_NE(out.find("too short"), std::string::npos) << out;
  const std::string token = writeFile(tmp / "token", kToken + "\n");
  EXPECT_EQ(runDaemonToExit({"--cache-dir", cache, "--listen", "0.0.0.0:0", "--token-file", token}, &out), 2) << out;
  EXPECT_NE(out.find("TLS"), std::string::npos) << out;
  EXPECT_NE(out.find("--allow-plaintext-token"), std::string::npos) << out;
}

TEST(DaemonTokens, HealthAnswersOnlyWithTheTokenWhenOneIsSet) {
  TempDir tmp;
  {
    // No token: the standard health service answers anyone (load balancers, k8s probes).
    DaemonProcess open_daemon(tmp / "open", quickFlags({"--no-restore"}));
    ASSERT_TRUE(open_daemon.ok()) << open_daemon.error();
    const auto st = standardHealthCheck(open_daemon.channel(), "");
    EXPECT_TRUE(st.ok()) << st.error_code() << " " << st.error_message();
  }
  const std::string token = writeFile(tmp / "token", kToken + "\n");
  DaemonProcess d(tmp / "cache", quickFlags({"--token-file", token}));
  ASSERT_TRUE(d.ok()) << d.error();
  EXPECT_FALSE(standardHealthCheck(d.channel(), "").ok()) << "grpc.health.v1 must not answer without the token";
  auto rpc = d.rpc();
  v1::HealthResponse h;
  EXPECT_EQ(rpc->Health(context().get(), {}, &h).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_TRUE(rpc->Health(context(5000, kToken).get(), {}, &h).ok());
}

TEST(DaemonTokens, RepeatedFailuresFromAnAddressAreRateLimited) {
  TempDir tmp;
  const std::string token = writeFile(tmp / "token", kToken + "\n");
  DaemonProcess d(tmp / "cache", quickFlags({"--token-file", token, "--no-restore"}));
  ASSERT_TRUE(d.ok()) << d.error();
  v1::HealthResponse h;
  int unauthenticated = 0;
  grpc::StatusCode last = grpc::StatusCode::OK;
  for (int i = 0; i < 12; ++i) {
    // New connections: the limit is per address, not per connection.
    last = d.rpc()->Health(context(5000, "wrong-token-guess-" + std::to_string(i)).get(), {}, &h).error_code();
    if (last == grpc::StatusCode::UNAUTHENTICATED) ++unauthenticated;
  }
  EXPECT_EQ(unauthenticated, 10) << "10 failures are answered, then the address is blocked";
  EXPECT_EQ(last, grpc::StatusCode::RESOURCE_EXHAUSTED);
  // While blocked even the right token is refused without being compared.
  const auto st = d.rpc()->Health(context(5000, kToken).get(), {}, &h);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  const std::string log = d.log();
  std::size_t blocks = 0;
  for (auto at = log.find("auth_rate_limited"); at != std::string::npos; at = log.find("auth_rate_limited", at + 1))
    ++blocks;
  EXPECT_EQ(blocks, 1u) << "logged once per block\n" << log;
}

// Sets the umask for a scope; the daemon started inside inherits it.
struct Umask {
  explicit Umask(mode_t m) : old(::umask(m)) {}
  ~Umask() { ::umask(old); }
  mode_t old;
};

TEST(DaemonDisk, UploadsStoredOnlyOnceValidFilesPrivateAndClosedScenesEvicted) {
  TempDir tmp;
  const fs::path cache = tmp / "cache";
  Umask open_umask(0);  // only explicit modes keep the cache private
  // A 1-byte quota: every closed scene's file goes at the next write; resident ones stay.
  DaemonProcess d(cache, quickFlags({"--cache-quota", "1"}));
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  // Garbage, and a glTF that parses but is no scene: refused, and nothing is stored.
  for (const std::string& bytes : {std::string("{ this is not gltf"), std::string(R"({"asset": {"version": "2.0"}})"),
                                  std::string("glTF\x02\0\0\0garbage-garbage-garbage", 31)}) {
    v1::OpenSceneRequest r = cornellRequest();
    r.set_gltf_bytes(bytes);
    const auto st = openScene(*rpc, r, nullptr);
    EXPECT_FALSE(st.ok());
    EXPECT_NE(st.error_code(), grpc::StatusCode::INTERNAL) << st.error_message();
  }
  EXPECT_TRUE(filesIn(cache / "inline", "").empty()) << "an upload that does not load never stays on disk";

  // A valid upload is stored, privately, as is its artifact.
  v1::OpenSceneRequest upload = cornellRequest();
  upload.set_gltf_bytes(readAll(sourceDir() / "clients/demo/cornell_box.gltf"));
  v1::SceneOpened a;
  ASSERT_TRUE(openScene(*rpc, upload, &a).ok()) << d.log();
  const auto inline_files = filesIn(cache / "inline", ".gltf");
  ASSERT_EQ(inline_files.size(), 1u);
  const auto artifacts_a = filesIn(cache, ".llk");
  ASSERT_EQ(artifacts_a.size(), 1u);
  EXPECT_EQ(modeOf(cache), 0700u);
  EXPECT_EQ(modeOf(cache / "inline"), 0700u);
  EXPECT_EQ(modeOf(inline_files[0]), 0600u);
  EXPECT_EQ(modeOf(artifacts_a[0]), 0600u);
  for (int i = 0; i < 200 && !fs::exists(cache / "sessions.json"); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  EXPECT_EQ(modeOf(cache / "sessions.json"), 0600u);

  // Resident: over the quota, yet kept. Closed: evicted when the next scene's artifact lands.
  v1::OpenSceneRequest other = cornellRequest();
  other.set_surfels(1024);
  v1::SceneOpened b;
  ASSERT_TRUE(openScene(*rpc, other, &b).ok()) << d.log();
  EXPECT_TRUE(fs::exists(artifacts_a[0])) << "a resident scene's artifact is never evicted";
  EXPECT_TRUE(fs::exists(inline_files[0]));
  v1::CloseSceneRequest close;
  close.mutable_scene()->set_scene_id(a.scene_id());
  close.mutable_scene()->set_token(a.scene_token());
  v1::CloseSceneResponse closed;
  ASSERT_TRUE(rpc->CloseScene(context().get(), close, &closed).ok());
  v1::OpenSceneRequest third = cornellRequest();
  third.set_surfels(512);
  ASSERT_TRUE(openScene(*rpc, third, nullptr).ok()) << d.log();
  EXPECT_FALSE(fs::exists(artifacts_a[0])) << "the closed scene's artifact was evicted\n" << d.log();
  EXPECT_FALSE(fs::exists(inline_files[0])) << "and its stored upload";
  EXPECT_EQ(filesIn(cache, ".llk").size(), 2u) << "the two resident scenes' artifacts stay";
}

TEST(DaemonDisk, RestartListensAtOnceWhileASlowSceneIsRestored) {
  TempDir tmp;
  const fs::path cache = tmp / "cache";
  v1::SceneOpened opened;
  {
    DaemonProcess d(cache, quickFlags());
    ASSERT_TRUE(d.ok()) << d.error();
    ASSERT_TRUE(openScene(*d.rpc(), cornellRequest(), &opened).ok()) << d.log();
    ASSERT_EQ(d.signalAndWait(SIGTERM), 0) << d.log();
  }
  // Make the recorded scene slow to re-open: a far heavier precompute, nothing cached.
  nlohmann::json sessions = nlohmann::json::parse(readAll(cache / "sessions.json"));
  ASSERT_EQ(sessions["scenes"].size(), 1u);
  auto& params = sessions["scenes"][0]["params"];
  params["surfels"] = 200000;  // modest memory (links), many rays: time, not space
  params["rays"] = 65536;
  params["links"] = 64;
  writeFile(cache / "sessions.json", sessions.dump());
  for (const auto& f : filesIn(cache, ".llk")) fs::remove(f);

  const auto start = Clock::now();
  DaemonProcess d(cache, quickFlags());
  ASSERT_TRUE(d.ok()) << d.error();
  auto rpc = d.rpc();
  v1::HealthResponse h;
  ASSERT_TRUE(rpc->Health(context(5000).get(), {}, &h).ok());
  v1::ListScenesResponse list;
  ASSERT_TRUE(rpc->ListScenes(context(5000).get(), {}, &list).ok());
  const double answered_s = std::chrono::duration<double>(Clock::now() - start).count();
  RecordProperty("answered_ms", static_cast<int>(answered_s * 1000));
  // The restore alone takes about ten seconds on a 2-core machine; listening must not wait for it.
  EXPECT_LT(answered_s, 5.0) << d.log();
  ASSERT_EQ(list.scenes_size(), 1);
  EXPECT_EQ(list.scenes(0).scene_id(), opened.scene_id());
  EXPECT_EQ(list.scenes(0).backend(), "restoring");
  // A call naming the scene waits within its deadline, then says it is still restoring (or,
  // on a machine fast enough to finish the restore within the deadline, is answered); a
  // wrong scene token is refused at once.
  v1::GetTexturesRequest g;
  g.mutable_scene()->set_scene_id(opened.scene_id());
  g.mutable_scene()->set_token(opened.scene_token());
  auto ctx = context(2000);
  auto reader = rpc->GetTextures(ctx.get(), g);
  Result r;
  const auto st = readOne(reader.get(), r, nullptr);
  // The answer leaves 250 ms before the deadline; on a machine the restore keeps busy it
  // may still arrive late, which the client sees as its own deadline.
  RecordProperty("waiting_call_code", static_cast<int>(st.error_code()));
  if (st.ok()) {
    v1::ListScenesResponse after;
    ASSERT_TRUE(rpc->ListScenes(context(5000).get(), {}, &after).ok());
    ASSERT_EQ(after.scenes_size(), 1);
    EXPECT_NE(after.scenes(0).backend(), "restoring") << "answered while still restoring";
  } else {
    EXPECT_TRUE(st.error_code() == grpc::StatusCode::UNAVAILABLE ||
                st.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED)
        << st.error_code() << " " << st.error_message();
  }
  if (st.error_code() == grpc::StatusCode::UNAVAILABLE) {
    EXPECT_NE(st.error_message().find("restored"), std::string::npos) << st.error_message();
  }
  g.mutable_scene()->set_token(std::string(32, '0'));
  auto ctx2 = context(1000);
  auto reader2 = rpc->GetTextures(ctx2.get(), g);
  EXPECT_EQ(readOne(reader2.get(), r, nullptr).error_code(), grpc::StatusCode::PERMISSION_DENIED);
}

}  // namespace
}  // namespace lightlink::testing
