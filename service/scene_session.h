// SceneSession: one resident scene in the daemon — its precomputation (ResidentScene), its
// current LightSet and version, its relight backend, and the one worker thread that
// relights it.
//
// Versions and coalescing (proto/lightlink.proto "Versions"). Every accepted update
// replaces the light set atomically and takes the next version (monotonic, persisted, so
// it keeps growing across daemon restarts). With a journal (SessionOptions::journal) a new
// version is first appended to it and becomes visible (to the worker, readers, and the
// client's answer) only once it is on disk; until then it is "in flight", and later updates
// build on it. A failed write drops it and every in-flight version after it: the update
// fails, the light set and the version counter stay where the durable state is.
//
// The worker always relights the *latest* light set: updates that arrive while it runs are
// folded into the next relight, so a result exists for the versions the worker computed,
// and the result for version v contains every update acknowledged with a version <= v.
// Results are published as immutable shared snapshots; waiting readers are woken on each
// publish.
//
// Progressive (SessionOptions::progressive, with bounces enabled): the worker relights the
// newest light set with one bounce iteration started from the last solution
// (RelightOptions::warm_start: seed 000's progressive multi-bounce) and publishes it as a
// `preview`; then, while no update arrives, it takes the next version itself (under the same
// lock as updates, so versions stay unique and increasing) and publishes more iterations
// under it — 2, 4, 8 ... per version — until the iteration converges (bounce_threshold) or
// the bounce cap is near, when the cold relight a non-progressive daemon gives ends it. Each
// result says its `residual` and `iterations`. An update that arrives during a relight waits
// for it; one that arrives before the next skips the rest, so a designer dragging a light
// sees one-iteration previews and the converged result when the drag stops.
//
// Instant preview (startPreview, docs/service.md "Preview while the precompute runs"): a
// session can start before its precomputation exists, from the loaded scene's BVH and a
// preview::PreviewGrid. It publishes the preview grid (Snapshot::instant_preview) for its
// initial version at once, and the worker re-lights the preview for every update while the
// precompute runs (a preview relight is shadow rays and an SH projection, tens of ms). attach()
// hands it the ResidentScene: the worker makes the backend, takes the next version for the
// newest light set (durable first, like takeVersion) unless an update already waits, relights it
// with the links and publishes it; from then on the session is an ordinary one and the preview
// state is freed. Updates accepted during the preview are in the light set the linked relight
// computes.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <mutex>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "core/common/status.h"
#include "core/precompute/resident.h"
#include "core/relight/backend.h"
#include "gpu/backend_factory.h"
#include "core/lights/scenarios.h"
#include "core/relight/light_set.h"
#include "core/rt/accel.h"
#include "proto/lightlink.pb.h"
#include "service/snapshot.h"
#include "service/update_journal.h"

namespace lightlink::preview {
class PreviewGrid;
}

namespace lightlink::service {

// What an instant-preview session lights before its precomputation exists: the loaded
// scene's BVH and the preview grid traced against it (which keeps a reference to `accel`).
struct PreviewScene {
  std::unique_ptr<rt::Accel> accel;
  std::unique_ptr<preview::PreviewGrid> grid;
  double build_seconds = 0.0;  // BVH and probe rays
  PreviewScene();
  PreviewScene(PreviewScene&&) noexcept;
  PreviewScene& operator=(PreviewScene&&) noexcept;
  ~PreviewScene();
};

// Who the session is and how it was opened: what sessions.json records.
struct SessionIdentity {
  std::string id;
  std::string token;
  std::string name;
  std::string source_path;     // the file the scene was loaded from (inline bytes: a cache file)
  std::string source_label;    // path, or "<inline N bytes>"
  v1::OpenSceneRequest params; // precompute parameters and backend (no source, no lightset_json)
};

// How a session relights.
struct SessionOptions {
  std::string backend;                 // auto | cpu | gpu
  relight::RelightOptions relight;     // max_bounces: the converged result's bounce cap
  bool progressive = false;            // one-iteration preview first, then more (only when max_bounces > 0)
  // Where new versions are made durable before they are visible (the progressive converged
  // version too: clients see it, so a restarted daemon must not hand it out again). Null:
  // versions are visible at once (in-process tools and tests).
  std::shared_ptr<UpdateJournal> journal;
  // Lighting scenarios: the base a scenario's light-set document applies over (the scene's
  // own lights), each material's emission (for blends), and the scenarios a restart restores.
  relight::LightSet scene_lights;
  std::vector<lights::MaterialEmission> emissions;
  std::vector<lights::Scenario> scenarios;
};

struct SessionStats {
  std::uint64_t version = 0, result_version = 0;
  std::uint64_t updates = 0, relights = 0, coalesced = 0, relight_errors = 0;
  std::uint64_t previews = 0;  // progressive: results not yet converged among `relights`
  std::uint64_t instant_previews = 0;  // instant-preview results (not counted in `relights`)
  double last_relight_ms = 0.0, mean_relight_ms = 0.0;
  std::uint64_t resident_bytes = 0, artifact_bytes = 0;
  std::uint32_t subscribers = 0;
};

class SceneSession {
 public:
  using Clock = std::chrono::steady_clock;

