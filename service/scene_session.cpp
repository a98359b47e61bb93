#include "service/scene_session.h"

#include <future>
#include <new>

#include "core/relight/direct_layer.h"
#include "gpu/backend_factory.h"
#include "service/logging.h"
#include "service/validation.h"

namespace lightlink::service {
namespace {

constexpr auto kWaitSlice = std::chrono::milliseconds(50);

}  // namespace

SceneSession::SceneSession(SessionIdentity identity, precompute::ResidentScene resident, relight::LightSet lights,
                           std::uint64_t version, const SessionOptions& options)
    : identity_(std::move(identity)),
      resident_(std::move(resident)),
      options_(options.relight),
      progressive_(options.progressive),
      journal_(options.journal),
      lights_(std::move(lights)),
      version_(version),
      relit_version_(version - 1) {}  // the initial version is the worker's first job

Expected<std::shared_ptr<SceneSession>> SceneSession::start(SessionIdentity identity,
                                                           precompute::ResidentScene resident,
                                                           relight::LightSet lights, std::uint64_t initial_version,
                                                           const SessionOptions& options) {
  if (initial_version == 0) initial_version = 1;  // versions start at 1; 0 means "none" on the wire
  auto choice = gpu::parseBackendChoice(options.backend);
  if (!choice) return choice.status();
  std::shared_ptr<SceneSession> s(
      new SceneSession(std::move(identity), std::move(resident), std::move(lights), initial_version, options));
  const auto& p = s->resident_.precomputation();
  s->grid_valid_ = std::make_shared<const std::vector<std::uint8_t>>(p.grid.valid);

  // The backend is made on the worker thread, which is the only one that ever uses it (a
  // GL context is current on the thread that created it).
  std::promise<Status> made;
  auto made_future = made.get_future();
  SceneSession* self = s.get();
  const gpu::BackendChoice c = *choice;
  s->worker_ = std::thread([self, c, &made] {
    const auto& r = self->resident_;
    std::string note;
    auto backend = gpu::makeBackend(c, r.scene(), r.accel(), r.precomputation(), r.lightmapLinks(), r.gridLinks(),
                                    &note);
    if (!backend) {
      made.set_value(backend.status());
      return;
    }
    self->backend_ = std::move(backend).value();
    self->backend_name_ = std::string(self->backend_->name());
    self->backend_note_ = note;
    made.set_value(Status{});
    self->workerLoop();
  });
  if (Status st = made_future.get(); !st) {
    s->worker_.join();
    return st;
  }
  return s;
}

SceneSession::~SceneSession() { close(); }

void SceneSession::close() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  closed_ = true;
  work_cv_.notify_all();
  result_cv_.notify_all();
  if (worker_.joinable() && worker_.get_id() != std::this_thread::get_id()) worker_.join();
}

int SceneSession::bands() const {
  const auto& p = resident_.precomputation();
  return options_.bands > 0 ? options_.bands : p.options.bands;
}

std::vector<std::string> SceneSession::lightIds() const {
  std::lock_guard lock(mutex_);
  std::vector<std::string> ids;
  for (const auto& e : lights_.lights()) ids.push_back(e.id);
  return ids;
}

Expected<std::uint64_t> SceneSession::update(const v1::UpdateLightsRequest& request) {
  std::unique_lock lock(mutex_);
  UpdateJournal::Ticket ticket;
  std::uint64_t v = 0;
  while (true) {
    if (stop_) return notFound("scene_id: scene '{}' is closed", identity_.id);
    settleInFlight();
    // Build on the newest version, durable or in flight. Apply to a copy and keep it only
    // when every change succeeded: all or nothing.
    const InFlight* tip = in_flight_.empty() ? nullptr : &in_flight_.back();
    relight::LightSet next = tip ? tip->lights : lights_;
    if (Status s = applyUpdate(request, resident_.scene().materials.size(), next); !s) return s;
    v = (tip ? tip->version : version_) + 1;
    if (!journal_) {
      lights_ = std::move(next);
      version_ = v;
      break;
    }
    ticket = journal_->append({identity_.id, v, next.toJson()}, tip ? tip->ticket : nullptr);
    if (!ticket) continue;  // the version it built on failed meanwhile: rebuild on the durable state
    in_flight_.push_back({v, std::move(next), ticket});
    break;
  }
  if (ticket) {
    lock.unlock();
    const Status persisted = journal_->wait(ticket);
    lock.lock();
    settleInFlight();  // ours (and every one before it) is visible now, or dropped
    if (!persisted) return persisted;
  }
  ++updates_;
  lock.unlock();
  work_cv_.notify_one();
  return v;
}

