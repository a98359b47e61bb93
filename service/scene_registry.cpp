#include "service/scene_registry.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <google/protobuf/util/json_util.h>

#include "core/artifact/artifact.h"
#include "core/common/private_files.h"
#include "core/preview/preview_grid.h"
#include "core/rt/accel.h"
#include "service/auth.h"
#include "service/cache_quota.h"
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
  if (Status s = lights.checkMaterials(material_count); !s) return invalidInput("{}: {}", field, s.message());
  return {};
}

// Writes an upload to a new private temp file (fsynced); it becomes the stored scene only
// once the open succeeded (SceneRegistry::openResident renames it).
Status writeStagedFile(const std::string& path, std::string_view bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, kPrivateFileMode);
  if (fd < 0) return ioError("cannot create {}: {}", path, std::strerror(errno));
  ::fchmod(fd, kPrivateFileMode);
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = std::strerror(errno);
      ::close(fd);
      ::unlink(path.c_str());
      return ioError("cannot write {}: {}", path, why);
    }
    done += static_cast<std::size_t>(n);
  }
  const bool synced = ::fsync(fd) == 0;
  ::close(fd);
  if (!synced) {
    ::unlink(path.c_str());
    return ioError("cannot fsync {}", path);
  }
  return {};
}

// The progress of an open that published a preview: the caller's, and cancelled also once the
// previewed scene was closed (CloseScene during the precompute stops the precompute).
class PreviewedProgress final : public Progress {
 public:
  PreviewedProgress(Progress* inner, const std::shared_ptr<SceneSession>& previewed)
      : inner_(inner), previewed_(previewed) {}
  void begin(std::string_view stage, std::size_t total) override {
    if (inner_) inner_->begin(stage, total);
  }
  void update(std::size_t done) override {
    if (inner_) inner_->update(done);
  }
  void end() override {
    if (inner_) inner_->end();
  }
  bool cancelled() const override {
    return (inner_ && inner_->cancelled()) || (previewed_ && previewed_->closed());
  }

 private:
  Progress* inner_;
  const std::shared_ptr<SceneSession>& previewed_;  // set by the load callback, read while precomputing
};

// A background restore stops early when the daemon shuts down.
class RestoreProgress final : public Progress {
 public:
  explicit RestoreProgress(const std::atomic<bool>& stop) : stop_(stop) {}
  void begin(std::string_view, std::size_t) override {}
  void update(std::size_t) override {}
  void end() override {}
  bool cancelled() const override { return stop_.load(); }

 private:
  const std::atomic<bool>& stop_;
};

}  // namespace

