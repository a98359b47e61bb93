// SceneRegistry: the daemon's resident scenes by id — opening (load or precompute through
// ResidentScene, then a SceneSession), lookup, closing, and persistence.
//
// Restore is lazy: restore() only reads sessions.json and re-opens the scenes on a
// background thread, so a restarted daemon listens at once. A scene still being restored
// is listed and counted, and a call naming it waits for it (waitRestored).
//
// Persistence: sessions.json is the snapshot (scenes, tokens, parameters, light sets) and
// `sessions.journal` (UpdateJournal) every light-set version taken since. An open is in
// sessions.json before OpenScene answers; an update is in the journal before UpdateLights
// answers (SceneSession). A background thread compacts (rewrites sessions.json, empties the
// journal) when the journal grows past kCompactBytes or a scene closes; shutdown compacts
// a last time. Restore reads the snapshot and replays the journal over it (synchronously,
// before listening) and only then re-opens the scenes in the background.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/bake/bake_options.h"
#include "core/common/progress.h"
#include "core/common/status.h"
#include "proto/lightlink.pb.h"
#include "service/config.h"
#include "service/scene_roots.h"
#include "service/scene_session.h"
#include "service/session_store.h"
#include "service/update_journal.h"

namespace lightlink::service {

class SceneRegistry {
 public:
  explicit SceneRegistry(const DaemonConfig& config);
  ~SceneRegistry();
  SceneRegistry(const SceneRegistry&) = delete;
  SceneRegistry& operator=(const SceneRegistry&) = delete;

  // Where OpenScene may name a scene by path (open() checks it too).
  const SceneRoots& sceneRoots() const { return roots_; }
  // Called once when an open publishes its instant preview: the session is registered (and
  // persisted) and its first result is the preview.
  using PreviewCallback = std::function<void(const std::shared_ptr<SceneSession>&)>;
  // Opens a scene (request validated here); `progress` sees the precompute stages. With the
  // instant preview on (--preview, OpenSceneRequest.preview), the scene is registered with its
  // preview as soon as it is loaded (`on_preview` is told), and the session is linked when the
  // precomputation is ready; returns once the linked result is published. A failed open
  // removes the previewed scene again.
  Expected<std::shared_ptr<SceneSession>> open(const v1::OpenSceneRequest& request, Progress* progress,
                                               const PreviewCallback& on_preview = {});
  // Re-opens the scenes of sessions.json (same ids, tokens, light sets, versions) on a
  // background thread and returns at once. Scenes that cannot be re-opened are logged and
  // dropped.
  void restore();
  // A scene of sessions.json not re-opened yet, as ListScenes shows it.
  struct Restoring {
    std::string id, token, name, source_label;
    std::uint64_t version = 0;
  };
  std::vector<Restoring> restoring() const;
  // The scene token of `id` while it is being restored, nullopt otherwise.
  std::optional<std::string> restoringToken(const std::string& id) const;
  // Waits while `id` is being restored, until `deadline` or `stop()`; polls `stop` every
  // ~50 ms. True when the scene is still being restored then.
  bool waitRestored(const std::string& id, std::chrono::steady_clock::time_point deadline,
                    const std::function<bool()>& stop) const;

  std::shared_ptr<SceneSession> find(const std::string& id) const;
  std::vector<std::shared_ptr<SceneSession>> list() const;
  // Resident scenes plus those still being restored.
  std::size_t size() const;
  // size() without the scenes showing their instant preview (their open still runs, and is
  // counted as an open).
  std::size_t sizeWithoutPreviews() const;
  // Removes and closes a scene. False when no such scene.
  bool close(const std::string& id);
  // Stops the background writer, writes sessions.json a last time and closes every scene.
  // Idempotent; the destructor calls it.
  Status shutdown();

  // Something persistent changed (a close): the background thread compacts.
  void markDirty();
  // Writes sessions.json now (blocking), the journal kept.
  Status persistNow();
  // Writes sessions.json and empties the journal (blocking).
  Status compact();

  // The journal is compacted once it holds this many bytes.
  static constexpr std::uint64_t kCompactBytes = 4u << 20;

 private:
  Expected<std::shared_ptr<SceneSession>> openResident(SessionIdentity identity, const v1::OpenSceneRequest& request,
                                                       const relight::LightSet* restored_lights,
                                                       std::vector<lights::Scenario> restored_scenarios,
                                                       std::uint64_t restored_version,
                                                       const std::string& lightset_json, Progress* progress,
                                                       const std::string& staged_upload = {},
                                                       const PreviewCallback* on_preview = nullptr);
  // Builds the instant preview of a loaded scene and registers its session (persisted).
  // Null when it cannot (logged): the open goes on without a preview.
  std::shared_ptr<SceneSession> startPreview(const SessionIdentity& identity, const scene::Scene& scene,
                                             const bake::BakeOptions& options, const relight::LightSet& lights,
                                             std::uint64_t version, const SessionOptions& so);
  Expected<std::string> storeInlineScene(const std::string& bytes, std::string* staged);
  void restoreAll(std::vector<SessionRecord> records);
  // Removes closed scenes' cache files beyond the quota (`incoming`: bytes about to be written).
  void enforceQuota(std::uint64_t incoming);
  std::shared_ptr<std::mutex> openMutexFor(const std::string& key);
  void persistLoop();
  void closeAll();

  DaemonConfig config_;
  SceneRoots roots_;  // where OpenScene may name a scene by path
  std::string sessions_path_;
  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<SceneSession>> scenes_;
  std::size_t opening_ = 0;  // opens in flight, counted against max_scenes
  std::map<std::string, std::shared_ptr<std::mutex>> open_mutexes_;
  std::map<std::string, SessionRecord> restoring_;  // by id, until re-opened or dropped
  mutable std::condition_variable restored_cv_;     // with mutex_: a restore finished
  std::atomic<bool> restore_stop_{false};
  std::thread restore_thread_;

  std::shared_ptr<UpdateJournal> journal_;
  std::mutex persist_mutex_;
  std::condition_variable persist_cv_;
  bool dirty_ = false, persist_stop_ = false;
  bool restore_running_ = false;  // no compaction while the restore has scenes left to open
  bool shut_down_ = false;
  std::mutex write_mutex_;  // one writer of sessions.json at a time
  std::thread persist_thread_;
};

}  // namespace lightlink::service
