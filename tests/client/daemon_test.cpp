// The client library, the CLI and the Python example against real lightlinkd processes on
// loopback (port 0 + port file, artifacts in the build tree so only the first test
// precomputes). Every call has a deadline; every child process a time limit.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <thread>

#include "clients/client/client.h"
#include "clients/client/local_daemon.h"
#include "clients/client/session.h"
#include "clients/viewer/baked_lighting.h"
#include "tests/client/process.h"
#include "tests/common/testing.h"

namespace lightlink::client {
namespace {

namespace fs = std::filesystem;
using lightlink::testing::CommandResult;
using lightlink::testing::runCommand;
using lightlink::testing::TempDir;

const std::string kCornell = (lightlink::testing::sourceDir() / "clients/demo/cornell_box.gltf").string();
const std::string kDemoDir = (lightlink::testing::sourceDir() / "clients/demo").string();  // the daemons' scene root
constexpr const char* kPreset = "draft";  // the smallest precompute: these tests are about the wire

// OpenScene of the bundled Cornell box at the draft preset.
OpenOptions cornellOpen() {
  OpenOptions o;
  o.path = kCornell;
  o.preset = kPreset;
  o.timeout = std::chrono::seconds(240);
  return o;
}

class ClientDaemon : public ::testing::Test {
 protected:
  void SetUp() override {
    LocalDaemon::Options d;
    d.binary = LIGHTLINK_DAEMON_PATH;
    d.cache_dir = lightlink::testing::clientTestCacheDir();
    d.extra = {"--no-restore", "--scene-root", kDemoDir};  // the shared cache dir records earlier tests' scenes
    auto started = LocalDaemon::start(d);
    ASSERT_TRUE(started) << started.status().toString();
    daemon_ = std::move(started).value();
    ConnectOptions o;
    o.target = daemon_->target();
    o.call_timeout = std::chrono::seconds(60);
    auto c = Client::connect(o);
    ASSERT_TRUE(c) << c.status().toString();
    client_ = std::make_unique<Client>(std::move(c).value());
  }

  SceneHandle open() {
    auto s = client_->openScene(cornellOpen());
    EXPECT_TRUE(s) << s.status().toString() << "\n" << daemon_->log();
    return s ? std::move(s).value() : SceneHandle{};
  }