SceneRegistry::SceneRegistry(const DaemonConfig& config)
    : config_(config),
      sessions_path_((fs::path(config.cache_dir) / "sessions.json").string()),
      journal_(std::make_shared<UpdateJournal>((fs::path(config.cache_dir) / "sessions.journal").string())) {
  journal_->onLarge(kCompactBytes, [this] { markDirty(); });
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
  // A background restore first: it must not add scenes once they are being closed. Scenes
  // it did not reach stay in sessions.json (persistNow writes the restoring ones too).
  restore_stop_ = true;
  if (restore_thread_.joinable()) restore_thread_.join();
  // Stop the background writer first: after closeAll the registry is empty, and a late
  // write would record "no scenes" and lose every session.
  {
    std::lock_guard lock(persist_mutex_);
    persist_stop_ = true;
  }
  persist_cv_.notify_all();
  if (persist_thread_.joinable()) persist_thread_.join();
  Status saved;
  if (!shut_down_) {
    saved = compact();
    // How well group commit shared the syncs over this run.
    logEvent(LogLevel::kInfo, "journal_closed", {{"commits", journal_->commits()}, {"records", journal_->records()}});
  }
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

// The upload is validated before it is stored: it is written to a temp file that
// openResident loads and renames to its content-hash name only once the scene opened, so
// bytes that do not load never stay in the cache. `staged` receives the temp file (empty
// when the same content is stored already).
Expected<std::string> SceneRegistry::storeInlineScene(const std::string& bytes, std::string* staged) {
  if (bytes.size() < 4) return invalidInput("gltf_bytes: {} bytes is not a glTF or GLB file", bytes.size());
  const bool glb = bytes.compare(0, 4, "glTF") == 0;
  if (Status s = checkSelfContained(bytes, glb); !s) return s;
  const std::uint64_t hash = artifact::hashBytes(bytes.data(), bytes.size());
  const fs::path dir = fs::path(config_.cache_dir) / "inline";
  if (Status s = createPrivateDirectories(dir.string()); !s) return s;
  const fs::path path = dir / (artifact::cacheKeyHex(hash) + (glb ? ".glb" : ".gltf"));
  // Same content, same name: an existing regular file of the right size is this scene
  // already (lstat: a FIFO or link planted under the name is not).
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && static_cast<std::size_t>(st.st_size) == bytes.size()) {
    touchLastUse(path.string());
    return path.string();
  }
  enforceQuota(bytes.size());
  static std::atomic<unsigned> counter{0};
  const fs::path temp = dir / fmt::format(".{}.tmp.{}.{}", path.filename().string(), ::getpid(), counter++);
  if (Status s = writeStagedFile(temp.string(), bytes); !s) return s;
  *staged = temp.string();
  return path.string();
}

Expected<std::shared_ptr<SceneSession>> SceneRegistry::open(const v1::OpenSceneRequest& request, Progress* progress,
                                                            const PreviewCallback& on_preview) {
  SessionIdentity identity;
  identity.id = randomToken();
  identity.id[0] = 's';  // ids start with a letter; 60 random bits keep them unique
  identity.id.resize(16);
  identity.token = randomToken();
  identity.name = request.name();
  // An upload that did not open is removed (after a successful open it was renamed away).
  std::string staged;
  struct DropStaged {
    const std::string& path;
    ~DropStaged() {
      if (!path.empty()) ::unlink(path.c_str());
    }
  } drop_staged{staged};
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
    auto stored = storeInlineScene(request.gltf_bytes(), &staged);
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
  const bool preview = request.has_preview() ? request.preview() : config_.preview;
  const PreviewCallback none = [](const std::shared_ptr<SceneSession>&) {};
  auto session = openResident(std::move(identity), request, nullptr, {}, 1, request.lightset_json(), progress, staged,
                              preview ? (on_preview ? &on_preview : &none) : nullptr);
  // The scene is durable before OpenScene answers: its updates are journaled against it.
  if (session) {
    if (Status s = persistNow(); !s) {
      close((*session)->identity().id);
      return ioError("sessions: cannot persist the new scene: {}", s.message());
    }
  }
  return session;
}

