#include "service/scene_session.h"

#include <future>
#include <new>

#include "core/preview/preview_grid.h"
#include "core/relight/direct_layer.h"
#include "gpu/backend_factory.h"
#include "service/logging.h"
#include "service/validation.h"

namespace lightlink::service {
namespace {

constexpr auto kWaitSlice = std::chrono::milliseconds(50);

}  // namespace

PreviewScene::PreviewScene() = default;
PreviewScene::PreviewScene(PreviewScene&&) noexcept = default;
PreviewScene& PreviewScene::operator=(PreviewScene&&) noexcept = default;
PreviewScene::~PreviewScene() = default;

SceneSession::SceneSession(SessionIdentity identity, relight::LightSet lights, std::uint64_t version,
                           const SessionOptions& options, int bands, std::size_t material_count)
    : identity_(std::move(identity)),
      bands_(bands),
      material_count_(material_count),
      options_(options.relight),
      progressive_(options.progressive),
      journal_(options.journal),
      lights_(std::move(lights)),
      version_(version),
      scene_lights_(options.scene_lights),
      emissions_(options.emissions),
      relit_version_(version - 1) {  // the initial version is the worker's first job
  for (const lights::Scenario& sc : options.scenarios) scenarios_[sc.name] = sc.lights;
}

Expected<std::shared_ptr<SceneSession>> SceneSession::start(SessionIdentity identity,
                                                           precompute::ResidentScene resident,
                                                           relight::LightSet lights, std::uint64_t initial_version,
                                                           const SessionOptions& options) {
  if (initial_version == 0) initial_version = 1;  // versions start at 1; 0 means "none" on the wire
  auto choice = gpu::parseBackendChoice(options.backend);
  if (!choice) return choice.status();
  const auto& pre = resident.precomputation();
  const int bands = options.relight.bands > 0 ? options.relight.bands : pre.options.bands;
  const std::size_t materials = resident.scene().materials.size();
  std::shared_ptr<SceneSession> s(
      new SceneSession(std::move(identity), std::move(lights), initial_version, options, bands, materials));
  s->resident_ = std::make_unique<precompute::ResidentScene>(std::move(resident));
  s->linked_ = true;
  s->grid_valid_ = std::make_shared<const std::vector<std::uint8_t>>(s->resident_->precomputation().grid.valid);

  // The backend is made on the worker thread, which is the only one that ever uses it (a
  // GL context is current on the thread that created it).
  std::promise<Status> made;
  auto made_future = made.get_future();
  SceneSession* self = s.get();
  const gpu::BackendChoice c = *choice;
  s->worker_ = std::thread([self, c, &made] {
    const auto& r = *self->resident_;
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

Expected<std::shared_ptr<SceneSession>> SceneSession::startPreview(SessionIdentity identity, PreviewScene preview,
                                                                  relight::LightSet lights,
                                                                  std::uint64_t initial_version,
                                                                  const SessionOptions& options, int bands,
                                                                  std::size_t material_count) {
  if (initial_version == 0) initial_version = 1;
  auto choice = gpu::parseBackendChoice(options.backend);
  if (!choice) return choice.status();
  if (!preview.accel || !preview.grid) return internalError("startPreview: no preview grid");
  if (preview.grid->bands() != bands)
    return internalError("startPreview: the preview grid has {} bands, the scene {}", preview.grid->bands(), bands);
  std::shared_ptr<SceneSession> s(
      new SceneSession(std::move(identity), std::move(lights), initial_version, options, bands, material_count));
  s->backend_choice_ = *choice;
  s->preview_valid_ = std::make_shared<const std::vector<std::uint8_t>>(preview.grid->grid().valid);
  s->preview_ = std::make_unique<PreviewScene>(std::move(preview));
  s->backend_name_ = "cpu";  // what computes the preview; the backend's name once linked
  s->backend_note_ = "instant preview (the links are being computed)";
  // The first preview on this thread, so that it exists when this returns.
  {
    relight::LightSet first;
    {
      std::lock_guard lock(s->mutex_);
      first = s->lights_;
      s->relit_version_ = s->version_;
    }
    if (!s->previewAndPublish(first, initial_version, 0)) return internalError("instant preview: the first relight failed");
  }
  SceneSession* self = s.get();
  s->worker_ = std::thread([self] {
    if (self->previewLoop()) self->linkedStart();
  });
  return s;
}

Status SceneSession::attach(precompute::ResidentScene resident, Clock::time_point deadline) {
  std::promise<Status> made;
  auto made_future = made.get_future();
  std::uint64_t errors_before = 0;
  {
    std::lock_guard lock(mutex_);
    if (stop_) return notFound("scene_id: scene '{}' is closed", identity_.id);
    if (linked_ || attach_requested_) return internalError("attach: scene '{}' is linked already", identity_.id);
    resident_ = std::make_unique<precompute::ResidentScene>(std::move(resident));
    grid_valid_ = std::make_shared<const std::vector<std::uint8_t>>(resident_->precomputation().grid.valid);
    linked_.store(true, std::memory_order_release);
    attach_requested_ = true;
    attach_made_ = &made;
    errors_before = relight_errors_;
  }
  work_cv_.notify_all();
  if (Status st = made_future.get(); !st) return st;
  // The linked result: published, or its relight failed (counted), or the session closed.
  std::unique_lock lock(mutex_);
  while (true) {
    if (latest_ && !latest_->instant_preview) return {};
    if (relight_errors_ > errors_before) return internalError("scene '{}': the first linked relight failed", identity_.id);
    if (stop_) return notFound("scene_id: scene '{}' is closed", identity_.id);
    if (Clock::now() >= deadline) return cancelled("scene '{}': the linked result was not ready in time", identity_.id);
    result_cv_.wait_until(lock, std::min(deadline, Clock::now() + kWaitSlice));
  }
}

bool SceneSession::previewLoop() {
  std::uint64_t last = 0;
  {
    std::lock_guard lock(mutex_);
    last = relit_version_;  // the version startPreview published
  }
  while (true) {
    relight::LightSet lights;
    std::uint64_t v = 0;
    {
      std::unique_lock lock(mutex_);
      work_cv_.wait(lock, [&] { return stop_ || attach_requested_ || version_ > relit_version_; });
      if (stop_) {
        if (attach_made_) attach_made_->set_value(notFound("scene_id: scene '{}' is closed", identity_.id));
        attach_made_ = nullptr;
        return false;
      }
      if (attach_requested_) return true;
      lights = lights_;
      v = version_;
      relit_version_ = v;
    }
    if (previewAndPublish(lights, v, v > last ? v - last - 1 : 0)) last = v;
  }
}

void SceneSession::linkedStart() {
  std::promise<Status>* made = nullptr;
  {
    std::lock_guard lock(mutex_);
    made = attach_made_;
    attach_made_ = nullptr;
  }
  const auto& r = *resident_;
  std::string note;
  Expected<std::unique_ptr<relight::RelightBackend>> backend = internalError("no backend");
  try {
    backend = gpu::makeBackend(backend_choice_, r.scene(), r.accel(), r.precomputation(), r.lightmapLinks(),
                               r.gridLinks(), &note);
  } catch (const std::bad_alloc&) {
    backend = resourceExhausted("out of memory while making the relight backend");
  }
  if (!backend) {
    made->set_value(backend.status());
    return;
  }
  backend_ = std::move(backend).value();
  {
    std::lock_guard lock(mutex_);
    backend_name_ = std::string(backend_->name());
    backend_note_ = note;
  }
  made->set_value(Status{});
  preview_.reset();  // the preview's BVH and hits are not needed any more
  // The linked result takes a version of its own (a client that saw the preview's version
  // sees a newer one), unless an update already waits: then that version is the linked one.
  std::uint64_t v = 0;
  relight::LightSet lights;
  bool pending = false;
  {
    std::lock_guard lock(mutex_);
    if (journal_) settleInFlight();
    v = version_;
    lights = lights_;
    pending = version_ > relit_version_ || !in_flight_.empty();
  }
  if (!pending) {
    const std::uint64_t next = takeVersion(v, lights);
    std::lock_guard lock(mutex_);
    // takeVersion marked `next` as handed to the worker; workerLoop relights it. Without a
    // new version (not durable, or an update came), the newest version is relit.
    if (next != 0 && relit_version_ == next) relit_version_ = next - 1;
    else if (next == 0 && relit_version_ >= version_) relit_version_ = version_ - 1;
  }
  workerLoop();
}

bool SceneSession::lightOnWorker(std::uint64_t v, const char* what, const char* event, double& ms,
                                 const std::function<Status()>& light) {
  const auto t0 = Clock::now();
  Status s;
  // Out of memory in a worker thread would end the daemon: it fails this relight instead.
  try {
    s = light();
  } catch (const std::bad_alloc&) {
    s = resourceExhausted("out of memory while {}", what);
  }
  ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  if (s) return true;
  std::lock_guard lock(mutex_);
  ++relight_errors_;
  logEvent(LogLevel::kError, event, {{"scene", identity_.id}, {"version", v}, {"error", s.message()}});
  return false;
}

bool SceneSession::previewAndPublish(const relight::LightSet& lights, std::uint64_t v, std::uint64_t coalesced) {
  std::vector<float> grid_sh;
  double ms = 0.0;
  if (!lightOnWorker(v, "lighting the preview", "preview_failed", ms, [&] { return preview_->grid->light(lights, grid_sh); }))
    return false;
  auto snap = std::make_shared<Snapshot>();
  snap->scene_id = identity_.id;
  snap->version = v;
  snap->coalesced = coalesced;
  snap->preview = true;
  snap->instant_preview = true;
  snap->relight_ms = ms;
  snap->backend = "cpu";
  snap->bands = bands_;
  const auto& g = preview_->grid->grid();
  snap->grid.present = true;
  snap->grid.origin = g.origin;
  snap->grid.spacing_m = g.spacing_m;
  snap->grid.dims = g.dims;
  snap->grid_sh = std::move(grid_sh);
  snap->grid_valid = preview_valid_;
  {
    std::lock_guard lock(mutex_);
    snap->sequence = ++sequence_;
    latest_ = std::move(snap);
    ++instant_previews_;
    coalesced_ += coalesced;
  }
  result_cv_.notify_all();
  logEvent(LogLevel::kDebug, "relight",
           {{"scene", identity_.id}, {"version", v}, {"ms", ms}, {"coalesced", coalesced}, {"backend", "cpu"},
            {"kind", "instant_preview"}});
  return true;
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

std::vector<std::string> SceneSession::lightIds() const {
  std::lock_guard lock(mutex_);
  std::vector<std::string> ids;
  for (const auto& e : lights_.lights()) ids.push_back(e.id);
  return ids;
}

Expected<std::uint64_t> SceneSession::update(const v1::UpdateLightsRequest& request) {
  return commit([&](relight::LightSet& next) { return applyUpdate(request, material_count_, next); });
}

Expected<std::vector<std::string>> SceneSession::setScenario(const v1::SetScenarioRequest& request,
                                                             std::optional<relight::LightSet>* previous) {
  const std::string& name = request.name();
  if (Status s = lights::validateScenarioName(name, "name: scenario"); !s) return s;
  relight::LightSet set;
  switch (request.source_case()) {
    case v1::SetScenarioRequest::kLightSetJson: {
      if (request.light_set_json().size() > kMaxLightSetJsonBytes)
        return resourceExhausted("light_set_json: {} bytes, above the limit of {} bytes",
                                 request.light_set_json().size(), kMaxLightSetJsonBytes);
      auto patch = relight::LightSetPatch::parse(request.light_set_json(), "light_set_json");
      if (!patch) return patch.status();
      set = scene_lights_;
      if (Status s = set.apply(*patch); !s) return invalidInput("light_set_json: {}", s.message());
      break;
    }
    case v1::SetScenarioRequest::kFromCurrent: {
      if (!request.from_current()) return invalidInput("from_current: must be true when given");
      std::lock_guard lock(mutex_);
      set = in_flight_.empty() ? lights_ : in_flight_.back().lights;
      break;
    }
    case v1::SetScenarioRequest::kRemove:
      if (!request.remove()) return invalidInput("remove: must be true when given");
      break;
    default:
      return invalidInput("source: give light_set_json, from_current or remove");
  }
  if (request.source_case() != v1::SetScenarioRequest::kRemove) {
    if (Status s = set.checkMaterials(material_count_); !s) return invalidInput("light_set_json: {}", s.message());
    if (set.lights().size() > kMaxLightsPerScene)
      return resourceExhausted("scenario \"{}\": {} lights, above the limit of {} lights per scene", name,
                               set.lights().size(), kMaxLightsPerScene);
  }
  std::lock_guard lock(mutex_);
  if (stop_) return notFound("scene_id: scene '{}' is closed", identity_.id);
  const auto it = scenarios_.find(name);
  *previous = it == scenarios_.end() ? std::nullopt : std::optional<relight::LightSet>(it->second);
  if (request.source_case() == v1::SetScenarioRequest::kRemove) {
    if (it == scenarios_.end()) return notFound("name: scene '{}' has no scenario \"{}\"", identity_.id, name);
    scenarios_.erase(it);
  } else {
    if (it == scenarios_.end() && scenarios_.size() >= lights::kMaxScenarios)
      return resourceExhausted("scenarios: the scene has {} scenarios, the limit", lights::kMaxScenarios);
    scenarios_[name] = std::move(set);
  }
  std::vector<std::string> names;
  for (const auto& [n, s] : scenarios_) names.push_back(n);
  return names;
}

void SceneSession::restoreScenario(const std::string& name, std::optional<relight::LightSet> previous) {
  std::lock_guard lock(mutex_);
  if (previous) scenarios_[name] = std::move(*previous);
  else scenarios_.erase(name);
}

Expected<std::uint64_t> SceneSession::useScenarios(const v1::UseScenariosRequest& request) {
  if (request.wait_ms() > kMaxWaitMs) return invalidInput("wait_ms: {} is above the limit of {}", request.wait_ms(), kMaxWaitMs);
  if (static_cast<std::size_t>(request.weights_size()) > lights::kMaxScenarios)
    return invalidInput("weights: {} entries, above the limit of {}", request.weights_size(), lights::kMaxScenarios);
  std::vector<lights::ScenarioWeight> weights;
  for (const auto& w : request.weights()) weights.push_back({w.name(), w.weight()});
  std::vector<lights::Scenario> scenarios;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [name, set] : scenarios_) scenarios.push_back({name, set});
  }
  auto blend = lights::blendScenarios(scenarios, weights, emissions_);
  if (!blend) return blend.status();
  if (blend->lights().size() > kMaxLightsPerScene)
    return resourceExhausted("weights: the blend has {} lights, above the limit of {} lights per scene",
                             blend->lights().size(), kMaxLightsPerScene);
  return commit([&](relight::LightSet& next) {
    next = *blend;
    return Status{};
  });
}

std::vector<std::string> SceneSession::scenarioNames() const {
  std::lock_guard lock(mutex_);
  std::vector<std::string> names;
  for (const auto& [n, s] : scenarios_) names.push_back(n);
  return names;
}

nlohmann::ordered_json SceneSession::persistentScenarios() const {
  std::lock_guard lock(mutex_);
  nlohmann::ordered_json out = nlohmann::ordered_json::object();
  for (const auto& [n, s] : scenarios_) out[n] = s.toJson();
  return out;
}

Expected<std::uint64_t> SceneSession::commit(const std::function<Status(relight::LightSet&)>& change) {
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
    if (Status s = change(next); !s) return s;
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
  double ms = 0.0;
  // On failure readers waiting for this version run into their deadline.
  if (!lightOnWorker(v, "relighting", "relight_failed", ms, [&] { return backend_->relightInto(lights, options, result); }))
    return false;
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
  const auto& p = resident_->precomputation();
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
  st.instant_previews = instant_previews_;
  st.artifact_bytes = linked_ ? resident_->artifactBytes() : 0;
  // The mapping, the worker's result buffers (about one snapshot) and the newest snapshot.
  const std::uint64_t snap = latest_ ? latest_->bytes() : 0;
  st.resident_bytes = st.artifact_bytes + 2 * snap;
  st.subscribers = static_cast<std::uint32_t>(subscribers_.load());
  return st;
}

relight::LightSet SceneSession::lightSet(std::uint64_t* version) const {
  std::lock_guard lock(mutex_);
  if (journal_) settleInFlight();
  if (version) *version = version_;
  return lights_;
}

nlohmann::ordered_json SceneSession::persistentLights(std::uint64_t* version) const {
  std::lock_guard lock(mutex_);
  if (journal_) settleInFlight();
  if (version) *version = version_;
  return lights_.toJson();
}

}  // namespace lightlink::service