void SceneSession::settleInFlight() const {
  bool advanced = false;
  while (!in_flight_.empty()) {
    const auto state = journal_->state(in_flight_.front().ticket);
    if (state == UpdateJournal::State::kPending) break;
    if (state == UpdateJournal::State::kFailed) {
      // Commits complete in order and a failure fails every commit queued behind it, so
      // the versions after this one failed too (or would build on it).
      in_flight_.clear();
      break;
    }
    version_ = in_flight_.front().version;
    lights_ = std::move(in_flight_.front().lights);
    in_flight_.pop_front();
    advanced = true;
  }
  if (advanced) work_cv_.notify_one();
}

std::uint64_t SceneSession::version() const {
  std::lock_guard lock(mutex_);
  return version_;
}

std::shared_ptr<const Snapshot> SceneSession::latest() const {
  std::lock_guard lock(mutex_);
  return latest_;
}

std::shared_ptr<const Snapshot> SceneSession::waitForVersion(std::uint64_t min_version, Clock::time_point deadline,
                                                             const std::function<bool()>& stop) const {
  std::unique_lock lock(mutex_);
  while (true) {
    if (latest_ && latest_->version >= min_version) return latest_;
    if (stop_ || (stop && stop()) || Clock::now() >= deadline) return nullptr;
    result_cv_.wait_until(lock, std::min(deadline, Clock::now() + kWaitSlice));
  }
}

std::shared_ptr<const Snapshot> SceneSession::waitForNewer(std::uint64_t after_sequence, Clock::time_point deadline,
                                                           const std::function<bool()>& stop) const {
  std::unique_lock lock(mutex_);
  const std::uint64_t epoch = wake_epoch_.load();
  while (true) {
    if (latest_ && latest_->sequence > after_sequence) return latest_;
    if (stop_ || (stop && stop()) || Clock::now() >= deadline || wake_epoch_.load() != epoch) return nullptr;
    result_cv_.wait_until(lock, std::min(deadline, Clock::now() + kWaitSlice));
  }
}

void SceneSession::wakeAll() const {
  {
    std::lock_guard lock(mutex_);
    ++wake_epoch_;
  }
  result_cv_.notify_all();
}