  std::unique_ptr<LocalDaemon> daemon_;
  std::unique_ptr<Client> client_;
};

LightFields moveTo(const std::string& id, float x, float y, float z) {
  LightFields f;
  f.id = id;
  f.position = Vec3{x, y, z};
  return f;
}

TEST_F(ClientDaemon, RoundTripOpenUpdatePollRelight) {
  auto health = client_->health();
  ASSERT_TRUE(health) << health.status().toString();
  EXPECT_EQ(health->status(), v1::HealthResponse::STATUS_SERVING);
  EXPECT_EQ(health->protocol_version(), 1u);

  SceneHandle scene = open();
  ASSERT_FALSE(scene.id.empty());
  EXPECT_FALSE(scene.token.empty());
  EXPECT_GT(scene.info.lightmap().width(), 0);
  ASSERT_EQ(scene.info.light_ids_size(), 1);
  const std::string light = scene.info.light_ids(0);

  // The initial version's result.
  auto first = client_->relight(scene, scene.info.version());
  ASSERT_TRUE(first) << first.status().toString();
  const ResultInfo& i = first->info;
  EXPECT_GE(i.version, scene.info.version());
  EXPECT_EQ(i.width, scene.info.lightmap().width());
  EXPECT_EQ(i.bands, scene.info.bands());
  EXPECT_EQ(first->bytes(Payload::kLightmapSh).size(), i.texels() * 3 * i.coeffCount() * 2);
  EXPECT_EQ(first->bytes(Payload::kLightmapValid).size(), i.texels());

  // Not modified is one header, no payload.
  auto same = client_->getTextures(scene, i.version);
  ASSERT_TRUE(same) << same.status().toString();
  EXPECT_FALSE(same->has_value());

  // Move the light, wait for the relight, poll: a newer version with different texels.
  LightUpdate u;
  ASSERT_TRUE(u.modify(moveTo(light, 0.15f, 0.45f, 0.3f)));
  auto r = client_->updateLights(scene, u, 30000);
  ASSERT_TRUE(r) << r.status().toString();
  EXPECT_GT(r->version, i.version);
  EXPECT_TRUE(r->relit);
  auto polled = client_->getTextures(scene, i.version);
  ASSERT_TRUE(polled) << polled.status().toString();
  ASSERT_TRUE(polled->has_value());
  const Textures& moved = **polled;
  EXPECT_GE(moved.info.version, r->version);
  EXPECT_NE(moved.floats(Payload::kLightmapSh), first->floats(Payload::kLightmapSh));

  // Float precision carries the same values as half, to half precision.
  ResultSpec spec;
  spec.precision = Precision::kFloat;
  spec.grid = false;
  auto as_float = client_->relight(scene, moved.info.version, spec);
  ASSERT_TRUE(as_float) << as_float.status().toString();
  EXPECT_FALSE(as_float->has(Payload::kGridSh));
  const auto hf = moved.floats(Payload::kLightmapSh), ff = as_float->floats(Payload::kLightmapSh);
  ASSERT_EQ(hf.size(), ff.size());
  for (std::size_t k = 0; k < hf.size(); k += 97)
    ASSERT_NEAR(hf[k], ff[k], 1e-3f * std::max(1.0f, std::abs(ff[k]))) << "value " << k;

  auto scenes = client_->listScenes();
  ASSERT_TRUE(scenes);
  bool listed = false;
  for (const auto& s : *scenes) listed |= s.scene_id() == scene.id;
  EXPECT_TRUE(listed);
  auto stats = client_->stats(&scene);
  ASSERT_TRUE(stats) << stats.status().toString();
  ASSERT_EQ(stats->scene_size(), 1);
  EXPECT_GE(stats->scene(0).updates(), 1u);
  EXPECT_GT(stats->scene(0).resident_bytes(), 0u);

  ASSERT_TRUE(client_->closeScene(scene));
  auto gone = client_->getTextures(scene, 0);
  ASSERT_FALSE(gone);
  EXPECT_EQ(gone.status().code(), Code::kNotFound) << gone.status().toString();
}

TEST_F(ClientDaemon, ErrorsCarryTheGrpcCodeAndTheField) {
  SceneHandle scene = open();
  ASSERT_FALSE(scene.id.empty());
  // A wrong scene token.
  SceneHandle forged = SceneHandle::fromIdToken(scene.id, "not-the-token");
  auto denied = client_->getTextures(forged, 0);
  ASSERT_FALSE(denied);
  EXPECT_NE(denied.status().message().find("PERMISSION_DENIED"), std::string::npos) << denied.status().toString();
  // An unknown scene.
  SceneHandle unknown = SceneHandle::fromIdToken("no-such-scene", "x");
  auto missing = client_->relight(unknown, 0);
  ASSERT_FALSE(missing);
  EXPECT_EQ(missing.status().code(), Code::kNotFound) << missing.status().toString();
  // A NaN the client library would refuse, sent raw to check the daemon's answer arrives
  // with its code and field.
  LightUpdate raw;
  auto* l = raw.proto().add_modify();
  l->set_id(scene.info.light_ids(0));
  l->set_intensity(std::numeric_limits<float>::quiet_NaN());
  auto bad = client_->updateLights(scene, raw);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.status().code(), Code::kInvalidInput);
  EXPECT_NE(bad.status().message().find("INVALID_ARGUMENT"), std::string::npos) << bad.status().toString();
  EXPECT_NE(bad.status().message().find("intensity"), std::string::npos) << bad.status().toString();
  // The daemon still serves.
  EXPECT_TRUE(client_->getTextures(scene, 0));
}

// getTextures with wait_ms: a loop of long polls sees a new version as soon as it exists,
// and an idle scene answers "not modified" after the wait.
TEST_F(ClientDaemon, LongPollGetTextures) {
  SceneHandle scene = open();
  ASSERT_FALSE(scene.id.empty());
  auto first = client_->relight(scene, scene.info.version());
  ASSERT_TRUE(first) << first.status().toString();
  const std::uint64_t seen = first->info.version;
  using Clock = std::chrono::steady_clock;
  auto t0 = Clock::now();
  auto idle = client_->getTextures(scene, seen, {}, 300);
  const double idle_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  ASSERT_TRUE(idle) << idle.status().toString();
  EXPECT_FALSE(idle->has_value());
  EXPECT_GE(idle_ms, 250.0) << "the long poll did not wait";

  // Another thread moves the light while this one waits.
  LightUpdate u;
  ASSERT_TRUE(u.modify(moveTo(scene.info.light_ids(0), 0.2f, 0.4f, 0.25f)));
  std::uint64_t sent = 0;
  std::thread mover([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    auto r = client_->updateLights(scene, u);
    EXPECT_TRUE(r) << r.status().toString();
    if (r) sent = r->version;
  });
  t0 = Clock::now();
  auto fresh = client_->getTextures(scene, seen, {}, 30000);
  const double fresh_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  mover.join();
  ASSERT_TRUE(fresh) << fresh.status().toString();
  ASSERT_TRUE(fresh->has_value());
  EXPECT_EQ((*fresh)->info.version, sent);
  EXPECT_FALSE((*fresh)->info.preview);
  EXPECT_LT(fresh_ms, 15000.0) << "answered when the version existed, not at the end of the wait";

  auto absurd = client_->getTextures(scene, sent, {}, 60001);
  ASSERT_FALSE(absurd);
  EXPECT_EQ(absurd.status().code(), Code::kInvalidInput) << absurd.status().toString();
  EXPECT_NE(absurd.status().message().find("wait_ms"), std::string::npos) << absurd.status().toString();
}

// Shared-memory delivery (docs/service.md): a client on the daemon's machine that asks for it
// gets the same bytes from the daemon's file as another gets on the stream; a file that is
// gone is asked for again on the stream; the daemon removes a closed scene's files and its
// directory when it exits; --no-shared-memory answers on the stream.
TEST(ClientSharedMemory, SameResultAsTheStreamFallbackAndCleanup) {
  TempDir shm;
  LocalDaemon::Options d;
  d.binary = LIGHTLINK_DAEMON_PATH;
  d.cache_dir = lightlink::testing::clientTestCacheDir();
  d.extra = {"--no-restore", "--scene-root", kDemoDir, "--shared-memory-dir", shm.path().string()};
  auto started = LocalDaemon::start(d);
  ASSERT_TRUE(started) << started.status().toString();
  auto daemon = std::move(started).value();
  ConnectOptions o;
  o.target = daemon->target();
  o.call_timeout = std::chrono::seconds(60);
  auto plain = Client::connect(o);
  o.shared_memory = true;
  auto shared = Client::connect(o);
  ASSERT_TRUE(plain && shared);
  const OpenOptions open = cornellOpen();
  auto scene = plain->openScene(open);
  ASSERT_TRUE(scene) << scene.status().toString() << "\n" << daemon->log();

  auto streamed = plain->relight(*scene, scene->info.version());
  auto from_file = shared->relight(*scene, scene->info.version());
  ASSERT_TRUE(streamed && from_file) << daemon->log();
  EXPECT_FALSE(streamed->info.shared);
  EXPECT_TRUE(from_file->info.shared) << daemon->log();
  EXPECT_EQ(from_file->info.version, streamed->info.version);
  EXPECT_EQ(from_file->payloads, streamed->payloads);
  EXPECT_TRUE(from_file->has(Payload::kLightmapSh));
  EXPECT_TRUE(from_file->has(Payload::kGridSh));

  // The daemon's directory under the base holds the file; a poll with the same spec reuses it.
  std::vector<fs::path> dirs;
  for (const auto& e : fs::directory_iterator(shm.path())) dirs.push_back(e.path());
  ASSERT_EQ(dirs.size(), 1u);
  EXPECT_EQ(dirs[0].filename().string().rfind("lightlinkd-" + std::to_string(daemon->pid()) + "-", 0), 0u);
  auto polled = shared->getTextures(*scene, 0);
  ASSERT_TRUE(polled && polled->has_value());
  EXPECT_TRUE((*polled)->info.shared);
  EXPECT_EQ((*polled)->payloads, streamed->payloads);
  std::size_t files = 0;
  std::uint64_t bytes = 0;
  for (const auto& e : fs::directory_iterator(dirs[0])) {
    files += e.is_regular_file() ? 1 : 0;
    bytes += e.is_regular_file() ? e.file_size() : 0;
  }
  EXPECT_EQ(files, 1u);
  auto stats = plain->stats();
  ASSERT_TRUE(stats) << stats.status().toString();
  EXPECT_EQ(stats->shared_memory_files(), 1u);
  EXPECT_EQ(stats->shared_memory_bytes(), bytes);
  EXPECT_GT(bytes, from_file->totalBytes()) << "the payloads and their chunk framing";

  // Files gone (as if removed under a slow client): the same poll on the stream, same bytes.
  for (const auto& e : fs::directory_iterator(dirs[0])) fs::remove(e.path());
  auto fallback = shared->getTextures(*scene, 0);
  ASSERT_TRUE(fallback) << fallback.status().toString();
  ASSERT_TRUE(fallback->has_value());
  EXPECT_FALSE((*fallback)->info.shared);
  EXPECT_EQ((*fallback)->payloads, streamed->payloads);
  auto relit = shared->relight(*scene, 0);
  ASSERT_TRUE(relit) << relit.status().toString();
  EXPECT_FALSE(relit->info.shared);
  EXPECT_EQ(relit->payloads, streamed->payloads);

  // A new result gets a new file; closing the scene removes it; SIGTERM removes the directory.
  LightUpdate u;
  ASSERT_TRUE(u.modify(moveTo(scene->info.light_ids(0), 0.2f, 0.4f, 0.3f)));
  auto r = plain->updateLights(*scene, u, 30000);
  ASSERT_TRUE(r && r->relit);
  auto moved = shared->getTextures(*scene, streamed->info.version);
  ASSERT_TRUE(moved && moved->has_value());
  EXPECT_TRUE((*moved)->info.shared);
  EXPECT_NE((*moved)->payloads, streamed->payloads);
  EXPECT_FALSE(fs::is_empty(dirs[0]));
  ASSERT_TRUE(plain->closeScene(*scene));
  EXPECT_TRUE(fs::is_empty(dirs[0]));
  EXPECT_EQ(daemon->stop(), 0) << daemon->log();
  EXPECT_FALSE(fs::exists(dirs[0]));

  // Delivery off: the flag is ignored, the stream carries the result.
  d.extra = {"--no-restore", "--scene-root", kDemoDir, "--no-shared-memory"};
  auto off = LocalDaemon::start(d);
  ASSERT_TRUE(off) << off.status().toString();
  o.target = (*off)->target();
  auto client = Client::connect(o);
  ASSERT_TRUE(client);
  auto again = client->openScene(open);
  ASSERT_TRUE(again) << again.status().toString();
  auto plain_result = client->relight(*again, again->info.version());
  ASSERT_TRUE(plain_result) << plain_result.status().toString();
  EXPECT_FALSE(plain_result->info.shared);
  EXPECT_EQ(plain_result->payloads, streamed->payloads) << "the same scene and lights";
}

// Subscribe with tile deltas: after applying every delta, the stream's local copy equals a
// full fetch of the same version, byte for byte.
TEST_F(ClientDaemon, SubscribeDeltasRebuildTheFullResult) {
  SceneHandle scene = open();
  ASSERT_FALSE(scene.id.empty());
  const std::string light = scene.info.light_ids(0);
  auto sub = client_->subscribe(scene, {}, /*deltas=*/true);
  ASSERT_TRUE(sub) << sub.status().toString();
  auto first = (*sub)->next();
  ASSERT_TRUE(first) << first.status().toString();
  ASSERT_NE(*first, nullptr);
  std::uint64_t last = (*first)->info.version;
  const float xs[] = {0.1f, 0.3f, 0.45f};
  std::uint64_t final_version = 0;
  for (float x : xs) {
    LightUpdate u;
    ASSERT_TRUE(u.modify(moveTo(light, x, 0.45f, 0.3f)));
    auto r = client_->updateLights(scene, u, 30000);
    ASSERT_TRUE(r && r->relit) << (r ? "not relit" : r.status().toString());
    final_version = r->version;
  }
  // Read until the stream reaches the last version (a slow reader may skip some).
  const Textures* t = nullptr;
  while (last < final_version) {
    auto n = (*sub)->next();
    ASSERT_TRUE(n) << n.status().toString();
    ASSERT_NE(*n, nullptr) << "stream ended early";
    t = *n;
    ASSERT_GT(t->info.version, last) << "versions must increase";
    last = t->info.version;
  }
  ASSERT_NE(t, nullptr);
  EXPECT_TRUE(t->info.delta) << "after the first result a delta stream sends deltas";
  auto full = client_->relight(scene, last);
  ASSERT_TRUE(full) << full.status().toString();
  ASSERT_EQ(full->info.version, last);
  for (Payload p : {Payload::kLightmapSh, Payload::kLightmapDirect, Payload::kLightmapValid, Payload::kGridSh}) {
    const auto a = t->bytes(p), b = full->bytes(p);
    ASSERT_EQ(a.size(), b.size()) << payloadName(p);
    EXPECT_TRUE(std::equal(a.begin(), a.end(), b.begin())) << payloadName(p) << " differs after deltas";
  }
  (*sub)->cancel();
}

// ---- the CLI against the daemon

std::string cli() { return LIGHTLINK_CLI_PATH; }

TEST_F(ClientDaemon, CliOpenSetLightPullWatch) {
  TempDir tmp;
  const std::string session = (tmp / "session.json").string();
  auto opened = runCommand({cli(), "open", kCornell, "--preset", kPreset, "--target", daemon_->target(), "--session",
                            session, "--timeout", "0"},
                           std::chrono::seconds(240));
  ASSERT_EQ(opened.exit_code, 0) << opened.err << daemon_->log();
  const auto info = nlohmann::json::parse(opened.out, nullptr, false);
  ASSERT_FALSE(info.is_discarded()) << opened.out;
  ASSERT_TRUE(info.contains("scene_id")) << opened.out;
  ASSERT_TRUE(fs::exists(session));
  const std::string light = info["light_ids"][0].get<std::string>();

  auto set = runCommand({cli(), "set-light", light, "--session", session, "--position", "0.2,0.4,0.3", "--intensity",
                         "0.8", "--wait", "--json-output"},
                        std::chrono::seconds(60));
  ASSERT_EQ(set.exit_code, 0) << set.err;
  const auto s = nlohmann::json::parse(set.out, nullptr, false);
  ASSERT_FALSE(s.is_discarded()) << set.out;
  EXPECT_TRUE(s["relit"].get<bool>());
  EXPECT_GT(s["latency_ms"].get<double>(), 0.0);
  const std::uint64_t version = s["version"].get<std::uint64_t>();

  // A bad value is refused with the field named and exit code 2.
  auto bad = runCommand({cli(), "set-light", light, "--session", session, "--intensity", "-3"}, std::chrono::seconds(30));
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
  EXPECT_NE(bad.err.find("intensity: -3 is negative"), std::string::npos) << bad.err;

  // A light-set file through --json.
  const std::string lights =
      lightlink::testing::writeFile(tmp / "lights.json", R"({"version": 1, "lights": [{"id": ")" + light +
                                                             R"(", "color": [1, 1, 1]}]})");
  auto from_json = runCommand({cli(), "set-light", "--json", lights, "--session", session, "--wait"},
                              std::chrono::seconds(60));
  ASSERT_EQ(from_json.exit_code, 0) << from_json.err;
  EXPECT_NE(from_json.out.find("light change to texture"), std::string::npos) << from_json.out;

  const fs::path out = tmp / "pull";
  auto pull = runCommand({cli(), "pull", "--session", session, "-o", out.string(), "--version", std::to_string(version)},
                         std::chrono::seconds(60));
  ASSERT_EQ(pull.exit_code, 0) << pull.err;
  for (const char* f : {"irradiance.exr", "lightmap_L00.exr", "lightmap.png", "pull.json"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  // What pull wrote is what the viewer (and an engine) reads.
  auto baked = viewer::loadBakedLighting(out.string());
  ASSERT_TRUE(baked) << baked.status().toString();
  EXPECT_EQ(baked->width, info["lightmap"]["width"].get<int>());

  auto watch = runCommand({cli(), "watch", "--session", session, "--count", "1", "--json"}, std::chrono::seconds(60));
  ASSERT_EQ(watch.exit_code, 0) << watch.err;
  const auto w = nlohmann::json::parse(watch.out.substr(0, watch.out.find('\n')), nullptr, false);
  ASSERT_FALSE(w.is_discarded()) << watch.out;
  EXPECT_GE(w["version"].get<std::uint64_t>(), version);

  // No daemon there: exit code 3 (I/O), not a hang.
  auto nobody = runCommand({cli(), "pull", "--target", "127.0.0.1:1", "--scene", "x", "--scene-token", "y", "-o",
                            out.string(), "--timeout", "1000"},
                           std::chrono::seconds(30));
  EXPECT_EQ(nobody.exit_code, 3) << nobody.err;
}

// `lightlink serve` is the daemon in-process: same flags, clean exit on SIGTERM.
TEST(ClientServe, RunsTheDaemonInProcessAndDrainsOnSigterm) {
  TempDir cache;
  LocalDaemon::Options d;
  d.binary = LIGHTLINK_CLI_PATH;
  d.prefix = {"serve"};
  d.cache_dir = cache.path();
  d.extra = {"--no-restore", "--scene-root", kDemoDir};
  auto daemon = LocalDaemon::start(d);
  ASSERT_TRUE(daemon) << daemon.status().toString();
  ConnectOptions o;
  o.target = (*daemon)->target();
  auto c = Client::connect(o);
  ASSERT_TRUE(c) << c.status().toString();
  auto health = c->health();
  ASSERT_TRUE(health) << health.status().toString();
  EXPECT_EQ(health->status(), v1::HealthResponse::STATUS_SERVING);
  EXPECT_EQ((*daemon)->stop(), 0) << (*daemon)->log();
}

// A daemon with a bearer token refuses calls without it (UNAUTHENTICATED, mapped to
// kInvalidInput with the code in the message) and serves calls that carry it.
TEST(ClientAuth, BearerTokenOnEveryCall) {
  TempDir cache;
  LocalDaemon::Options d;
  d.binary = LIGHTLINK_DAEMON_PATH;
  d.cache_dir = cache.path();
  d.extra = {"--no-restore", "--scene-root", kDemoDir, "--token-file", lightlink::testing::writeFile(cache.path() / "token", "s3cret-token-0123456789\n")};
  auto daemon = LocalDaemon::start(d);
  ASSERT_TRUE(daemon) << daemon.status().toString();
  ConnectOptions o;
  o.target = (*daemon)->target();
  auto anonymous = Client::connect(o);
  ASSERT_TRUE(anonymous) << anonymous.status().toString();
  auto refused = anonymous->health();
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.status().code(), Code::kInvalidInput);
  EXPECT_NE(refused.status().message().find("UNAUTHENTICATED"), std::string::npos) << refused.status().toString();
  o.bearer_token = "wrong";
  auto wrong = Client::connect(o);
  ASSERT_TRUE(wrong);
  EXPECT_FALSE(wrong->health());
  o.bearer_token = "s3cret-token-0123456789";
  auto good = Client::connect(o);
  ASSERT_TRUE(good);
  auto health = good->health();
  EXPECT_TRUE(health) << health.status().toString();
}