Expected<std::shared_ptr<SceneSession>> SceneRegistry::openResident(SessionIdentity identity,
                                                                   const v1::OpenSceneRequest& request,
                                                                   const relight::LightSet* restored_lights,
                                                                   std::vector<lights::Scenario> restored_scenarios,
                                                                   std::uint64_t version,
                                                                   const std::string& lightset_json,
                                                                   Progress* progress,
                                                                   const std::string& staged_upload,
                                                                   const PreviewCallback* on_preview) {
  // The daemon's --bounces is the scene's bounce cap unless the request's options set one.
  relight::RelightOptions relight_defaults;
  relight_defaults.max_bounces = config_.relight_bounces;
  auto bake_options = bakeOptionsFrom(request, relight_defaults);
  if (!bake_options) return bake_options.status();
  if (!v1::Backend_IsValid(request.backend()))
    return invalidInput("backend: {} is not a Backend", static_cast<int>(request.backend()));
  // Parse the light-set JSON before the (long) precompute so a typo fails fast.
  nlohmann::json overrides;
  if (!lightset_json.empty()) {
    overrides = nlohmann::json::parse(lightset_json, nullptr, /*allow_exceptions=*/false);
    if (overrides.is_discarded() || !overrides.is_object())
      return invalidInput("lightset_json: not a JSON object (docs/lightset.md)");
    // Every relight evaluates every light: the cap UpdateLights enforces holds at open too.
    if (const auto it = overrides.find("lights"); it != overrides.end() && it->is_array() &&
                                                 it->size() > kMaxLightsPerScene)
      return resourceExhausted("lightset_json: {} lights is above the limit of {} lights per scene", it->size(),
                               kMaxLightsPerScene);
  }

  precompute::ResidentRequest rr;
  rr.scene_path = staged_upload.empty() ? identity.source_path : staged_upload;
  rr.options = bake_options->precompute;
  rr.cache_dir = config_.cache_dir;
  rr.options.limits.max_texels = config_.max_texels;
  rr.options.limits.max_link_bytes = config_.max_link_bytes;
  rr.load.max_image_pixels = config_.max_image_pixels;
  rr.load.max_triangles = config_.max_triangles;
  rr.load.max_lights = kMaxLightsPerScene;
  SessionOptions so;
  so.scenarios = std::move(restored_scenarios);
  so.backend = backendChoiceName(request.backend(), config_.backend);
  so.relight = bake_options->relight;  // every relight option of the one table, not a chosen few
  so.progressive = config_.progressive;
  so.journal = journal_;
  // The initial light set: the restored one, or the scene's lights with the JSON over them.
  const auto initialLights = [&](const scene::Scene& scene) -> Expected<relight::LightSet> {
    relight::LightSet lights;
    if (restored_lights) {
      lights = *restored_lights;
    } else {
      lights = relight::LightSet::fromSceneLights(scene.lights);
      if (!overrides.is_null()) {
        if (Status s = lights.apply(overrides); !s) return invalidInput("lightset_json: {}", s.message());
      }
    }
    if (Status s = checkMaterials(lights, scene.materials.size(), "lightset_json"); !s) return s;
    // What scenarios need of the scene (their documents apply over its own lights).
    so.scene_lights = relight::LightSet::fromSceneLights(scene.lights);
    so.emissions = scene.materialEmissions();
    if (lights.lights().size() > kMaxLightsPerScene)
      return resourceExhausted("lights: the scene and lightset_json give {} lights, above the limit of {} lights per "
                               "scene", lights.lights().size(), kMaxLightsPerScene);
    return lights;
  };
  // The instant preview, built from the loaded scene before the precompute starts.
  std::shared_ptr<SceneSession> previewed;
  if (on_preview) {
    rr.on_loaded = [&](const scene::Scene& scene) {
      auto lights = initialLights(scene);
      if (!lights) return;  // the open fails with this error after loading
      previewed = startPreview(identity, scene, *bake_options, *lights, version, so);
      if (previewed) (*on_preview)(previewed);
    };
  }
  // A previewed scene whose open fails is removed again: its clients get NOT_FOUND.
  struct DropPreview {
    SceneRegistry& registry;
    std::shared_ptr<SceneSession>& session;
    bool keep = false;
    ~DropPreview() {
      if (session && !keep) registry.close(session->identity().id);
    }
  } drop_preview{*this, previewed};

  // Two opens of the same scene and parameters precompute once: the second waits and reuses.
  auto mutex = openMutexFor(identity.source_path + "|" + bake_options->precompute.canonical());
  std::unique_lock open_lock(*mutex);
  PreviewedProgress open_progress(progress, previewed);
  auto resident = precompute::ResidentScene::open(rr, on_preview ? &open_progress : progress);
  open_lock.unlock();
  if (!resident) {
    if (previewed && previewed->closed() && resident.status().code() == Code::kCancelled)
      return notFound("scene_id: scene '{}' was closed while its links were computed", identity.id);
    return resident.status();
  }

  auto initial = initialLights(resident->scene());
  if (!initial) return initial.status();
  relight::LightSet lights = std::move(initial).value();
  if (!staged_upload.empty()) {
    // The upload loaded: now it is stored under its content name.
    if (::rename(staged_upload.c_str(), identity.source_path.c_str()) != 0)
      return ioError("cannot store the uploaded scene as {}: {}", identity.source_path, std::strerror(errno));
  }
  // Last use of the scene's cache files, for the quota's eviction order.
  touchLastUse(resident->artifactPath());
  if (identity.source_path.rfind(config_.cache_dir, 0) == 0) touchLastUse(identity.source_path);

  const bool reused = resident->reused();
  const std::string note = resident->note();
  const double open_s = resident->openSeconds();
  Expected<std::shared_ptr<SceneSession>> session = internalError("not opened");
  if (previewed) {
    // The session exists (with the updates its clients made meanwhile): it gets the
    // precomputation, and this returns once its linked result is published.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(10);
    if (Status s = previewed->attach(std::move(resident).value(), deadline); !s) return s;
    session = previewed;
    drop_preview.keep = true;
  } else {
    session = SceneSession::start(identity, std::move(resident).value(), std::move(lights), version, so);
    if (!session) return session.status();
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
  // The new artifact may have taken the cache beyond its quota: closed scenes' files go.
  enforceQuota(0);
  return session;
}

std::shared_ptr<SceneSession> SceneRegistry::startPreview(const SessionIdentity& identity, const scene::Scene& scene,
                                                          const bake::BakeOptions& options,
                                                          const relight::LightSet& lights, std::uint64_t version,
                                                          const SessionOptions& so) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto failed = [&](const Status& why) -> std::shared_ptr<SceneSession> {
    logEvent(LogLevel::kWarn, "preview_skipped", {{"scene", identity.id}, {"error", why.message()}});
    return nullptr;
  };
  PreviewScene ps;
  try {
    // A fast BVH: the preview traces a few hundred thousand rays, not the precompute's billions.
    rt::AccelOptions ao;
    ao.quality = rt::AccelOptions::Quality::kFast;
    auto accel = rt::Accel::build(scene, ao);
    if (!accel) return failed(accel.status());
    ps.accel = std::make_unique<rt::Accel>(std::move(accel).value());
    const precompute::PrecomputeOptions& pre = options.precompute;
    preview::PreviewOptions po;
    po.bands = options.relight.bands > 0 ? options.relight.bands : pre.bands;
    po.grid.spacing_m = pre.grid_spacing_m;
    po.grid.resolution = pre.grid_resolution;
    po.grid.validity.rays = pre.validity_rays;
    auto grid = preview::PreviewGrid::build(scene, *ps.accel, po);
    if (!grid) return failed(grid.status());
    ps.grid = std::make_unique<preview::PreviewGrid>(std::move(grid).value());
    ps.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const preview::PreviewStats st = ps.grid->buildStats();
    const int bands = po.bands;
    auto session = SceneSession::startPreview(identity, std::move(ps), lights, version, so, bands,
                                              scene.materials.size());
    if (!session) return failed(session.status());
    {
      std::lock_guard lock(mutex_);
      scenes_[identity.id] = *session;
    }
    // Durable before anyone is told: updates are journaled against it.
    if (Status s = persistNow(); !s) {
      close(identity.id);
      return failed(s);
    }
    logEvent(LogLevel::kInfo, "preview_published",
             {{"scene", identity.id},
              {"version", version},
              {"probes", st.probes},
              {"probes_valid", st.probes_valid},
              {"rays_per_probe", st.rays_per_probe},
              {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}});
    return *session;
  } catch (const std::bad_alloc&) {
    return failed(resourceExhausted("out of memory while building the instant preview"));
  }
}

