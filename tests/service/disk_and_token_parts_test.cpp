// In process: the daemon's token rules (sources, length, TLS beyond loopback), failed-auth
// rate limiting, the cache quota's LRU eviction and private, never-blocking cache files.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/artifact/artifact.h"
#include "core/common/private_files.h"
#include "service/auth_limiter.h"
#include "service/cache_quota.h"
#include "service/config.h"
#include "service/session_store.h"
#include "tests/common/testing.h"

namespace lightlink::service {
namespace {

namespace fs = std::filesystem;
using lightlink::testing::TempDir;
using lightlink::testing::writeFile;

ParsedArgs parse(std::vector<std::string> args) {
  args.insert(args.begin(), "lightlinkd");
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  return parseArgs(static_cast<int>(argv.size()), argv.data());
}

unsigned modeOf(const fs::path& p) {
  struct stat st {};
  if (::lstat(p.c_str(), &st) != 0) return 0xffff;
  return st.st_mode & 07777;
}

// Sets the umask for a scope (0: nothing masked, so only explicit modes keep files private).
struct Umask {
  explicit Umask(mode_t m) : old(::umask(m)) {}
  ~Umask() { ::umask(old); }
  mode_t old;
};

TEST(ServiceConfig, SessionIdleTimeoutFromTheFlagAndTheConfigFile) {
  EXPECT_EQ(parse({"--cache-dir", "/tmp/x"}).config.session_idle_timeout_s, 1800.0) << "default: 30 minutes";
  const ParsedArgs flag = parse({"--cache-dir", "/tmp/x", "--session-idle-timeout", "90"});
  ASSERT_FALSE(flag.exit_now) << flag.output;
  EXPECT_EQ(flag.config.session_idle_timeout_s, 90.0);
  EXPECT_EQ(parse({"--cache-dir", "/tmp/x", "--session-idle-timeout", "0"}).config.session_idle_timeout_s, 0.0);
  TempDir tmp;
  writeFile(tmp / "c.json", R"({"cache_dir": "/tmp/x", "session_idle_timeout": 12.5})");
  const ParsedArgs file = parse({"--config", (tmp / "c.json").string()});
  ASSERT_FALSE(file.exit_now) << file.output;
  EXPECT_EQ(file.config.session_idle_timeout_s, 12.5);
  writeFile(tmp / "bad.json", R"({"cache_dir": "/tmp/x", "session_idle_timeout": "soon"})");
  const ParsedArgs bad = parse({"--config", (tmp / "bad.json").string()});
  ASSERT_TRUE(bad.exit_now);
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.output.find("session_idle_timeout"), std::string::npos) << bad.output;
  const ParsedArgs negative = parse({"--cache-dir", "/tmp/x", "--session-idle-timeout", "-1"});
  ASSERT_TRUE(negative.exit_now);
  EXPECT_NE(negative.output.find("--session-idle-timeout"), std::string::npos) << negative.output;
}

TEST(ServiceTokens, TokenInArgvIsRefusedNamingTheAlternatives) {
  const ParsedArgs p = parse({"--cache-dir", "/tmp/x", "--token", "0123456789abcdef0123"});
  ASSERT_TRUE(p.exit_now);
  EXPECT_EQ(p.exit_code, 2);
  EXPECT_NE(p.output.find("--token-file"), std::string::npos) << p.output;
  EXPECT_NE(p.output.find("LIGHTLINKD_TOKEN"), std::string::npos) << p.output;
}

TEST(ServiceTokens, FileAndEnvironmentAreTheSources) {
  TempDir tmp;
  const std::string file = writeFile(tmp / "token", "0123456789abcdef-from-file\n");
  ParsedArgs p = parse({"--cache-dir", "/tmp/x", "--token-file", file});
  ASSERT_FALSE(p.exit_now) << p.output;
  EXPECT_EQ(p.config.token, "0123456789abcdef-from-file");
  ::setenv(kTokenEnvVar, "0123456789abcdef-from-env", 1);
  p = parse({"--cache-dir", "/tmp/x"});
  ASSERT_FALSE(p.exit_now) << p.output;
  EXPECT_EQ(p.config.token, "0123456789abcdef-from-env");
  p = parse({"--cache-dir", "/tmp/x", "--token-file", file});
  EXPECT_EQ(p.config.token, "0123456789abcdef-from-file") << "a file given explicitly wins over the environment";
  ::unsetenv(kTokenEnvVar);
}

TEST(ServiceTokens, ShortTokenIsRefused) {
  TempDir tmp;
  const ParsedArgs p = parse({"--cache-dir", "/tmp/x", "--token-file", writeFile(tmp / "token", "x\n")});
  ASSERT_TRUE(p.exit_now);
  EXPECT_EQ(p.exit_code, 2);
  EXPECT_NE(p.output.find("too short"), std::string::npos) << p.output;
  DaemonConfig c;
  c.cache_dir = "/tmp/x";
  c.token = std::string(kMinTokenLength - 1, 'a');
  EXPECT_FALSE(c.validate());
  c.token = std::string(kMinTokenLength, 'a');
  EXPECT_TRUE(c.validate());
}

TEST(ServiceTokens, TokenBeyondLoopbackNeedsTlsUnlessAllowed) {
  DaemonConfig c;
  c.cache_dir = "/tmp/x";
  c.listen = "0.0.0.0:50051";
  c.token = std::string(32, 'a');
  const Status plain = c.validate();
  ASSERT_FALSE(plain);
  EXPECT_NE(plain.message().find("--allow-plaintext-token"), std::string::npos) << plain.message();
  c.allow_plaintext_token = true;
  EXPECT_TRUE(c.validate());
  c.allow_plaintext_token = false;
  c.tls_cert = "cert.pem";
  c.tls_key = "key.pem";
  EXPECT_TRUE(c.validate());
  c = DaemonConfig{};
  c.cache_dir = "/tmp/x";
  c.token = std::string(32, 'a');
  EXPECT_TRUE(c.validate()) << "loopback: plaintext is fine";
}

TEST(ServiceTokens, FailedAuthIsRateLimitedPerAddress) {
  AuthFailureLimiter::Limits limits;
  limits.max_failures = 3;
  limits.window = std::chrono::seconds(10);
  limits.backoff = std::chrono::seconds(30);
  AuthFailureLimiter l(limits);
  const auto t0 = AuthFailureLimiter::Clock::now();
  EXPECT_FALSE(l.recordFailure("10.0.0.5", t0));
  EXPECT_FALSE(l.recordFailure("10.0.0.5", t0));
  EXPECT_EQ(l.blockedFor("10.0.0.5", t0), AuthFailureLimiter::Clock::duration::zero());
  EXPECT_TRUE(l.recordFailure("10.0.0.5", t0)) << "the third failure starts the block (logged once)";
  EXPECT_GT(l.blockedFor("10.0.0.5", t0 + std::chrono::seconds(29)), AuthFailureLimiter::Clock::duration::zero());
  EXPECT_EQ(l.blockedFor("10.0.0.6", t0), AuthFailureLimiter::Clock::duration::zero()) << "other addresses unaffected";
  EXPECT_EQ(l.blockedFor("10.0.0.5", t0 + std::chrono::seconds(31)), AuthFailureLimiter::Clock::duration::zero());
  // Failures spread beyond the window never add up to a block.
  for (int i = 0; i < 10; ++i) EXPECT_FALSE(l.recordFailure("10.0.0.7", t0 + std::chrono::seconds(11 * i)));
  EXPECT_EQ(peerAddress("ipv4:10.1.2.3:5555"), "10.1.2.3");
  EXPECT_EQ(peerAddress("ipv6:[::1]:5555"), "::1");
  EXPECT_EQ(peerAddress("unix:/tmp/sock"), "unix");
}

// Sets a file's last use `age_s` seconds in the past.
void age(const fs::path& p, int age_s) {
  const auto t = fs::file_time_type::clock::now() - std::chrono::seconds(age_s);
  fs::last_write_time(p, t);
}

TEST(CacheQuota, EvictsClosedScenesLeastRecentlyUsedFirstAndKeepsResidentOnes) {
  TempDir tmp;
  const fs::path cache = tmp / "cache";
  fs::create_directories(cache / "inline");
  const std::string kb(1000, 'x');
  const auto oldest = writeFile(cache / "aaaa.llk", kb), resident = writeFile(cache / "bbbb.llk", kb),
             middle = writeFile(cache / "inline" / "cccc.gltf", kb), newest = writeFile(cache / "dddd.llk", kb);
  const auto sessions = writeFile(cache / "sessions.json", kb), temp = writeFile(cache / ".eeee.llk.tmp.1.0", kb);
  age(oldest, 400);
  age(resident, 500);  // the oldest of all, but resident
  age(middle, 300);
  age(newest, 100);
  ASSERT_EQ(::mkfifo((cache / "ffff.llk").c_str(), 0600), 0);
  // 4000 evictable bytes; quota 2500 with 500 incoming: two files must go, oldest first.
  const EvictionReport r = enforceCacheQuota(cache.string(), 2500, 500, {resident});
  EXPECT_EQ(r.files_removed, 2);
  EXPECT_FALSE(fs::exists(oldest));
  EXPECT_FALSE(fs::exists(middle));
  EXPECT_TRUE(fs::exists(resident));
  EXPECT_TRUE(fs::exists(newest));
  EXPECT_TRUE(fs::exists(sessions) && fs::exists(temp)) << "only artifacts and inline scenes are evictable";
  EXPECT_TRUE(fs::is_fifo(cache / "ffff.llk")) << "a non-regular file is neither counted nor removed";
  EXPECT_EQ(r.bytes_after, 2000u);
  // Within the quota: nothing happens; no quota: nothing happens.
  EXPECT_EQ(enforceCacheQuota(cache.string(), 2500, 0, {resident}).files_removed, 0);
  EXPECT_EQ(enforceCacheQuota(cache.string(), 0, 1u << 30, {}).files_removed, 0);
  // Resident files stay even when the quota cannot be met.
  const EvictionReport over = enforceCacheQuota(cache.string(), 1, 0, {resident});
  EXPECT_TRUE(fs::exists(resident));
  EXPECT_FALSE(fs::exists(newest));
  EXPECT_EQ(over.bytes_after, 1000u);
}

TEST(CacheQuota, QuotaFlagTakesSizeSuffixes) {
  ParsedArgs p = parse({"--cache-dir", "/tmp/x", "--cache-quota", "2GiB"});
  ASSERT_FALSE(p.exit_now) << p.output;
  EXPECT_EQ(p.config.cache_quota, 2ull << 30);
  p = parse({"--cache-dir", "/tmp/x"});
  EXPECT_EQ(p.config.cache_quota, 10ull << 30);
}

TEST(PrivateFiles, CacheFilesAndDirectoriesArePrivateWhateverTheUmask) {
  TempDir tmp;
  Umask open_umask(0);
  const fs::path dir = tmp / "a" / "b";
  ASSERT_TRUE(createPrivateDirectories(dir.string()));
  EXPECT_EQ(modeOf(tmp / "a"), 0700u);
  EXPECT_EQ(modeOf(dir), 0700u);
  ASSERT_TRUE(writeFileAtomic((dir / "f.json").string(), "{}"));
  EXPECT_EQ(modeOf(dir / "f.json"), 0600u);
  artifact::Writer w(42);
  ASSERT_TRUE(w.addString("x", "payload"));
  ASSERT_TRUE(w.write((dir / "k.llk").string()));
  EXPECT_EQ(modeOf(dir / "k.llk"), 0600u);
}

TEST(PrivateFiles, AFifoNamedLikeAnArtifactIsRefusedWithoutBlocking) {
  TempDir tmp;
  const fs::path fifo = tmp / "0123456789abcdef.llk";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // A plain open of a FIFO without a writer blocks forever; this must return at once.
  const auto opened = artifact::Artifact::open(fifo.string());
  ASSERT_FALSE(opened);
  EXPECT_NE(opened.status().message().find("FIFO"), std::string::npos) << opened.status().message();
}

TEST(PrivateFiles, AFifoAsSessionsFileIsAnErrorNotAHang) {
  TempDir tmp;
  const fs::path fifo = tmp / "sessions.json";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto loaded = loadSessions(fifo.string());
  ASSERT_FALSE(loaded);
  EXPECT_NE(loaded.status().message().find("FIFO"), std::string::npos) << loaded.status().message();
  const auto missing = loadSessions((tmp / "none.json").string());
  ASSERT_TRUE(missing);
  EXPECT_TRUE(missing->empty());
}

}  // namespace
}  // namespace lightlink::service