// TLS: the client trusts the daemon's certificate through `tls_root_cert`; a plaintext
// client cannot talk to a TLS daemon.
TEST(ClientTls, RootCertificateConnects) {
  if (runCommand({"/usr/bin/openssl", "version"}, std::chrono::seconds(10)).exit_code != 0)
    GTEST_SKIP() << "/usr/bin/openssl is not installed: no certificate to test with";
  TempDir tmp;
  const std::string cert = (tmp / "cert.pem").string(), key = (tmp / "key.pem").string();
  auto gen = runCommand({"/usr/bin/openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", key, "-out",
                         cert, "-days", "1", "-subj", "/CN=localhost", "-addext",
                         "subjectAltName=DNS:localhost,IP:127.0.0.1"},
                        std::chrono::seconds(60));
  ASSERT_EQ(gen.exit_code, 0) << gen.err;
  LocalDaemon::Options d;
  d.binary = LIGHTLINK_DAEMON_PATH;
  d.cache_dir = tmp / "cache";
  d.extra = {"--no-restore", "--scene-root", kDemoDir, "--tls-cert", cert, "--tls-key", key};
  auto daemon = LocalDaemon::start(d);
  ASSERT_TRUE(daemon) << daemon.status().toString();
  ConnectOptions o;
  o.target = (*daemon)->target();
  o.tls_root_cert = cert;
  o.tls_server_name = "localhost";
  auto tls = Client::connect(o);
  ASSERT_TRUE(tls) << tls.status().toString() << (*daemon)->log();
  auto health = tls->health();
  EXPECT_TRUE(health) << health.status().toString();
  ConnectOptions plain;
  plain.target = (*daemon)->target();
  plain.connect_timeout = std::chrono::milliseconds(1000);
  auto p = Client::connect(plain);
  EXPECT_TRUE(!p || !p->health()) << "a plaintext client must not get an answer from a TLS daemon";
  ConnectOptions missing = o;
  missing.tls_root_cert = (tmp / "nope.pem").string();
  auto m = Client::connect(missing);
  ASSERT_FALSE(m);
  EXPECT_EQ(m.status().code(), Code::kNotFound);
}