void SceneSession::workerLoop() {
  relight::RelightResult result;
  std::uint64_t last_relit = 0;
  const bool progressive = progressive_ && options_.max_bounces > 0;
  while (true) {
    relight::LightSet lights;
    std::uint64_t v = 0;
    {
      std::unique_lock lock(mutex_);
      work_cv_.wait(lock, [&] { return stop_ || version_ > relit_version_; });
      if (stop_) return;
      // The latest state: every update acknowledged so far is in it.
      lights = lights_;
      v = version_;
      relit_version_ = v;
    }
    const std::uint64_t coalesced = last_relit == 0 || v <= last_relit ? 0 : v - last_relit - 1;
    if (!progressive) {
      if (relightAndPublish(lights, v, coalesced, options_, nullptr, result)) last_relit = v;
      continue;  // on failure: wait for the next update rather than retrying a failing state in a loop
    }
    // Progressive: one bounce iteration started from the last solution, published at once;
    // then, while no update waits, more iterations (1, 2, 4, ... per version) until the
    // iteration converges; when the bounce cap comes first, the cold relight the daemon
    // would give without --progressive ends it. Each result after the first takes a version
    // of its own.
    Progress progress;
    // One light changed on a converged solution: the incremental relight propagates the
    // change through the bounces and converges in this one call.
    if (backend_->incrementalFor(lights, options_)) {
      progress.final_cold = true;
      if (relightAndPublish(lights, v, coalesced, options_, &progress, result)) last_relit = v;
      continue;
    }
    relight::RelightOptions warm = options_;
    warm.warm_start = true;
    warm.max_bounces = 1;
    if (!relightAndPublish(lights, v, coalesced, warm, &progress, result)) continue;
    last_relit = v;
    int step = 1;
    while (!progress.converged) {
      const std::uint64_t next = takeVersion(v, lights);
      if (next == 0) break;  // a newer light set waits, or the version could not be made durable
      v = next;
      step *= 2;
      const bool last = progress.iterations + step >= options_.max_bounces;
      warm.max_bounces = step;
      if (last) progress.final_cold = true;
      if (!relightAndPublish(lights, v, 0, last ? options_ : warm, &progress, result)) break;
      last_relit = v;
    }
  }
}

std::uint64_t SceneSession::takeVersion(std::uint64_t v, const relight::LightSet& lights) {
  std::uint64_t next = 0;
  UpdateJournal::Ticket ticket;
  {
    std::lock_guard lock(mutex_);
    if (journal_) settleInFlight();
    if (stop_ || version_ != v || !in_flight_.empty()) return 0;
    next = v + 1;
    relit_version_ = next;
    if (journal_) {
      // Clients will see this version: durable first, like an update's.
      ticket = journal_->append({identity_.id, next, lights.toJson()}, nullptr);
      in_flight_.push_back({next, lights, ticket});
    } else {
      version_ = next;
    }
  }
  if (ticket) {
    const Status persisted = journal_->wait(ticket);
    std::lock_guard lock(mutex_);
    settleInFlight();
    if (!persisted) {
      // Not durable, so not published: the next update takes the number, and is relit.
      relit_version_ = v;
      return 0;
    }
  }
  return next;
}

bool SceneSession::relightAndPublish(const relight::LightSet& lights, std::uint64_t v, std::uint64_t coalesced,
                                     const relight::RelightOptions& options, Progress* progress,
                                     relight::RelightResult& result) {
  const auto t0 = Clock::now();
  Status s;
  // Out of memory in a worker thread would end the daemon: it fails this relight instead.
  try {
    s = backend_->relightInto(lights, options, result);
  } catch (const std::bad_alloc&) {
    s = resourceExhausted("out of memory while relighting");
  }
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  if (!s) {
    std::lock_guard lock(mutex_);
    ++relight_errors_;
    logEvent(LogLevel::kError, "relight_failed", {{"scene", identity_.id}, {"version", v}, {"error", s.message()}});
    // Readers waiting for this version run into their deadline.
    return false;
  }
  bool preview = false;
  float residual = 0.0f;
  int iterations = 0;
  if (progress) {
    // The change of the last iteration over the total flux says how converged the result is.
    const auto& log = result.bounce_log;
    residual = log.empty() || !(log.back().total_flux > 0.0) ? 0.0f
                                                             : float(log.back().added_flux / log.back().total_flux);
    progress->iterations = progress->final_cold ? result.passes.bounces : progress->iterations + result.passes.bounces;
    progress->converged = progress->final_cold || result.bounce_stop != "cap";
    preview = !progress->converged;
    iterations = progress->iterations;
  }
  std::shared_ptr<const Snapshot> snap;
  try {
    snap = buildSnapshot(result, v, coalesced, ms, preview, residual, iterations);
  } catch (const std::bad_alloc&) {
    std::lock_guard lock(mutex_);
    ++relight_errors_;
    logEvent(LogLevel::kError, "relight_failed", {{"scene", identity_.id}, {"version", v}, {"error", "out of memory while building the result"}});
    return false;
  }
  {
    std::lock_guard lock(mutex_);
    latest_ = std::move(snap);
    ++relights_;
    previews_ += preview ? 1 : 0;
    coalesced_ += coalesced;
    last_ms_ = ms;
    total_ms_ += ms;
  }
  result_cv_.notify_all();
  // Where the relight's time went, stage by stage (the backend's own clocks), so a slow
  // relight in the daemon can be compared with bench/relight without a profiler.
  std::string stages;
  for (const auto& st : result.timings)
    stages += fmt::format("{}{}={:.2f}", stages.empty() ? "" : ",", st.stage, st.seconds * 1e3);
  logEvent(LogLevel::kDebug, "relight",
           {{"scene", identity_.id},
            {"version", v},
            {"ms", ms},
            {"coalesced", coalesced},
            {"backend", backend_name_},
            {"preview", preview},
            {"iterations", iterations},
            {"residual", residual},
            {"incremental", result.passes.incremental != 0},
            {"stages_ms", stages}});
  return true;
}

