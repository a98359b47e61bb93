#include "service/scene_registry.h"

#include <cstring>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <google/protobuf/util/json_util.h>

#include "core/artifact/artifact.h"
#include "service/auth.h"
#include "service/logging.h"
#include "service/session_store.h"
#include "service/validation.h"

namespace lightlink::service {
namespace {

namespace fs = std::filesystem;

// The open parameters worth remembering: everything but the source and the initial
// light-set JSON (the current light set is stored separately).
nlohmann::json paramsToJson(const v1::OpenSceneRequest& request) {
  v1::OpenSceneRequest params = request;
  params.clear_source();
  params.clear_lightset_json();
  std::string text;
  google::protobuf::util::JsonPrintOptions o;
  o.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(params, &text, o);
  return nlohmann::json::parse(text, nullptr, false);
}

Expected<v1::OpenSceneRequest> paramsFromJson(const nlohmann::json& j) {
  v1::OpenSceneRequest r;
  const auto st = google::protobuf::util::JsonStringToMessage(j.dump(), &r);
  if (!st.ok()) return invalidInput("params: {}", st.ToString());
  return r;
}

std::string backendChoiceName(v1::Backend b, const std::string& daemon_default) {
  switch (b) {
    case v1::BACKEND_CPU: return "cpu";
    case v1::BACKEND_GPU: return "gpu";
    default: return daemon_default;
  }
}

// Emissive overrides of a light-set JSON must name materials the scene has.
Status checkMaterials(const relight::LightSet& lights, std::size_t material_count, std::string_view field) {
  for (std::size_t i = 0; i < lights.emissive().size(); ++i) {
    const int m = lights.emissive()[i].material;
    if (m < 0 || static_cast<std::size_t>(m) >= material_count)
      return invalidInput("{}: emissive[{}].material {} is not a material of the scene ({} materials)", field, i, m,
                          material_count);
  }
  return {};
}

}  // namespace

SceneRegistry::SceneRegistry(const DaemonConfig& config)
    : config_(config), sessions_path_((fs::path(config.cache_dir) / "sessions.json").string()) {
  // validate() checked the roots at start; one that has gone since is dropped, not trusted.
  if (auto roots = SceneRoots::resolve(config.scene_roots)) roots_ = std::move(roots).value();
  else logEvent(LogLevel::kError, "scene_roots_unusable", {{"error", roots.status().message()}});
  persist_thread_ = std::thread([this] { persistLoop(); });
}

SceneRegistry::~SceneRegistry() {
  if (Status s = shutdown(); !s)
    logEvent(LogLevel::kError, "sessions_write_failed", {{"path", sessions_path_}, {"error", s.message()}});
}

Status SceneRegistry::shutdown() {
  // Stop the background writer first: after closeAll the registry is empty, and a late
  // write would record "no scenes" and lose every session.
  {
    std::lock_guard lock(persist_mutex_);
    persist_stop_ = true;
  }
  persist_cv_.notify_all();
  if (persist_thread_.joinable()) persist_thread_.join();
  Status saved;
  if (!shut_down_) saved = persistNow();
  shut_down_ = true;
  closeAll();
  return saved;
}

std::shared_ptr<std::mutex> SceneRegistry::openMutexFor(const std::string& key) {
  std::lock_guard lock(mutex_);
  auto& m = open_mutexes_[key];
  if (!m) m = std::make_shared<std::mutex>();
  return m;
}

// Inline scenes come from clients: a URI naming a file would make the daemon read whatever
// that path points at on its own machine (another scene, /etc/..., /dev/zero) and would not
// be covered by the bytes the client sent. So they must be self-contained: data: URIs or a
// GLB's own buffer. The JSON is checked here; malformed JSON is left to the loader's message.
static Status checkSelfContained(const std::string& bytes, bool glb) {
  std::string_view text = bytes;
  if (glb) {
    std::uint32_t length = 0, type = 0;
    if (bytes.size() < 20) return invalidInput("gltf_bytes: {} bytes is too short for a GLB", bytes.size());
    std::memcpy(&length, bytes.data() + 12, 4);
    std::memcpy(&type, bytes.data() + 16, 4);
    if (type != 0x4E4F534Au || length > bytes.size() - 20) return Status::ok();
    text = text.substr(20, length);
  }
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) return Status::ok();
  for (const char* list : {"buffers", "images"}) {
    const auto it = j.find(list);
    if (it == j.end() || !it->is_array()) continue;
    for (std::size_t i = 0; i < it->size(); ++i) {
      const nlohmann::json& e = (*it)[i];
      if (!e.is_object() || !e.contains("uri")) continue;
      const nlohmann::json& uri = e["uri"];
      if (uri.is_string() && uri.get_ref<const std::string&>().rfind("data:", 0) == 0) continue;
      return invalidInput("gltf_bytes: {}[{}].uri names an external file; inline scenes must be self-contained "
                          "(data: URIs or GLB buffers), or open the scene by path",
                          list, i);
    }
  }
  return Status::ok();
}

