// ResidentScene: "open or precompute" — everything a relight needs, loaded once and kept.
//
// Shared by `lightlink bake` (one relight, then exit) and the daemon (many relights of a
// scene that stays resident). Given a scene file, precompute options and a cache directory
// it loads the scene, computes the artifact cache key (scene bytes + options + format
// version), reuses a matching artifact when one opens cleanly (every section checksum is
// verified by precompute::open), and otherwise unwraps, precomputes and saves the artifact
// atomically under its key. A damaged or mismatching cached artifact is recomputed and
// replaced, never served.
//
// The relight keeps references to the scene, the Embree scene and the precomputation, so
// they live on the heap behind one pointer: moving a ResidentScene (into a session, a
// container) never moves what a Relighter or a GPU backend points at.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/common/progress.h"
#include "core/common/status.h"
#include "core/links/links.h"
#include "core/precompute/precompute.h"
#include "core/rt/accel.h"
#include "core/scene/load.h"
#include "core/scene/scene.h"

namespace lightlink::precompute {

struct ResidentRequest {
  std::string scene_path;   // .gltf / .glb
  PrecomputeOptions options;
  std::string cache_dir;    // artifacts as <cache_dir>/<key hex>.llk; created when missing
  bool use_cache = true;    // false: recompute even when a matching artifact exists (and replace it)
  // How the scene is loaded: which files it may name (default: its own folder only) and its
  // budgets (image size, triangles, lights).
  scene::LoadOptions load;
  // Called once the scene is loaded (surface rules applied), before the artifact is opened
  // or the precompute starts, on the opening thread: the daemon builds its instant preview
  // here (core/preview) without loading the scene twice. The scene is changed afterwards
  // (the unwrap writes uv1), so the callback must not keep a reference to it.
  std::function<void(const scene::Scene&)> on_loaded;
};

class ResidentScene {
 public:
  // Loads or precomputes. `progress` receives the stages "load", "artifact" and, when
  // precomputing, those of precompute::run; its cancelled() stops a precompute early
  // (Code::kCancelled). std::bad_alloc in any stage becomes Code::kResourceExhausted.
  static Expected<ResidentScene> open(const ResidentRequest& request, Progress* progress = nullptr);

  ResidentScene(ResidentScene&&) noexcept;
  ResidentScene& operator=(ResidentScene&&) noexcept;
  ~ResidentScene();

  // The scene as the artifact was made on it (uv1 from the same unwrap).
  const scene::Scene& scene() const;
  const rt::Accel& accel() const;
  const Precomputation& precomputation() const;
  // Views of the links: in the artifact mapping (reused) or in precomputation() (computed).
  links::LinksView lightmapLinks() const;
  links::LinksView gridLinks() const;
  const charts::LightmapAtlas& atlas() const;

  std::uint64_t cacheKey() const;
  std::string cacheKeyHex() const;
  const std::string& artifactPath() const;
  std::uint64_t artifactBytes() const;  // size of the artifact file
  bool reused() const;                  // true: loaded from the cache, nothing precomputed
  // "reused <path>", "computed <path>" or "recomputed: cached artifact unusable (<why>)".
  const std::string& note() const;
  // The precompute report (computed) or the artifact's metadata (reused).
  nlohmann::ordered_json precomputeReport() const;
  // The load stage (scene ingest and cache key): seconds, resident memory before it and the
  // process's peak after it (the peak is the load's own when nothing earlier in the process
  // used more, as in `lightlink bake`), and what was decoded (Scene::stats).
  nlohmann::ordered_json loadReport() const;
  double openSeconds() const;

 private:
  struct State;
  explicit ResidentScene(std::unique_ptr<State> state);
  static Expected<ResidentScene> openUnguarded(const ResidentRequest& request, Progress* progress);
  std::unique_ptr<State> state_;
};

}  // namespace lightlink::precompute