// The example game client polls, renders the first version it gets and writes the frame.
TEST_F(ClientDaemon, GameClientRendersAFrame) {
  TempDir tmp;
  SceneHandle scene = open();
  ASSERT_FALSE(scene.id.empty());
  client::Session s{daemon_->target(), scene};
  const std::string session = (tmp / "session.json").string();
  ASSERT_TRUE(saveSession(session, s));
  auto r = runCommand({LIGHTLINK_GAME_CLIENT_PATH, "--session", session, "--preset", kPreset, "--frames", "1",
                       "--width", "64", "--height", "48", "-o", (tmp / "frames").string()},
                      std::chrono::seconds(120));
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_TRUE(fs::exists(tmp / "frames" / "frame_0000.png")) << r.out;
  EXPECT_NE(r.out.find("poll"), std::string::npos) << r.out;
  // Long polling (--wait-ms): each new version is rendered as it appears; a mover thread
  // keeps changing the light until the client has its two frames (bounded by --duration).
  std::atomic<bool> done{false};
  std::thread mover([&] {
    for (int k = 0; !done.load(); ++k) {
      LightUpdate u;
      if (!u.modify(moveTo(scene.info.light_ids(0), 0.2f + 0.01f * float(k % 10), 0.4f, 0.3f))) return;
      (void)client_->updateLights(scene, u);
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
    }
  });
  // Long polls, results through shared memory (the fixture's daemon keeps its default base,
  // /dev/shm, where the machine has one).
  auto waited = runCommand({LIGHTLINK_GAME_CLIENT_PATH, "--session", session, "--preset", kPreset, "--frames", "2",
                            "--wait-ms", "5000", "--duration", "60", "--width", "32", "--height", "24",
                            "--shared-memory", "-o", (tmp / "waited").string()},
                           std::chrono::seconds(120));
  done = true;
  mover.join();
  ASSERT_EQ(waited.exit_code, 0) << waited.out << waited.err;
  EXPECT_TRUE(fs::exists(tmp / "waited" / "frame_0001.png")) << waited.out;
  EXPECT_EQ(waited.out.find("through shared memory") != std::string::npos, fs::is_directory("/dev/shm")) << waited.out;
  // A preset whose atlas differs from the daemon's is refused, not rendered with wrong UVs.
  auto wrong = runCommand({LIGHTLINK_GAME_CLIENT_PATH, "--session", session, "--preset", "high", "--frames", "1",
                           "-o", (tmp / "frames").string()},
                          std::chrono::seconds(120));
  EXPECT_EQ(wrong.exit_code, 2) << wrong.out << wrong.err;
  EXPECT_NE(wrong.err.find("--preset"), std::string::npos) << wrong.err;
}