Expected<std::string> SceneRegistry::storeInlineScene(const std::string& bytes) {
  if (bytes.size() < 4) return invalidInput("gltf_bytes: {} bytes is not a glTF or GLB file", bytes.size());
  const bool glb = bytes.compare(0, 4, "glTF") == 0;
  if (Status s = checkSelfContained(bytes, glb); !s) return s;
  const std::uint64_t hash = artifact::hashBytes(bytes.data(), bytes.size());
  const fs::path dir = fs::path(config_.cache_dir) / "inline";
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return ioError("cannot create {}: {}", dir.string(), ec.message());
  const fs::path path = dir / (artifact::cacheKeyHex(hash) + (glb ? ".glb" : ".gltf"));
  // Same content, same name: an existing file of the right size is this scene already.
  if (fs::exists(path, ec) && fs::file_size(path, ec) == bytes.size()) return path.string();
  if (Status s = writeFileAtomic(path.string(), bytes); !s) return s;
  return path.string();
}

Expected<std::shared_ptr<SceneSession>> SceneRegistry::open(const v1::OpenSceneRequest& request, Progress* progress) {
  SessionIdentity identity;
  identity.id = randomToken();
  identity.id[0] = 's';  // ids start with a letter; 60 random bits keep them unique
  identity.id.resize(16);
  identity.token = randomToken();
  identity.name = request.name();
  if (request.source_case() == v1::OpenSceneRequest::kPath) {
    if (request.path().empty()) return invalidInput("path: must not be empty");
    if (request.path().size() > kMaxPathBytes) return invalidInput("path: longer than {} bytes", kMaxPathBytes);
    // Outside the roots nothing is looked at, so the answer cannot tell what exists there.
    auto admitted = roots_.admit(request.path());
    if (!admitted) return admitted.status();
    std::error_code ec;
    if (!fs::is_regular_file(*admitted, ec)) return notFound("path: no scene file '{}'", request.path());
    identity.source_path = *admitted;  // canonical: what was checked is what gets read
    identity.source_label = request.path();
  } else if (request.source_case() == v1::OpenSceneRequest::kGltfBytes) {
    auto stored = storeInlineScene(request.gltf_bytes());
    if (!stored) return stored.status();
    identity.source_path = *stored;
    identity.source_label = fmt::format("<inline {} bytes>", request.gltf_bytes().size());
  } else {
    return invalidInput("source: set path or gltf_bytes");
  }
  if (identity.name.empty()) identity.name = fs::path(identity.source_path).stem().string();
  v1::OpenSceneRequest params = request;
  params.clear_source();
  params.clear_lightset_json();
  identity.params = params;
  return openResident(std::move(identity), request, nullptr, 1, request.lightset_json(), progress);
}

Expected<std::shared_ptr<SceneSession>> SceneRegistry::openResident(SessionIdentity identity,
                                                                   const v1::OpenSceneRequest& request,
                                                                   const relight::LightSet* restored_lights,
                                                                   std::uint64_t version,
                                                                   const std::string& lightset_json,
                                                                   Progress* progress) {
  auto options = precomputeOptionsFrom(request);
  if (!options) return options.status();
  if (!v1::Backend_IsValid(request.backend()))
    return invalidInput("backend: {} is not a Backend", static_cast<int>(request.backend()));
  // Parse the light-set JSON before the (long) precompute so a typo fails fast.
  nlohmann::json overrides;
  if (!lightset_json.empty()) {
    overrides = nlohmann::json::parse(lightset_json, nullptr, /*allow_exceptions=*/false);
    if (overrides.is_discarded() || !overrides.is_object())
      return invalidInput("lightset_json: not a JSON object (docs/lightset.md)");
  }

  precompute::ResidentRequest rr;
  rr.scene_path = identity.source_path;
  rr.options = *options;
  rr.cache_dir = config_.cache_dir;
  // Two opens of the same scene and parameters precompute once: the second waits and reuses.
  auto mutex = openMutexFor(identity.source_path + "|" + options->canonical());
  std::unique_lock open_lock(*mutex);
  auto resident = precompute::ResidentScene::open(rr, progress);
  open_lock.unlock();
  if (!resident) return resident.status();

  relight::LightSet lights;
  if (restored_lights) {
    lights = *restored_lights;
  } else {
    lights = relight::LightSet::fromScene(resident->scene());
    if (!overrides.is_null()) {
      if (Status s = lights.apply(overrides); !s) return invalidInput("lightset_json: {}", s.message());
    }
  }
  if (Status s = checkMaterials(lights, resident->scene().materials.size(), "lightset_json"); !s) return s;

  SessionOptions so;
  so.backend = backendChoiceName(request.backend(), config_.backend);
  so.relight.max_bounces = config_.relight_bounces;
  so.progressive = config_.progressive;
  so.on_own_version = [this] { markDirty(); };
  const bool reused = resident->reused();
  const std::string note = resident->note();
  const double open_s = resident->openSeconds();
  auto session = SceneSession::start(identity, std::move(resident).value(), std::move(lights), version, so);
  if (!session) return session.status();
  {
    std::lock_guard lock(mutex_);
    scenes_[identity.id] = *session;
  }
  markDirty();
  logEvent(LogLevel::kInfo, restored_lights ? "scene_restored" : "scene_opened",
           {{"scene", identity.id},
            {"source", identity.source_label},
            {"artifact", note},
            {"artifact_reused", reused},
            {"backend", (*session)->backendName()},
            {"backend_note", (*session)->backendNote()},
            {"version", version},
            {"open_s", open_s}});
  return session;
}