void SceneRegistry::restore() {
  auto records = loadSessions(sessions_path_);
  if (!records) {
    logEvent(LogLevel::kError, "sessions_unreadable", {{"path", sessions_path_}, {"error", records.status().message()}});
    return;
  }
  // The versions taken since the snapshot, in order, before anything can be journaled anew.
  if (const std::size_t n = replayJournal(*records, journal_->takeRecovered()); n > 0)
    logEvent(LogLevel::kInfo, "journal_replayed", {{"path", journal_->path()}, {"records", n}});
  if (records->empty()) return;
  {
    std::lock_guard lock(mutex_);
    for (const auto& r : *records) restoring_[r.id] = r;
  }
  {
    std::lock_guard lock(persist_mutex_);
    restore_running_ = true;
  }
  logEvent(LogLevel::kInfo, "restore_started", {{"scenes", records->size()}});
  // Re-opening decodes and maps every scene (seconds each for a large one): the daemon
  // listens meanwhile, and calls naming a scene wait for it (waitRestored).
  restore_thread_ = std::thread([this, r = std::move(records).value()]() mutable { restoreAll(std::move(r)); });
}

void SceneRegistry::restoreAll(std::vector<SessionRecord> records) {
  RestoreProgress progress(restore_stop_);
  for (const auto& r : records) {
    if (restore_stop_) return;  // shutdown: the rest stays in sessions.json
    auto params = paramsFromJson(r.params);
    auto lights = relight::LightSet::fromJson(r.lights);
    Status why = !params ? params.status() : !lights ? lights.status() : Status{};
    std::vector<lights::Scenario> scenarios;
    for (const auto& [name, set] : r.scenarios.items()) {
      if (!why) break;
      auto parsed = relight::LightSet::fromJson(set);
      if (!parsed) why = invalidInput("scenarios.{}: {}", name, parsed.status().message());
      else scenarios.push_back({name, std::move(parsed).value()});
    }
    // The roots may have changed since the scene was opened; uploaded scenes live in the cache.
    const bool uploaded = fs::path(r.source_path).parent_path() == fs::path(config_.cache_dir) / "inline";
    if (why && !uploaded)
      if (auto admitted = roots_.admit(r.source_path); !admitted) why = admitted.status();
    if (why) {
      SessionIdentity identity{r.id, r.token, r.name, r.source_path, r.source_label, *params};
      v1::OpenSceneRequest request = *params;
      request.set_path(r.source_path);
      auto opened = openResident(identity, request, &*lights, std::move(scenarios),
                                 std::max<std::uint64_t>(r.version, 1), "", &progress);
      if (!opened) why = opened.status();
    }
    if (restore_stop_ && !why) return;  // cancelled mid-open: the record stays
    {
      std::lock_guard lock(mutex_);
      restoring_.erase(r.id);
    }
    restored_cv_.notify_all();
    if (!why)
      logEvent(LogLevel::kWarn, "scene_not_restored",
               {{"scene", r.id}, {"source", r.source_label}, {"error", why.message()}});
  }
  logEvent(LogLevel::kInfo, "restore_finished", {{"scenes", size()}});
  {
    std::lock_guard lock(persist_mutex_);
    restore_running_ = false;
  }
  markDirty();  // the file now lists exactly the scenes that came back
  enforceQuota(0);
}