  // Takes the resident scene and the initial light set (version `initial_version`), makes
  // the backend and starts the worker, which computes the initial result at once.
  static Expected<std::shared_ptr<SceneSession>> start(SessionIdentity identity, precompute::ResidentScene resident,
                                                      relight::LightSet lights, std::uint64_t initial_version,
                                                      const SessionOptions& options);
  // An instant-preview session (see above): lights and publishes the preview for
  // `initial_version` before returning (its failure is this call's), then starts the worker.
  // `bands` and `material_count` are what the precomputation will have (SH bands of every
  // result, materials emissive overrides may name).
  static Expected<std::shared_ptr<SceneSession>> startPreview(SessionIdentity identity, PreviewScene preview,
                                                             relight::LightSet lights, std::uint64_t initial_version,
                                                             const SessionOptions& options, int bands,
                                                             std::size_t material_count);
  // Ends an instant-preview session's preview: the worker makes the backend for `resident` and
  // publishes the linked result under a new version. Returns once that result is published,
  // or with the error that prevented it (no backend, the relight failed, the session closed,
  // `deadline`).
  Status attach(precompute::ResidentScene resident, Clock::time_point deadline);
  ~SceneSession();
  SceneSession(const SceneSession&) = delete;
  SceneSession& operator=(const SceneSession&) = delete;

  const SessionIdentity& identity() const { return identity_; }
  // The precomputation; only once linked() (an instant-preview session before attach() has none).
  const precompute::ResidentScene& resident() const { return *resident_; }
  bool linked() const { return linked_.load(std::memory_order_acquire); }
  // Copies: an instant-preview session changes them when it is linked.
  std::string backendName() const {
    std::lock_guard lock(mutex_);
    return backend_name_;
  }
  std::string backendNote() const {
    std::lock_guard lock(mutex_);
    return backend_note_;
  }
  int bands() const { return bands_; }
  std::vector<std::string> lightIds() const;

  // Validates and applies an update (all or nothing); returns the version it created, once
  // that version is durable. A failed write is the journal's error, and nothing changed.
  Expected<std::uint64_t> update(const v1::UpdateLightsRequest& request);

  // Lighting scenarios (proto SetScenario / UseScenarios). setScenario returns the sorted
  // names afterwards; `previous` gets what the name held before (for a rollback when the
  // change cannot be persisted: restoreScenario). useScenarios makes the blend the light set
  // of a new version, as update does.
  Expected<std::vector<std::string>> setScenario(const v1::SetScenarioRequest& request,
                                                 std::optional<relight::LightSet>* previous);
  void restoreScenario(const std::string& name, std::optional<relight::LightSet> previous);
  Expected<std::uint64_t> useScenarios(const v1::UseScenariosRequest& request);
  std::vector<std::string> scenarioNames() const;
  nlohmann::ordered_json persistentScenarios() const;  // name -> LightSet::toJson, for sessions.json

  std::uint64_t version() const;
  std::shared_ptr<const Snapshot> latest() const;

  // Waits until a result with version >= `min_version` exists (the newest one is returned),
  // until `deadline`, until the session closes or `stop()` turns true (polled every ~50 ms).
  // Returns null when none arrived.
  std::shared_ptr<const Snapshot> waitForVersion(std::uint64_t min_version, Clock::time_point deadline,
                                                 const std::function<bool()>& stop) const;
  // Waits for a result with sequence > `after_sequence` (Subscribe); same exits as above.
  std::shared_ptr<const Snapshot> waitForNewer(std::uint64_t after_sequence, Clock::time_point deadline,
                                               const std::function<bool()>& stop) const;

  // Wakes every waiter (drain) so it re-checks its stop condition.
  void wakeAll() const;
  // Stops the worker; waiters return. Idempotent.
  void close();
  bool closed() const { return closed_.load(); }

  SessionStats stats() const;
  void addSubscriber(int delta) {
    subscribers_ += delta;
    touch();
  }

  // The newest (visible) light set and its version (GetLights).
  relight::LightSet lightSet(std::uint64_t* version) const;

  // Client activity, for the daemon's idle timeout (--session-idle-timeout): every call that
  // names the scene touches it. idleFor() is how long no call did, zero while a Subscribe
  // stream is open (a subscribed editor is a client even when it sends nothing).
  void touch() { last_activity_ns_.store(Clock::now().time_since_epoch().count(), std::memory_order_relaxed); }
  Clock::duration idleFor() const {
    if (subscribers_.load() > 0) return Clock::duration::zero();
    return Clock::now() - Clock::time_point(Clock::duration(last_activity_ns_.load(std::memory_order_relaxed)));
  }

  // The durable light set and version, for sessions.json.
  nlohmann::ordered_json persistentLights(std::uint64_t* version) const;

