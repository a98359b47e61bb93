#include "clients/gateway/gateway.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "clients/gateway/live_scene.h"
#include "clients/gateway/static_files.h"

namespace lightlink::gateway {
namespace fs = std::filesystem;

namespace {

constexpr std::size_t kMaxBody = 1 << 20;  // light-set documents and blends are small
constexpr auto kHeartbeat = std::chrono::seconds(10);

bool loopbackHost(const std::string& host) {
  return host == "localhost" || host == "::1" || host == "[::1]" || host.rfind("127.", 0) == 0;
}

Expected<std::pair<std::string, int>> splitListen(const std::string& listen) {
  const auto colon = listen.rfind(':');
  if (colon == std::string::npos) return invalidInput("--http {}: expected HOST:PORT", listen);
  std::string host = listen.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  int port = -1;
  try {
    std::size_t used = 0;
    port = std::stoi(listen.substr(colon + 1), &used);
    if (used != listen.size() - colon - 1) port = -1;
  } catch (...) {
  }
  if (port < 0 || port > 65535) return invalidInput("--http {}: port is not 0..65535", listen);
  if (!loopbackHost(host))
    return invalidInput("--http {}: the gateway serves loopback only (127.0.0.1, ::1, localhost): it holds the "
                        "daemon's token and gives every caller the scenes it opens", listen);
  return std::pair{host, port};
}

void sendJson(httplib::Response& res, int status, const nlohmann::json& body) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(body.dump(), "application/json");
}

void sendError(httplib::Response& res, int status, const std::string& message) {
  sendJson(res, status, {{"error", message}});
}

int httpStatusOf(const Status& s) {
  switch (s.code()) {
    case Code::kInvalidInput: return 400;
    case Code::kNotFound: return 404;
    case Code::kUnsupported: return 501;
    case Code::kIoError: return 502;
    default: return 500;
  }
}

std::string eventText(const LiveScene& live, const LiveVersion& v) {
  nlohmann::json j;
  j["version"] = v.version;
  j["url"] = fmt::format("/api/live/{}/versions/{}/", live.handle().id, v.version);
  j["lighting"] = v.lighting;
  j["relight_ms"] = v.relight_ms;
  j["write_ms"] = v.write_ms;
  if (!v.lights.is_null()) j["lights"] = v.lights;  // the set this version was lit with
  return "event: version\ndata: " + j.dump() + "\n\n";
}

}  // namespace

struct Gateway::Impl {
  GatewayOptions options;
  fs::path web_root, files_root, work_dir;
  bool own_work_dir = false;
  std::unique_ptr<client::Client> client;
  httplib::Server server;
  std::thread listener;
  int port = 0;
  std::string host;
  std::mutex open_mutex;   // serialises opens: one live scene per bake folder
  int opened_count = 0;    // under open_mutex: names each live scene's work folder
  std::mutex lives_mutex;  // the maps below and `stopped`
  std::map<std::string, std::shared_ptr<LiveScene>> lives_by_id;
  std::map<fs::path, std::shared_ptr<LiveScene>> lives_by_bake;
  bool stopped = false;

  std::shared_ptr<LiveScene> live(const std::string& id) {
    std::lock_guard lock(lives_mutex);
    auto it = lives_by_id.find(id);
    return it == lives_by_id.end() ? nullptr : it->second;
  }

  // Requests from other sites: a Host that is not ours (DNS rebinding), or a POST that is not
  // JSON from our own origin (a form or fetch from another page).
  bool allowed(const httplib::Request& req, httplib::Response& res) const {
    const std::string h = req.get_header_value("Host");
    const auto colon = h.rfind(':');
    const std::string name = colon == std::string::npos ? h : h.substr(0, colon);
    if (!loopbackHost(name) || (colon != std::string::npos && h.substr(colon + 1) != std::to_string(port))) {
      sendError(res, 403, fmt::format("Host \"{}\" is not this gateway's loopback address", h));
      return false;
    }
    if (req.method == "POST") {
      const std::string type = req.get_header_value("Content-Type");
      if (type.rfind("application/json", 0) != 0) {
        sendError(res, 415, "POST bodies must be application/json");
        return false;
      }
      const std::string origin = req.get_header_value("Origin");
      if (!origin.empty() && origin != "http://" + h) {
        sendError(res, 403, fmt::format("Origin \"{}\" is not this gateway", origin));
        return false;
      }
    }
    return true;
  }