std::vector<SceneRegistry::Restoring> SceneRegistry::restoring() const {
  std::lock_guard lock(mutex_);
  std::vector<Restoring> out;
  for (const auto& [id, r] : restoring_)
    if (scenes_.count(id) == 0) out.push_back({r.id, r.token, r.name, r.source_label, r.version});
  return out;
}

std::optional<std::string> SceneRegistry::restoringToken(const std::string& id) const {
  std::lock_guard lock(mutex_);
  const auto it = restoring_.find(id);
  if (it == restoring_.end()) return std::nullopt;
  return it->second.token;
}

bool SceneRegistry::waitRestored(const std::string& id, std::chrono::steady_clock::time_point deadline,
                                 const std::function<bool()>& stop) const {
  std::unique_lock lock(mutex_);
  while (restoring_.count(id) > 0) {
    if (std::chrono::steady_clock::now() >= deadline || stop()) return true;
    restored_cv_.wait_until(lock, std::min(deadline, std::chrono::steady_clock::now() + std::chrono::milliseconds(50)));
  }
  return false;
}

void SceneRegistry::enforceQuota(std::uint64_t incoming) {
  if (config_.cache_quota == 0) return;
  std::vector<std::string> keep;
  {
    std::lock_guard lock(mutex_);
    // A scene still being restored has no known artifact path yet: evict nothing until
    // the restore is over rather than remove what it is about to map.
    if (!restoring_.empty()) return;
    for (const auto& [id, s] : scenes_) {
      if (s->linked()) keep.push_back(s->resident().artifactPath());
      keep.push_back(s->identity().source_path);
    }
  }
  const EvictionReport r = enforceCacheQuota(config_.cache_dir, config_.cache_quota, incoming, keep);
  for (const auto& path : r.removed) logEvent(LogLevel::kInfo, "cache_evicted", {{"path", path}});
  if (r.bytes_after + incoming > config_.cache_quota)
    logEvent(LogLevel::kWarn, "cache_over_quota",
             {{"bytes", r.bytes_after + incoming}, {"quota", config_.cache_quota},
              {"reason", "the rest belongs to resident scenes"}});
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
  std::size_t n = scenes_.size();
  for (const auto& [id, r] : restoring_) n += scenes_.count(id) == 0 ? 1 : 0;
  return n;
}

