// SceneRegistry: the daemon's resident scenes by id — opening (load or precompute through
// ResidentScene, then a SceneSession), lookup, closing, and persistence to sessions.json.
//
// Persistence runs on its own thread: a change marks the registry dirty and the thread
// rewrites sessions.json (atomically) as soon as the previous write is done, so bursts of
// UpdateLights cost one write, not one per update, and no handler waits for a disk.
#pragma once

#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "core/common/progress.h"
#include "core/common/status.h"
#include "proto/lightlink.pb.h"
#include "service/config.h"
#include "service/scene_roots.h"
#include "service/scene_session.h"

namespace lightlink::service {

class SceneRegistry {
 public:
  explicit SceneRegistry(const DaemonConfig& config);
  ~SceneRegistry();
  SceneRegistry(const SceneRegistry&) = delete;
  SceneRegistry& operator=(const SceneRegistry&) = delete;

  // Where OpenScene may name a scene by path (open() checks it too).
  const SceneRoots& sceneRoots() const { return roots_; }
  // Opens a scene (request validated here); `progress` sees the precompute stages.
  Expected<std::shared_ptr<SceneSession>> open(const v1::OpenSceneRequest& request, Progress* progress);
  // Re-opens the scenes of sessions.json (same ids, tokens, light sets, versions). Scenes
  // that cannot be re-opened are logged and dropped.
  void restore();

  std::shared_ptr<SceneSession> find(const std::string& id) const;
  std::vector<std::shared_ptr<SceneSession>> list() const;
  std::size_t size() const;
  // Removes and closes a scene. False when no such scene.
  bool close(const std::string& id);
  // Stops the background writer, writes sessions.json a last time and closes every scene.
  // Idempotent; the destructor calls it.
  Status shutdown();

  // Something persistent changed (a light update): sessions.json will be rewritten.
  void markDirty();
  // Writes sessions.json now (blocking).
  Status persistNow();

 private:
  Expected<std::shared_ptr<SceneSession>> openResident(SessionIdentity identity, const v1::OpenSceneRequest& request,
                                                       const relight::LightSet* restored_lights,
                                                       std::uint64_t restored_version,
                                                       const std::string& lightset_json, Progress* progress);
  Expected<std::string> storeInlineScene(const std::string& bytes);
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

  std::mutex persist_mutex_;
  std::condition_variable persist_cv_;
  bool dirty_ = false, persist_stop_ = false;
  bool shut_down_ = false;
  std::mutex write_mutex_;  // one writer of sessions.json at a time
  std::thread persist_thread_;
};

}  // namespace lightlink::service