void SceneRegistry::restore() {
  auto records = loadSessions(sessions_path_);
  if (!records) {
    logEvent(LogLevel::kError, "sessions_unreadable", {{"path", sessions_path_}, {"error", records.status().message()}});
    return;
  }
  for (const auto& r : *records) {
    auto params = paramsFromJson(r.params);
    auto lights = relight::LightSet::fromJson(r.lights);
    Status why = !params ? params.status() : !lights ? lights.status() : Status{};
    // The roots may have changed since the scene was opened; uploaded scenes live in the cache.
    const bool uploaded = fs::path(r.source_path).parent_path() == fs::path(config_.cache_dir) / "inline";
    if (why && !uploaded)
      if (auto admitted = roots_.admit(r.source_path); !admitted) why = admitted.status();
    if (why) {
      SessionIdentity identity{r.id, r.token, r.name, r.source_path, r.source_label, *params};
      v1::OpenSceneRequest request = *params;
      request.set_path(r.source_path);
      auto opened = openResident(identity, request, &*lights, std::max<std::uint64_t>(r.version, 1), "", nullptr);
      if (opened) continue;
      why = opened.status();
    }
    logEvent(LogLevel::kWarn, "scene_not_restored", {{"scene", r.id}, {"source", r.source_label}, {"error", why.message()}});
  }
  markDirty();  // the file now lists exactly the scenes that came back
}

std::shared_ptr<SceneSession> SceneRegistry::find(const std::string& id) const {
  std::lock_guard lock(mutex_);
  auto it = scenes_.find(id);
  return it == scenes_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<SceneSession>> SceneRegistry::list() const {
  std::lock_guard lock(mutex_);
  std::vector<std::shared_ptr<SceneSession>> out;
  for (const auto& [id, s] : scenes_) out.push_back(s);
  return out;
}

std::size_t SceneRegistry::size() const {
  std::lock_guard lock(mutex_);
  return scenes_.size();
}

bool SceneRegistry::close(const std::string& id) {
  std::shared_ptr<SceneSession> s;
  {
    std::lock_guard lock(mutex_);
    auto it = scenes_.find(id);
    if (it == scenes_.end()) return false;
    s = it->second;
    scenes_.erase(it);
  }
  s->close();
  markDirty();
  logEvent(LogLevel::kInfo, "scene_closed", {{"scene", id}});
  return true;
}

void SceneRegistry::closeAll() {
  std::map<std::string, std::shared_ptr<SceneSession>> scenes;
  {
    std::lock_guard lock(mutex_);
    scenes.swap(scenes_);
  }
  for (auto& [id, s] : scenes) s->close();
}

void SceneRegistry::markDirty() {
  {
    std::lock_guard lock(persist_mutex_);
    dirty_ = true;
  }
  persist_cv_.notify_one();
}

Status SceneRegistry::persistNow() {
  std::vector<SessionRecord> records;
  for (const auto& s : list()) {
    const auto& id = s->identity();
    SessionRecord r;
    r.id = id.id;
    r.token = id.token;
    r.name = id.name;
    r.source_path = id.source_path;
    r.source_label = id.source_label;
    r.params = paramsToJson(id.params);
    r.lights = s->persistentLights(&r.version);
    records.push_back(std::move(r));
  }
  std::lock_guard lock(write_mutex_);
  return saveSessions(sessions_path_, records);
}

void SceneRegistry::persistLoop() {
  std::unique_lock lock(persist_mutex_);
  while (true) {
    persist_cv_.wait(lock, [&] { return dirty_ || persist_stop_; });
    if (persist_stop_) return;  // shutdown() writes the final state itself
    dirty_ = false;
    lock.unlock();
    if (Status s = persistNow(); !s)
      logEvent(LogLevel::kError, "sessions_write_failed", {{"path", sessions_path_}, {"error", s.message()}});
    lock.lock();
  }
}

}  // namespace lightlink::service