  void routes() {
    server.set_payload_max_length(kMaxBody);
    server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
      return allowed(req, res) ? httplib::Server::HandlerResponse::Unhandled : httplib::Server::HandlerResponse::Handled;
    });

    server.Get("/api/health", [this](const httplib::Request&, httplib::Response& res) {
      auto h = client->health();
      nlohmann::json j{{"gateway", "ok"}};
      j["daemon"] = h ? nlohmann::json("ok") : nlohmann::json(h.status().message());
      sendJson(res, h ? 200 : 502, j);
    });

    // {"bake": "/files/<folder>/"}: the bake folder, as the page's URL names it.
    server.Post("/api/live", [this](const httplib::Request& req, httplib::Response& res) {
      const nlohmann::json body = nlohmann::json::parse(req.body, nullptr, false);
      if (!body.is_object() || !body.contains("bake") || !body["bake"].is_string())
        return sendError(res, 400, "expected {\"bake\": \"/files/<bake folder>/\"}");
      std::string url = body["bake"].get<std::string>();
      if (url.rfind("/files/", 0) != 0) return sendError(res, 400, fmt::format("bake \"{}\" is not under /files/", url));
      auto dir = resolveInside(files_root, url.substr(7));
      if (!dir) return sendError(res, 404, fmt::format("bake \"{}\": {}", url, dir.status().message()));
      if (!fs::is_directory(*dir) || !fs::exists(*dir / "report.json"))
        return sendError(res, 404, fmt::format("bake \"{}\" is not a bake folder (no report.json)", url));
      // One open at a time (a second page of the same bake waits and shares it); the maps stay
      // readable meanwhile, so the pages of other bakes go on.
      std::lock_guard opening(open_mutex);
      std::shared_ptr<LiveScene> live, stale;
      {
        std::lock_guard lock(lives_mutex);
        if (stopped) return sendError(res, 503, "the gateway is stopping");
        auto it = lives_by_bake.find(*dir);
        if (it != lives_by_bake.end()) {
          if (it->second->usable()) {
            live = it->second;
          } else {  // its stream ended: open the bake again
            stale = it->second;
            lives_by_id.erase(stale->handle().id);
            lives_by_bake.erase(it);
          }
        }
      }
      if (stale) stale->close();
      if (!live) {
        const fs::path work = work_dir / fmt::format("live{}", ++opened_count);
        auto opened = LiveScene::open(*client, *dir, work, options.keep_versions);
        if (!opened) return sendError(res, httpStatusOf(opened.status()), opened.status().message());
        live = std::move(opened).value();
        spdlog::info("gateway: {} is live as scene {}", dir->string(), live->handle().id);
        std::lock_guard lock(lives_mutex);
        if (stopped) {
          live->close();
          return sendError(res, 503, "the gateway is stopping");
        }
        lives_by_id[live->handle().id] = live;
        lives_by_bake.emplace(*dir, live);
      }
      nlohmann::json j = live->describe();
      j["events"] = fmt::format("/api/live/{}/events", live->handle().id);
      sendJson(res, 200, j);
    });

    // Server-Sent Events: the newest version at once, then each new one; a comment line
    // every few seconds keeps proxies and the browser from timing the stream out.
    server.Get(R"(/api/live/([A-Za-z0-9_-]+)/events)", [this](const httplib::Request& req, httplib::Response& res) {
      auto live = this->live(req.matches[1]);
      if (!live) return sendError(res, 404, fmt::format("no live scene {}", std::string(req.matches[1])));
      res.set_header("Cache-Control", "no-store");
      auto last = std::make_shared<std::uint64_t>(0);
      // Ends with an `ended` event when the scene stops being live (gateway stopping, the
      // daemon's stream gone): the page then opens the bake again.
      res.set_chunked_content_provider("text/event-stream", [live, last](std::size_t, httplib::DataSink& sink) {
        auto v = live->usable() ? live->waitNewer(*last, kHeartbeat) : std::nullopt;
        std::string text = ": waiting\n\n";
        if (v) {
          *last = v->version;
          text = eventText(*live, *v);
        } else if (!live->usable()) {
          text = "event: ended\ndata: {}\n\n";
          sink.write(text.data(), text.size());
          sink.done();
          return true;
        }
        return sink.write(text.data(), text.size());
      });
    });

    server.Get(R"(/api/live/([A-Za-z0-9_-]+)/versions/([0-9]{1,19})/([A-Za-z0-9_.-]+))",
               [this](const httplib::Request& req, httplib::Response& res) {
                 auto live = this->live(req.matches[1]);
                 if (!live) return sendError(res, 404, fmt::format("no live scene {}", std::string(req.matches[1])));
                 const auto version = std::stoull(req.matches[2]);
                 auto v = live->find(version);
                 if (!v) return sendError(res, 404, fmt::format("version {} is not kept (newer ones replaced it)", version));
                 const std::string name = req.matches[3];
                 if (std::find(v->files.begin(), v->files.end(), name) == v->files.end())
                   return sendError(res, 404, fmt::format("version {} has no file {}", version, name));
                 serveFile(v->dir / name, res);
               });

    // A light-set document (docs/lightset.md), e.g. {"lights": [{"id": "lamp", "position": [x, y, z]}]}.
    server.Post(R"(/api/live/([A-Za-z0-9_-]+)/lights)", [this](const httplib::Request& req, httplib::Response& res) {
      auto live = this->live(req.matches[1]);
      if (!live) return sendError(res, 404, fmt::format("no live scene {}", std::string(req.matches[1])));
      auto version = live->updateLights(req.body);
      if (!version) return sendError(res, httpStatusOf(version.status()), version.status().message());
      sendJson(res, 200, {{"version", *version}});
    });

    // {"weights": {"day": 0.25, "night": 0.75}}
    server.Post(R"(/api/live/([A-Za-z0-9_-]+)/scenarios)", [this](const httplib::Request& req, httplib::Response& res) {
      auto live = this->live(req.matches[1]);
      if (!live) return sendError(res, 404, fmt::format("no live scene {}", std::string(req.matches[1])));
      const nlohmann::json body = nlohmann::json::parse(req.body, nullptr, false);
      if (!body.is_object() || !body.contains("weights") || !body["weights"].is_object() || body["weights"].empty())
        return sendError(res, 400, "expected {\"weights\": {\"<scenario>\": <weight>, ...}}");
      std::vector<lights::ScenarioWeight> weights;
      for (const auto& [name, w] : body["weights"].items()) {
        if (!w.is_number()) return sendError(res, 400, fmt::format("weights.{}: expected a number", name));
        weights.push_back({name, w.get<float>()});
      }
      auto version = live->useScenarios(weights);
      if (!version) return sendError(res, httpStatusOf(version.status()), version.status().message());
      sendJson(res, 200, {{"version", *version}});
    });

    server.Get(R"(/files/(.*))", [this](const httplib::Request& req, httplib::Response& res) {
      auto path = resolveInside(files_root, req.matches[1]);
      if (!path) return sendError(res, 404, path.status().message());
      serveFile(*path, res);
    });
    server.Get(R"(/(.*))", [this](const httplib::Request& req, httplib::Response& res) {
      std::string rel = req.matches[1];
      if (rel.empty()) rel = "index.html";
      auto path = resolveInside(web_root, rel);
      if (!path) return sendError(res, 404, path.status().message());
      serveFile(*path, res);
    });
  }
};

