#include "clients/gateway/live_scene.h"

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "clients/client/result_files.h"

namespace lightlink::gateway {
namespace fs = std::filesystem;

namespace {

Expected<nlohmann::json> readJson(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return ioError("cannot read {}", path.string());
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    return invalidInput("{}: {}", path.string(), e.what());
  }
}

// A file a report names, which must stay inside the bake folder.
Expected<fs::path> insideBake(const fs::path& bake, const nlohmann::json& name, const char* what) {
  if (!name.is_string()) return invalidInput("{}/report.json: {} is not a file name", bake.string(), what);
  const fs::path rel = fs::path(name.get<std::string>()).lexically_normal();
  if (rel.empty() || rel.is_absolute() || *rel.begin() == "..")
    return invalidInput("{}/report.json: {} \"{}\" leaves the bake folder", bake.string(), what, rel.string());
  return bake / rel;
}

// A whole light set (LightSet::toJson) as a document that turns the scene's own lights into
// exactly it: ids it lacks are removed.
std::string wholeSetDocument(nlohmann::json set, const std::vector<std::string>& scene_ids) {
  std::set<std::string> listed;
  if (!set.contains("lights") || !set["lights"].is_array()) set["lights"] = nlohmann::json::array();
  for (const auto& l : set["lights"])
    if (l.contains("id") && l["id"].is_string()) listed.insert(l["id"].get<std::string>());
  for (const auto& id : scene_ids)
    if (!listed.count(id)) set["lights"].push_back({{"id", id}, {"remove", true}});
  return set.dump();
}

}  // namespace

LiveScene::LiveScene(client::Client& client, fs::path work_dir, int keep)
    : client_(client), work_dir_(std::move(work_dir)), keep_(std::max(1, keep)) {}

Expected<std::unique_ptr<LiveScene>> LiveScene::open(client::Client& client, const fs::path& bake_dir,
                                                     const fs::path& work_dir, int keep_versions) {
  auto report = readJson(bake_dir / "report.json");
  if (!report) return report.status();
  const nlohmann::json& source = (*report)["source"];
  if (!source.is_object() || !source.contains("scene") || !source["scene"].is_string())
    return invalidInput("{}/report.json has no \"source\" (a bake before live mode): bake again", bake_dir.string());
  std::unique_ptr<LiveScene> live(new LiveScene(client, work_dir, keep_versions));

  client::OpenOptions open;
  open.path = source["scene"].get<std::string>();
  if (source.contains("options") && source["options"].is_object())
    for (const auto& [name, value] : source["options"].items())
      if (value.is_string()) open.options[name] = value.get<std::string>();
  open.preview = false;  // the page already shows the bake; its first live version is linked
  open.name = "web: " + bake_dir.filename().string();
  auto handle = client.openScene(open);
  if (!handle) return handle.status();
  live->handle_ = std::move(handle).value();
  live->own_light_ids_.assign(live->handle_.light_ids.begin(), live->handle_.light_ids.end());
  const std::string key = (*report).value("cache_key", "");
  if (live->handle_.info.cache_key() != key) {
    (void)client.closeScene(live->handle_);
    return invalidInput("{}: the daemon's precompute of {} has cache key {}, the bake's is {} (the scene or the "
                        "daemon's version changed since the bake): bake again", bake_dir.string(), open.path,
                        live->handle_.info.cache_key(), key);
  }
  if (source.contains("light_nodes") && source["light_nodes"].is_object()) live->light_nodes_ = source["light_nodes"];

  auto fail = [&](const Status& s) {
    (void)client.closeScene(live->handle_);
    return s;
  };
  // The bake's light set, then its scenarios, as the daemon's.
  if (source.contains("light_set")) {
    auto path = insideBake(bake_dir, source["light_set"], "source.light_set");
    if (!path) return fail(path.status());
    auto set = readJson(*path);
    if (!set) return fail(set.status());
    auto version = live->updateLights(wholeSetDocument(*set, live->own_light_ids_));
    if (!version) return fail(version.status());
  }
  if (report->contains("scenarios") && (*report)["scenarios"].is_array()) {
    for (const auto& sc : (*report)["scenarios"]) {
      if (!sc.contains("name") || !sc["name"].is_string() || !sc.contains("light_set")) continue;
      auto path = insideBake(bake_dir, sc["light_set"], "scenarios[].light_set");
      if (!path) return fail(path.status());
      auto set = readJson(*path);
      if (!set) return fail(set.status());
      auto names = client.setScenario(live->handle_, sc["name"].get<std::string>(),
                                      wholeSetDocument(*set, live->own_light_ids_));
      if (!names) return fail(names.status());
      live->scenarios_ = std::move(names).value();
    }
  }

  std::error_code ec;
  fs::create_directories(work_dir, ec);
  if (ec) return fail(ioError("cannot create {}: {}", work_dir.string(), ec.message()));
  client::ResultSpec spec;  // lightmap and grid, every band, half: what a bake writes
  auto sub = client.subscribe(live->handle_, spec, /*deltas=*/true);
  if (!sub) return fail(sub.status());
  live->subscription_ = std::move(sub).value();
  live->follower_ = std::thread([p = live.get()] { p->follow(); });
  return live;
}

LiveScene::~LiveScene() { close(); }

