#include "core/precompute/resident.h"

#include <chrono>
#include <filesystem>
#include <new>
#include <optional>

#include <fmt/format.h>

#include "core/artifact/artifact.h"
#include "core/common/private_files.h"
#include "core/common/process_memory.h"
#include "core/scene/load.h"

namespace lightlink::precompute {

namespace fs = std::filesystem;

struct ResidentScene::State {
  scene::Scene scene;
  std::optional<rt::Accel> accel;
  // Exactly one of the two holds the precomputation.
  std::optional<LoadedPrecomputation> loaded;
  std::optional<Precomputation> computed;
  charts::LightmapAtlas atlas;
  std::uint64_t key = 0;
  std::string artifact_path;
  std::uint64_t artifact_bytes = 0;
  std::string note;
  double open_seconds = 0.0;
  double load_seconds = 0.0;
  std::uint64_t rss_before_load = 0, peak_rss_after_load = 0;
};

namespace {

// A stage with no measurable units, so a progress sink sees where we are and how long it took.
class Stage {
 public:
  Stage(Progress* progress, const char* name) : progress_(progress) {
    if (progress_ != nullptr) progress_->begin(name, 0);
  }
  ~Stage() {
    if (progress_ != nullptr) progress_->end();
  }
  Stage(const Stage&) = delete;
  Stage& operator=(const Stage&) = delete;

 private:
  Progress* progress_;
};

}  // namespace

Expected<ResidentScene> ResidentScene::open(const ResidentRequest& request, Progress* progress) {
  // precompute::run names the stage that ran out of memory; this catches the rest (loading,
  // opening an artifact, the BVH) so that no request ends the process.
  try {
    return openUnguarded(request, progress);
  } catch (const std::bad_alloc&) {
    return resourceExhausted("{}: out of memory while opening the scene", request.scene_path);
  }
}

Expected<ResidentScene> ResidentScene::openUnguarded(const ResidentRequest& request, Progress* progress) {
  const auto start = std::chrono::steady_clock::now();
  if (Status s = request.options.validate(); !s) return s;
  if (request.cache_dir.empty()) return invalidInput("cache directory: must not be empty");
  {
    if (Status s = createPrivateDirectories(request.cache_dir); !s)
      return ioError("cache directory: {}", s.message());
  }
  auto state = std::make_unique<State>();

  {
    Stage stage(progress, "load");
    const auto load_start = std::chrono::steady_clock::now();
    state->rss_before_load = residentBytes();
    auto scene = scene::loadScene(request.scene_path, request.load);
    if (!scene) return scene.status();
    scene::applySurfaceRules(*scene, request.options.surfaces);
    state->scene = std::move(scene).value();
    auto key = cacheKeyFor(request.scene_path, request.options, request.load.files);
    if (!key) return key.status();
    state->key = *key;
    state->peak_rss_after_load = peakResidentBytes();
    state->load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - load_start).count();
  }
  if (request.on_loaded && !stopRequested(progress)) request.on_loaded(state->scene);
  if (stopRequested(progress)) return cancelled("open cancelled after loading {}", request.scene_path);
  const std::uint64_t key = state->key;
  state->artifact_path = (fs::path(request.cache_dir) / (artifact::cacheKeyHex(key) + ".llk")).string();

  // Reuse a matching artifact when it opens cleanly (all checksums verified); a damaged
  // or foreign one is recomputed and replaced atomically, never used.
  if (request.use_cache && fs::exists(state->artifact_path)) {
    Stage stage(progress, "artifact");
    auto opened = precompute::open(state->artifact_path);
    if (opened && opened->file.cacheKey() == key) {
      state->loaded.emplace(std::move(opened).value());
      state->note = "reused " + state->artifact_path;
    } else {
      state->note = fmt::format("recomputed: cached artifact unusable ({})",
                                opened ? "key mismatch" : opened.status().message());
    }
  }
  if (state->loaded) {
    // The artifact was made on the unwrapped scene: give this scene the same uv1.
    auto unwrapped = unwrapFor(state->scene, request.options, progress);
    if (!unwrapped) return unwrapped.status();
    state->atlas = unwrapped->atlas;
  } else {
    auto p = run(state->scene, request.options, progress);
    if (!p) return p.status();
    state->computed.emplace(std::move(p).value());
    state->atlas = state->computed->atlas;
    if (Status s = save(*state->computed, state->artifact_path, key); !s) return s;
    if (state->note.empty()) state->note = "computed " + state->artifact_path;
  }
  std::error_code ec;
  state->artifact_bytes = fs::file_size(state->artifact_path, ec);
  if (ec) state->artifact_bytes = 0;

  // After the unwrap: seam splits change the triangles the BVH must hold.
  auto accel = rt::Accel::build(state->scene);
  if (!accel) return accel.status();
  state->accel.emplace(std::move(accel).value());
  state->open_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return ResidentScene(std::move(state));
}

ResidentScene::ResidentScene(std::unique_ptr<State> state) : state_(std::move(state)) {}
ResidentScene::ResidentScene(ResidentScene&&) noexcept = default;
ResidentScene& ResidentScene::operator=(ResidentScene&&) noexcept = default;
ResidentScene::~ResidentScene() = default;

const scene::Scene& ResidentScene::scene() const { return state_->scene; }
const rt::Accel& ResidentScene::accel() const { return *state_->accel; }
const Precomputation& ResidentScene::precomputation() const {
  return state_->loaded ? state_->loaded->p : *state_->computed;
}
links::LinksView ResidentScene::lightmapLinks() const {
  return state_->loaded ? state_->loaded->lightmap_links : state_->computed->lightmap_links.view();
}
links::LinksView ResidentScene::gridLinks() const {
  return state_->loaded ? state_->loaded->grid_links : state_->computed->grid_links.view();
}
const charts::LightmapAtlas& ResidentScene::atlas() const { return state_->atlas; }
std::uint64_t ResidentScene::cacheKey() const { return state_->key; }
std::string ResidentScene::cacheKeyHex() const { return artifact::cacheKeyHex(state_->key); }
const std::string& ResidentScene::artifactPath() const { return state_->artifact_path; }
std::uint64_t ResidentScene::artifactBytes() const { return state_->artifact_bytes; }
bool ResidentScene::reused() const { return state_->loaded.has_value(); }
const std::string& ResidentScene::note() const { return state_->note; }
double ResidentScene::openSeconds() const { return state_->open_seconds; }

nlohmann::ordered_json ResidentScene::loadReport() const {
  const scene::SceneStats& st = state_->scene.stats;
  nlohmann::ordered_json j;
  j["seconds"] = state_->load_seconds;
  j["rss_before_bytes"] = state_->rss_before_load;
  j["peak_rss_after_bytes"] = state_->peak_rss_after_load;
  j["triangles"] = st.triangles_in;
  j["images_decoded"] = st.images_decoded;
  j["images_skipped"] = st.images_skipped;
  j["image_bytes"] = st.image_bytes;
  j["warnings"] = state_->scene.warnings.size();
  return j;
}

nlohmann::ordered_json ResidentScene::precomputeReport() const {
  return state_->computed ? state_->computed->report() : nlohmann::ordered_json(state_->loaded->meta);
}

}  // namespace lightlink::precompute