std::shared_ptr<const Snapshot> SceneSession::buildSnapshot(const relight::RelightResult& r, std::uint64_t version,
                                                            std::uint64_t coalesced, double ms, bool preview,
                                                            float residual, int iterations) {
  auto s = std::make_shared<Snapshot>();
  s->scene_id = identity_.id;
  s->version = version;
  {
    std::lock_guard lock(mutex_);
    s->sequence = ++sequence_;
  }
  s->coalesced = coalesced;
  s->preview = preview;
  s->residual = residual;
  s->iterations = iterations;
  s->relight_ms = ms;
  s->backend = r.backend;
  s->bands = r.bands;
  s->width = r.width;
  s->height = r.height;
  s->lightmap_sh = r.lightmap_sh;
  // The wire carries one atlas size: a finer direct layer is streamed box-filtered to it
  // (bake writes it at full size, direct.exr).
  std::vector<glm::vec3> direct;
  relight::directAtLightmapSize(r, direct);
  s->direct.resize(direct.size() * 3);
  for (std::size_t i = 0; i < direct.size(); ++i) {
    s->direct[3 * i + 0] = direct[i].x;
    s->direct[3 * i + 1] = direct[i].y;
    s->direct[3 * i + 2] = direct[i].z;
  }
  s->texel_valid = r.texel_valid;
  const auto& p = resident_.precomputation();
  if (p.has_grid) {
    s->grid.present = true;
    s->grid.origin = p.grid.origin;
    s->grid.spacing_m = p.grid.spacing_m;
    s->grid.dims = p.grid.dims;
    s->grid_sh = r.grid_sh;
    s->grid_valid = grid_valid_;
  }
  return s;
}

SessionStats SceneSession::stats() const {
  std::lock_guard lock(mutex_);
  SessionStats st;
  st.version = version_;
  st.result_version = latest_ ? latest_->version : 0;
  st.updates = updates_;
  st.relights = relights_;
  st.coalesced = coalesced_;
  st.relight_errors = relight_errors_;
  st.previews = previews_;
  st.last_relight_ms = last_ms_;
  st.mean_relight_ms = relights_ ? total_ms_ / static_cast<double>(relights_) : 0.0;
  st.artifact_bytes = resident_.artifactBytes();
  // The mapping, the worker's result buffers (about one snapshot) and the newest snapshot.
  const std::uint64_t snap = latest_ ? latest_->bytes() : 0;
  st.resident_bytes = st.artifact_bytes + 2 * snap;
  st.subscribers = static_cast<std::uint32_t>(subscribers_.load());
  return st;
}

nlohmann::ordered_json SceneSession::persistentLights(std::uint64_t* version) const {
  std::lock_guard lock(mutex_);
  if (journal_) settleInFlight();
  if (version) *version = version_;
  return lights_.toJson();
}

}  // namespace lightlink::service