void LiveScene::close() {
  if (closed_.exchange(true)) return;
  {
    std::lock_guard lock(mutex_);
    if (subscription_) subscription_->cancel();
  }
  changed_.notify_all();
  if (follower_.joinable()) follower_.join();
  if (Status s = client_.closeScene(handle_); !s)
    spdlog::warn("gateway: closing live scene {}: {}", handle_.id, s.message());
  std::error_code ec;
  fs::remove_all(work_dir_, ec);
}

void LiveScene::follow() {
  client::ResultFileOptions options;
  options.png_preview = false;
  options.compress = false;        // written and read at once on this machine
  options.all_grid_files = false;  // the page reads grid.raw
  options.irradiance = false;      // and evaluates the SH files itself
  options.scene_hash = handle_.info.cache_key();
  while (!closed_) {
    auto next = subscription_->next();
    if (!next || *next == nullptr) {
      if (!closed_) spdlog::warn("gateway: the stream of scene {} ended{}", handle_.id, next ? "" : ": " + next.status().message());
      break;
    }
    const client::Textures& tex = **next;
    if (tex.info.width == 0 || tex.info.kind != client::ResultKind::kLinked) continue;  // a grid-only preview: the page keeps the bake's lightmap
    const std::uint64_t version = tex.info.version;
    const fs::path dir = work_dir_ / fmt::format("v{}", version);
    const fs::path staging = work_dir_ / fmt::format("v{}.partial", version);
    const auto t0 = std::chrono::steady_clock::now();
    std::error_code ec;
    fs::remove_all(staging, ec);
    fs::create_directories(staging, ec);
    auto files = ec ? Expected<client::ResultFiles>(ioError("cannot create {}: {}", staging.string(), ec.message()))
                    : client::writeResultFiles(tex, staging.string(), options);
    if (!files) {
      spdlog::warn("gateway: version {} of {}: {}", version, handle_.id, files.status().message());
      continue;
    }
    fs::remove_all(dir, ec);
    fs::rename(staging, dir, ec);
    if (ec) {
      spdlog::warn("gateway: {}: {}", dir.string(), ec.message());
      continue;
    }
    const double write_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    LiveVersion v{version, dir, files->files, files->lighting, tex.info.relight_ms, write_ms, nullptr};
    // Pages move their light handles (and the direct light of grid-lit objects) to the set
    // this version was lit with, also when another client changed it.
    if (auto state = client_.getLights(handle_); state && state->version == version)
      v.lights = nlohmann::json::parse(state->json, nullptr, false);
    std::vector<fs::path> dropped;
    {
      std::lock_guard lock(mutex_);
      versions_.push_back(std::move(v));
      while (int(versions_.size()) > keep_) {
        dropped.push_back(versions_.front().dir);
        versions_.pop_front();
      }
    }
    changed_.notify_all();
    for (const auto& d : dropped) fs::remove_all(d, ec);
  }
  ended_ = true;
  changed_.notify_all();
}

nlohmann::json LiveScene::describe() const {
  auto state = client_.getLights(handle_);  // before the locks: an RPC
  std::lock_guard update(update_mutex_);  // updates change the handle's light ids
  std::lock_guard lock(mutex_);
  nlohmann::json j;
  j["scene_id"] = handle_.id;
  j["scene_token"] = handle_.token;  // so the CLI (set-light, watch, pull) can join this scene
  j["cache_key"] = handle_.info.cache_key();
  j["light_ids"] = nlohmann::json(std::vector<std::string>(handle_.light_ids.begin(), handle_.light_ids.end()));
  j["lights"] = state ? nlohmann::json::parse(state->json, nullptr, false) : nlohmann::json();
  j["light_nodes"] = light_nodes_;
  j["scenarios"] = scenarios_;
  j["lightmap"] = {{"width", handle_.info.lightmap().width()}, {"height", handle_.info.lightmap().height()}};
  j["version"] = versions_.empty() ? 0 : versions_.back().version;
  return j;
}

Expected<std::uint64_t> LiveScene::updateLights(const std::string& light_set_json) {
  if (closed_) return Status(Code::kNotFound, "the live scene is closed");
  std::lock_guard update(update_mutex_);
  auto r = client_.updateLightsFromJson(handle_, light_set_json);
  if (!r) return r.status();
  return r->version;
}

Expected<std::uint64_t> LiveScene::useScenarios(const std::vector<lights::ScenarioWeight>& weights) {
  if (closed_) return Status(Code::kNotFound, "the live scene is closed");
  std::lock_guard update(update_mutex_);
  auto r = client_.useScenarios(handle_, weights);
  if (!r) return r.status();
  return r->version;
}

std::optional<LiveVersion> LiveScene::waitNewer(std::uint64_t after, std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  changed_.wait_for(lock, timeout, [&] { return !usable() || (!versions_.empty() && versions_.back().version > after); });
  if (closed_ || versions_.empty() || versions_.back().version <= after) return std::nullopt;
  return versions_.back();
}

std::optional<LiveVersion> LiveScene::find(std::uint64_t version) const {
  std::lock_guard lock(mutex_);
  for (const auto& v : versions_)
    if (v.version == version) return v;
  return std::nullopt;
}


}  // namespace lightlink::gateway
