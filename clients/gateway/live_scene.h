// LiveScene: one bake made live on a daemon, for the gateway (gateway.h). Opening reads the
// bake's report.json `source` (scene path, bake options, light set) and opens that scene
// with those options; the daemon answers with the artifact's cache key, which must be the
// bake's, or the lightmap atlas the page draws with would not be the daemon's. The bake's
// light set (lights.json) and its scenarios (scenarios/<name>/lights.json) are then given to
// the daemon, so the first live version lights the scene as the bake did.
//
// A thread follows the scene's Subscribe stream and writes every version it receives into
// `<work>/v<N>/` (EXR layout 2, grid.raw: what the page reads from a bake), keeping the
// newest few. Waiters (the pages' event streams) are woken per version.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "clients/client/client.h"
#include "core/common/status.h"

namespace lightlink::gateway {

// One result as files, announced to pages.
struct LiveVersion {
  std::uint64_t version = 0;
  std::filesystem::path dir;
  std::vector<std::string> files;
  nlohmann::json lighting;   // LIGHTLINK_lighting description of `files`
  double relight_ms = 0.0;
  double write_ms = 0.0;     // the gateway writing the files
  // The daemon's light set of this version (GetLights), whoever changed it; null when the
  // set had moved on by the time it was asked for (the next version brings it).
  nlohmann::json lights;
};

class LiveScene {
 public:
  // `bake_dir` is a bake folder (canonical); `work_dir` this scene's own folder (created).
  static Expected<std::unique_ptr<LiveScene>> open(client::Client& client, const std::filesystem::path& bake_dir,
                                                   const std::filesystem::path& work_dir, int keep_versions);
  ~LiveScene();

  const client::SceneHandle& handle() const { return handle_; }
  // What a page needs to start: ids, tokens, the light set (asked of the daemon), the light
  // -> glTF node map, scenario names and the newest version (when one was written).
  nlohmann::json describe() const;

  // A light-set document (docs/lightset.md) applied over the current lights; returns the
  // version it becomes.
  Expected<std::uint64_t> updateLights(const std::string& light_set_json);
  // Weighted blend of the scene's scenarios (names as the bake wrote them).
  Expected<std::uint64_t> useScenarios(const std::vector<lights::ScenarioWeight>& weights);

  // The newest version above `after`, waiting up to `timeout`; nullopt on timeout or close.
  std::optional<LiveVersion> waitNewer(std::uint64_t after, std::chrono::milliseconds timeout);
  std::optional<LiveVersion> find(std::uint64_t version) const;
  // Ends the stream and wakes every waiter; the daemon scene is closed too.
  void close();
  bool closed() const { return closed_; }
  // False once closed or once the daemon ended the stream (a restart, the scene closed by
  // another client): the gateway then opens the bake again.
  bool usable() const { return !closed_ && !ended_; }

 private:
  LiveScene(client::Client& client, std::filesystem::path work_dir, int keep);
  void follow();

  client::Client& client_;
  std::filesystem::path work_dir_;
  int keep_;
  client::SceneHandle handle_;
  nlohmann::json light_nodes_ = nlohmann::json::object();
  std::vector<std::string> scenarios_;
  std::vector<std::string> own_light_ids_;

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<LiveVersion> versions_;
  mutable std::mutex update_mutex_;     // one update at a time (the handle's light ids)
  std::unique_ptr<client::Subscription> subscription_;
  std::thread follower_;
  std::atomic<bool> closed_{false};
  std::atomic<bool> ended_{false};
};

}  // namespace lightlink::gateway