std::size_t SceneRegistry::sizeWithoutPreviews() const {
  std::lock_guard lock(mutex_);
  std::size_t n = 0;
  for (const auto& [id, s] : scenes_) n += s->linked() ? 1 : 0;
  for (const auto& [id, r] : restoring_) n += scenes_.count(id) == 0 ? 1 : 0;
  return n;
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
  const std::string artifact = s->linked() ? s->resident().artifactPath() : std::string();
  s->close();
  if (!artifact.empty()) touchLastUse(artifact);  // last use, for the quota's eviction order
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
  // Snapshot and write under one lock: a later snapshot is never overwritten by an earlier.
  std::lock_guard lock(write_mutex_);
  std::vector<SessionRecord> records;
  // Scenes not restored yet keep their record (one list, under the lock, so a scene that
  // just came back is neither missed nor written twice).
  std::vector<std::shared_ptr<SceneSession>> resident;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, s] : scenes_) resident.push_back(s);
    for (const auto& [id, r] : restoring_)
      if (scenes_.count(id) == 0) records.push_back(r);
  }
  for (const auto& s : resident) {
    const auto& id = s->identity();
    SessionRecord r;
    r.id = id.id;
    r.token = id.token;
    r.name = id.name;
    r.source_path = id.source_path;
    r.source_label = id.source_label;
    r.params = paramsToJson(id.params);
    r.lights = s->persistentLights(&r.version);
    r.scenarios = s->persistentScenarios();
    records.push_back(std::move(r));
  }
  return saveSessions(sessions_path_, records);
}

Status SceneRegistry::compact() {
  return journal_->compact([this] { return persistNow(); });
}

void SceneRegistry::persistLoop() {
  std::unique_lock lock(persist_mutex_);
  while (true) {
    persist_cv_.wait(lock, [&] { return (dirty_ && !restore_running_) || persist_stop_; });
    if (persist_stop_) return;  // shutdown() writes the final state itself
    dirty_ = false;
    lock.unlock();
    if (Status s = compact(); !s)
      logEvent(LogLevel::kError, "sessions_write_failed", {{"path", sessions_path_}, {"error", s.message()}});
    lock.lock();
  }
}

}  // namespace lightlink::service