 private:
  SceneSession(SessionIdentity identity, relight::LightSet lights, std::uint64_t version, const SessionOptions& options,
               int bands, std::size_t material_count);
  void workerLoop();
  // Instant preview: relights the preview for every new version until attach() (true) or close (false).
  bool previewLoop();
  // After attach: the backend, the linked result's version, then workerLoop.
  void linkedStart();
  // One preview relight of `lights` for version `v`, published; false when it failed.
  bool previewAndPublish(const relight::LightSet& lights, std::uint64_t v, std::uint64_t coalesced);
  // Runs `light` (a relight or the preview's) on the worker thread and times it into `ms`;
  // a failure, out of memory included, is counted and logged as `event` and gives false.
  bool lightOnWorker(std::uint64_t v, const char* what, const char* event, double& ms,
                     const std::function<Status()>& light);
  void publish(std::shared_ptr<const Snapshot> snap, double ms);
  // Makes the in-flight versions whose commit is done visible, in order, and drops the rest
  // from the first failed one on. Needs mutex_ held.
  void settleInFlight() const;
  // update()'s body: `change` edits a copy of the newest light set (all or nothing), which
  // becomes a new version once durable.
  Expected<std::uint64_t> commit(const std::function<Status(relight::LightSet&)>& change);
  // One relight of `lights` for version `v`, published as a snapshot; false when it failed
  // (logged, counted).
  // Where a progressive light change's iterations stand.
  struct Progress {
    int iterations = 0;       // bounce iterations since the light change
    bool converged = false;   // the last result is final (threshold met, or the cold relight)
    bool final_cold = false;  // the next relight is the cold one that ends the progression
  };
  // `progress` (progressive only) is advanced and decides the result's preview flag.
  bool relightAndPublish(const relight::LightSet& lights, std::uint64_t v, std::uint64_t coalesced,
                         const relight::RelightOptions& options, Progress* progress, relight::RelightResult& result);
  // The version after `v` for the same lights, taken by the worker (durable first with a
  // journal); 0 when an update arrived meanwhile or it could not be persisted.
  std::uint64_t takeVersion(std::uint64_t v, const relight::LightSet& lights);
  std::shared_ptr<const Snapshot> buildSnapshot(const relight::RelightResult& r, std::uint64_t version,
                                                std::uint64_t coalesced, double ms, bool preview, float residual,
                                                int iterations);

  SessionIdentity identity_;
  std::unique_ptr<precompute::ResidentScene> resident_;  // set once (start, or attach before linked_)
  std::atomic<bool> linked_{false};
  int bands_ = 0;
  std::size_t material_count_ = 0;
  std::unique_ptr<PreviewScene> preview_;  // instant preview; the worker's, until the linked start
  std::shared_ptr<const std::vector<std::uint8_t>> preview_valid_;
  gpu::BackendChoice backend_choice_{};
  // attach() -> worker: the backend's outcome; guarded by mutex_.
  bool attach_requested_ = false;
  std::promise<Status>* attach_made_ = nullptr;
  relight::RelightOptions options_;
  bool progressive_ = false;
  std::shared_ptr<UpdateJournal> journal_;
  std::unique_ptr<relight::RelightBackend> backend_;
  std::string backend_name_, backend_note_;
  std::shared_ptr<const std::vector<std::uint8_t>> grid_valid_;

  mutable std::mutex mutex_;
  mutable std::condition_variable work_cv_;    // worker: a new version or stop
  mutable std::condition_variable result_cv_;  // readers: a new result, close or drain
  // The durable (visible) light set and version; mutable: settleInFlight advances them.
  mutable relight::LightSet lights_;           // guarded by mutex_
  mutable std::uint64_t version_ = 0;          // guarded
  struct InFlight {
    std::uint64_t version;
    relight::LightSet lights;
    UpdateJournal::Ticket ticket;
  };
  mutable std::deque<InFlight> in_flight_;
  relight::LightSet scene_lights_;                      // the base of scenario documents
  std::vector<lights::MaterialEmission> emissions_;
  std::map<std::string, relight::LightSet> scenarios_;  // guarded by mutex_     // appended to the journal, not yet visible; guarded
  std::uint64_t relit_version_ = 0;            // last version handed to the worker, guarded
  std::shared_ptr<const Snapshot> latest_;     // guarded
  std::uint64_t sequence_ = 0;                 // results published, guarded
  bool stop_ = false;                          // guarded
  std::atomic<bool> closed_{false};
  // Stats (guarded by mutex_ except the atomics).
  std::uint64_t updates_ = 0, relights_ = 0, coalesced_ = 0, relight_errors_ = 0, previews_ = 0, instant_previews_ = 0;
  double last_ms_ = 0.0, total_ms_ = 0.0;
  std::atomic<int> subscribers_{0};
  std::atomic<Clock::rep> last_activity_ns_{Clock::now().time_since_epoch().count()};
  mutable std::atomic<std::uint64_t> wake_epoch_{0};
  std::thread worker_;
};

}  // namespace lightlink::service
