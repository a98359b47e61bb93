// The web gateway's own rules, without a daemon (the live path end to end is
// tests/node/web_live_test.mjs): files only from inside their root, loopback only, requests
// from other sites refused, bad bakes named.
#include <gtest/gtest.h>
#include <httplib.h>

#include <filesystem>
#include <fstream>

#include "clients/gateway/gateway.h"
#include "clients/gateway/static_files.h"

namespace fs = std::filesystem;
using lightlink::gateway::Gateway;
using lightlink::gateway::GatewayOptions;
using lightlink::gateway::resolveInside;

namespace {

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("lightlink-gateway-test-" + std::to_string(::getpid()) + "-" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text;
}

}  // namespace

TEST(GatewayFiles, ResolvesOnlyInsideTheRoot) {
  TempDir t;
  const fs::path root = t.path / "files";
  write(root / "demo" / "report.json", "{}");
  write(t.path / "files2" / "secret.txt", "no");
  write(root / ".hidden", "no");
  fs::create_directory_symlink(t.path / "files2", root / "link_out");
  const fs::path canon = fs::canonical(root);

  auto ok = resolveInside(canon, "demo/report.json");
  ASSERT_TRUE(ok) << ok.status().message();
  EXPECT_EQ(*ok, canon / "demo" / "report.json");
  for (const char* bad : {"../files2/secret.txt", "demo/../../files2/secret.txt", ".hidden", "demo/.git/config",
                          "link_out/secret.txt", "/etc/passwd"}) {
    auto r = resolveInside(canon, bad);
    EXPECT_FALSE(r) << bad << " resolved to " << (r ? r->string() : "");
  }
}

TEST(GatewayFiles, NamesContentTypes) {
  EXPECT_STREQ(lightlink::gateway::contentTypeOf("viewer.js"), "text/javascript; charset=utf-8");
  EXPECT_STREQ(lightlink::gateway::contentTypeOf("a_lm.gltf"), "model/gltf+json");
  EXPECT_STREQ(lightlink::gateway::contentTypeOf("lightmap_L00.exr"), "image/x-exr");
  EXPECT_STREQ(lightlink::gateway::contentTypeOf("grid.raw"), "application/octet-stream");
}

TEST(Gateway, RefusesWhatItCannotServeSafely) {
  TempDir t;
  GatewayOptions o;
  o.listen = "127.0.0.1:0";
  o.web_root = (t.path / "web").string();
  o.files_root = (t.path / "files").string();
  o.daemon.target = "127.0.0.1:1";
  o.work_dir = (t.path / "work").string();
  fs::create_directories(o.files_root);

  auto missing = Gateway::start(o);
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.status().message().find("--web-root"), std::string::npos) << missing.status().message();
  fs::create_directories(o.web_root);
  auto no_index = Gateway::start(o);
  ASSERT_FALSE(no_index);
  EXPECT_NE(no_index.status().message().find("index.html"), std::string::npos) << no_index.status().message();
  write(fs::path(o.web_root) / "index.html", "<html>viewer</html>");
  for (const char* listen : {"0.0.0.0:0", "192.168.1.2:8080", "example.com:80", "127.0.0.1", "127.0.0.1:99999"}) {
    o.listen = listen;
    auto g = Gateway::start(o);
    EXPECT_FALSE(g) << listen;
  }
}

TEST(Gateway, ServesThePageAndRefusesOtherSites) {
  TempDir t;
  GatewayOptions o;
  o.listen = "127.0.0.1:0";
  o.web_root = (t.path / "web").string();
  o.files_root = (t.path / "files").string();
  o.daemon.target = "127.0.0.1:1";  // no daemon: health says so, the rest needs none
  o.daemon.call_timeout = std::chrono::milliseconds(2000);
  o.work_dir = (t.path / "work").string();
  write(fs::path(o.web_root) / "index.html", "<html>viewer</html>");
  write(fs::path(o.files_root) / "old" / "report.json", R"({"cache_key": "00"})");
  write(fs::path(o.files_root) / "demo" / "lightmap.png", "png");
  auto g = Gateway::start(o);
  ASSERT_TRUE(g) << g.status().message();
  const int port = (*g)->port();
  ASSERT_GT(port, 0);
  httplib::Client http("127.0.0.1", port);

  auto page = http.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_EQ(page->body, "<html>viewer</html>");
  auto file = http.Get("/files/demo/lightmap.png");
  ASSERT_TRUE(file);
  EXPECT_EQ(file->status, 200);
  EXPECT_EQ(file->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(http.Get("/files/demo/missing.png")->status, 404);

  auto health = http.Get("/api/health");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 502);  // the gateway answers, naming the daemon's state

  // DNS rebinding: another name for this address.
  auto rebound = http.Get("/", {{"Host", "attacker.example:" + std::to_string(port)}});
  ASSERT_TRUE(rebound);
  EXPECT_EQ(rebound->status, 403);
  // Cross-site POSTs: a form body, or JSON from another origin.
  EXPECT_EQ(http.Post("/api/live", "bake=/files/demo/", "application/x-www-form-urlencoded")->status, 415);
  auto other = http.Post("/api/live", {{"Origin", "http://evil.example"}}, R"({"bake":"/files/demo/"})", "application/json");
  ASSERT_TRUE(other);
  EXPECT_EQ(other->status, 403);

  // Bad bakes are named before any daemon call.
  auto not_bake = http.Post("/api/live", R"({"bake":"/files/demo/"})", "application/json");
  EXPECT_EQ(not_bake->status, 404);
  EXPECT_NE(not_bake->body.find("no report.json"), std::string::npos) << not_bake->body;
  auto old = http.Post("/api/live", R"({"bake":"/files/old/"})", "application/json");
  EXPECT_EQ(old->status, 400);
  EXPECT_NE(old->body.find("bake again"), std::string::npos) << old->body;
  auto outside = http.Post("/api/live", R"({"bake":"/etc/"})", "application/json");
  EXPECT_EQ(outside->status, 400);
  EXPECT_EQ(http.Post("/api/live", "[1, 2", "application/json")->status, 400);
  EXPECT_EQ(http.Get("/api/live/nosuch/events")->status, 404);

  (*g)->stop();
  (*g)->stop();  // idempotent
  EXPECT_FALSE(http.Get("/"));
}