Gateway::Gateway(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Gateway::~Gateway() { stop(); }

int Gateway::port() const { return impl_->port; }

Expected<std::unique_ptr<Gateway>> Gateway::start(const GatewayOptions& options) {
  auto listen = splitListen(options.listen);
  if (!listen) return listen.status();
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  for (auto [root, flag, out] : {std::tuple{&options.web_root, "--web-root", &impl->web_root},
                                 std::tuple{&options.files_root, "--files", &impl->files_root}}) {
    std::error_code ec;
    if (root->empty()) return invalidInput("{}: required with --http", flag);
    *out = fs::canonical(*root, ec);
    if (ec || !fs::is_directory(*out)) return invalidInput("{} {}: not a folder", flag, *root);
  }
  if (!fs::exists(impl->web_root / "index.html"))
    return invalidInput("--web-root {}: no index.html (build the viewer: ninja -C build web_viewer)", options.web_root);
  std::error_code ec;
  if (options.work_dir.empty()) {
    impl->work_dir = fs::temp_directory_path(ec) / fmt::format("lightlink-gateway-{}", ::getpid());
    impl->own_work_dir = true;
  } else {
    impl->work_dir = options.work_dir;
  }
  fs::create_directories(impl->work_dir, ec);
  if (ec) return ioError("cannot create {}: {}", impl->work_dir.string(), ec.message());
  client::ConnectOptions daemon = options.daemon;
  daemon.connect_timeout = std::chrono::milliseconds(0);  // the daemon may still be starting
  auto c = client::Client::connect(daemon);
  if (!c) return c.status();
  impl->client = std::make_unique<client::Client>(std::move(c).value());
  // Each event stream holds a thread; a few pages and their file reads fit in 32.
  impl->server.new_task_queue = [] { return new httplib::ThreadPool(32); };
  impl->routes();
  impl->host = listen->first;
  impl->port = listen->second == 0 ? impl->server.bind_to_any_port(impl->host)
                                   : (impl->server.bind_to_port(impl->host, listen->second) ? listen->second : -1);
  if (impl->port <= 0) return ioError("--http {}: cannot listen there", options.listen);
  if (!options.port_file.empty()) {
    const std::string tmp = options.port_file + ".tmp";
    std::ofstream(tmp) << impl->port << "\n";
    fs::rename(tmp, options.port_file, ec);
    if (ec) return ioError("--http-port-file {}: {}", options.port_file, ec.message());
  }
  Impl* raw = impl.get();
  impl->listener = std::thread([raw] { raw->server.listen_after_bind(); });
  spdlog::info("gateway: http://{}:{}/ (viewer {}, bakes {})", impl->host, impl->port, impl->web_root.string(),
               impl->files_root.string());
  return std::unique_ptr<Gateway>(new Gateway(std::move(impl)));
}

void Gateway::stop() {
  if (!impl_) return;
  std::map<std::string, std::shared_ptr<LiveScene>> lives;
  {
    std::lock_guard lock(impl_->lives_mutex);
    if (impl_->stopped) return;
    impl_->stopped = true;
    lives.swap(impl_->lives_by_id);
    impl_->lives_by_bake.clear();
  }
  for (auto& [id, live] : lives) live->close();  // wakes the event streams, closes the scenes
  impl_->server.stop();
  if (impl_->listener.joinable()) impl_->listener.join();
  std::error_code ec;
  if (impl_->own_work_dir) fs::remove_all(impl_->work_dir, ec);
}

}  // namespace lightlink::gateway