// ---- reading a scene back: the library and the CLI

TEST_F(ClientDaemon, LightsAndLightmapUvsReadBackThroughTheLibraryAndTheCli) {
  SceneHandle scene = open();
  ASSERT_FALSE(scene.id.empty());
  const std::string light = scene.info.light_ids(0);
  LightUpdate u;
  ASSERT_TRUE(u.modify(moveTo(light, 0.2f, 0.4f, 0.25f)));
  auto r = client_->updateLights(scene, u);
  ASSERT_TRUE(r) << r.status().toString();
  auto lights = client_->getLights(scene);
  ASSERT_TRUE(lights) << lights.status().toString();
  EXPECT_EQ(lights->version, r->version);
  ASSERT_EQ(lights->lights.size(), 1u);
  EXPECT_EQ(lights->lights[0].id(), light);
  EXPECT_FLOAT_EQ(lights->lights[0].position().z(), 0.25f);
  // The document converts back into an update through the one light-set reader.
  auto again = LightUpdate::fromLightSetText(lights->json, &scene.light_ids);
  ASSERT_TRUE(again) << again.status().toString() << "\n" << lights->json;

  auto uvs = client_->getLightmapUvs(scene, true);
  ASSERT_TRUE(uvs) << uvs.status().toString();
  EXPECT_EQ(uvs->width, scene.info.lightmap().width());
  EXPECT_TRUE(uvs->generated);
  std::size_t lit = 0;
  for (const MeshUvs& m : uvs->meshes) {
    if (!m.lightmapped) continue;
    ++lit;
    EXPECT_EQ(m.source_vertex.size() * 2, m.uv.size()) << m.name;
    EXPECT_EQ(m.indices.size() % 3, 0u);
  }
  EXPECT_GT(lit, 0u);
  EXPECT_EQ(uvs->glb.substr(0, 4), "glTF");

  // The CLI prints the same document and writes the same .glb.
  TempDir tmp;
  const std::string session = (tmp / "s.json").string();
  ASSERT_TRUE(saveSession(session, Session{daemon_->target(), scene}));
  auto printed = runCommand({LIGHTLINK_CLI_PATH, "lights", "--session", session}, std::chrono::seconds(60));
  ASSERT_EQ(printed.exit_code, 0) << printed.out << printed.err;
  EXPECT_EQ(nlohmann::json::parse(printed.out), nlohmann::json::parse(lights->json));
  const std::string glb = (tmp / "lm.glb").string(), json = (tmp / "uvs.json").string();
  auto wrote = runCommand({LIGHTLINK_CLI_PATH, "uvs", "--session", session, "--gltf", glb, "--json", json},
                          std::chrono::seconds(60));
  ASSERT_EQ(wrote.exit_code, 0) << wrote.out << wrote.err;
  std::ifstream glb_in(glb, std::ios::binary);
  const std::string glb_bytes((std::istreambuf_iterator<char>(glb_in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(glb_bytes, uvs->glb);
  std::ifstream json_in(json);
  const auto doc = nlohmann::json::parse(json_in, nullptr, false);
  ASSERT_FALSE(doc.is_discarded());
  ASSERT_EQ(doc["meshes"].size(), uvs->meshes.size());
  EXPECT_EQ(doc["meshes"][0]["uv"].get<std::vector<float>>(), uvs->meshes[0].uv);
}

// ---- the Python example on the `lightlink` package (Debian's python3-grpcio, -protobuf, -numpy)

TEST_F(ClientDaemon, PythonExampleMovesALightAndSavesTheLightmap) {
  const std::string python = "/usr/bin/python3";
  auto probe = runCommand({python, "-c", "import grpc, google.protobuf, numpy"}, std::chrono::seconds(30));
  if (probe.exit_code != 0)
    GTEST_SKIP() << "Debian's python3-grpcio / python3-protobuf / python3-numpy are not installed "
                    "(scripts/packages.txt): "
                 << probe.err;
  TempDir tmp;
  const std::string session = (tmp / "session.json").string();
  auto r = runCommand({python, (lightlink::testing::sourceDir() / "clients/python/move_light.py").string(),
                       "--target", daemon_->target(), "--scene", kCornell, "--preset", kPreset, "--out",
                       tmp.path().string(), "--timeout", "200", "--session", session},
                      std::chrono::seconds(240), {"PYTHONPATH=" LIGHTLINK_PYTHON_PACKAGE});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err << daemon_->log();
  std::ifstream meta_in(tmp / "lightmap.json");
  const auto meta = nlohmann::json::parse(meta_in, nullptr, false);
  ASSERT_FALSE(meta.is_discarded());
  const int w = meta["width"], h = meta["height"], bands = meta["bands"];
  EXPECT_EQ(fs::file_size(tmp / "lightmap_sh.f32"), std::uintmax_t(w) * h * 3 * bands * bands * 4);
  EXPECT_EQ(fs::file_size(tmp / "valid.u8"), std::uintmax_t(w) * h);
  std::ifstream png(tmp / "lightmap.png", std::ios::binary);
  char sig[8] = {};
  png.read(sig, 8);
  EXPECT_EQ(std::string(sig + 1, 3), "PNG");
  EXPECT_EQ(meta["position"][0].get<double>(), 0.15);  // the example's default move
  EXPECT_NE(r.out.find("light change to texture"), std::string::npos) << r.out;

  // numpy's decode is the C++ client's: the same version fetched through the session file the
  // script wrote (the handle `lightlink pull --session` reads) gives the same floats, bit for bit.
  auto loaded = loadSession(session);
  ASSERT_TRUE(loaded) << loaded.status().toString();
  EXPECT_EQ(loaded->scene.id, meta["scene_id"].get<std::string>());
  ResultSpec spec;
  spec.grid = false;
  auto tex = client_->relight(loaded->scene, meta["version"].get<std::uint64_t>(), spec);
  ASSERT_TRUE(tex) << tex.status().toString();
  ASSERT_EQ(tex->info.version, meta["version"].get<std::uint64_t>());
  const auto readFloats = [&](const char* name) {
    std::ifstream in(tmp / name, std::ios::binary);
    std::vector<float> v(fs::file_size(tmp / name) / 4);
    in.read(reinterpret_cast<char*>(v.data()), std::streamsize(v.size() * 4));
    return v;
  };
  const std::vector<float> sh = readFloats("lightmap_sh.f32"), cpp_sh = tex->floats(Payload::kLightmapSh);
  ASSERT_EQ(sh.size(), cpp_sh.size());
  EXPECT_EQ(std::memcmp(sh.data(), cpp_sh.data(), sh.size() * 4), 0) << "numpy's half decode differs from C++'s";
  if (tex->has(Payload::kLightmapDirect)) {
    const std::vector<float> direct = readFloats("direct.f32"), cpp_direct = tex->floats(Payload::kLightmapDirect);
    ASSERT_EQ(direct.size(), cpp_direct.size());
    EXPECT_EQ(std::memcmp(direct.data(), cpp_direct.data(), direct.size() * 4), 0);
  }
  std::ifstream valid_in(tmp / "valid.u8", std::ios::binary);
  const std::string valid((std::istreambuf_iterator<char>(valid_in)), std::istreambuf_iterator<char>());
  const auto cpp_valid = tex->bytes(Payload::kLightmapValid);
  ASSERT_EQ(valid.size(), cpp_valid.size());
  EXPECT_EQ(std::memcmp(valid.data(), cpp_valid.data(), valid.size()), 0);
}

}  // namespace
}  // namespace lightlink::client
