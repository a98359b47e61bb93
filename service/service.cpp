#include "service/service.h"

#include <unistd.h>

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <system_error>
#include <thread>

#include "core/charts/gltf_writer.h"
#include "gpu/backend_factory.h"
#include "service/auth.h"
#include "service/logging.h"
#include "service/status_map.h"
#include "service/validation.h"

namespace lightlink::service {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kDefaultWait = std::chrono::seconds(60);  // a call without a deadline waits at most this
// A long poll answers this long before the call's deadline, so the answer arrives in time.
constexpr auto kAnswerMargin = std::chrono::milliseconds(20);

// Streams precompute progress to the OpenScene caller: one message per stage start and
// end, updates at most every 100 ms. Progress callbacks come from worker threads, and a
// ServerWriter allows one writer at a time: every write holds the mutex.
class StreamProgress final : public Progress {
 public:
  StreamProgress(grpc::ServerContext* ctx, grpc::ServerWriter<v1::OpenSceneProgress>* writer,
                 const std::atomic<bool>& draining)
      : ctx_(ctx), writer_(writer), draining_(draining) {}

  void begin(std::string_view stage, std::size_t total) override {
    std::lock_guard lock(mutex_);
    stage_ = std::string(stage);
    total_ = total;
    last_ = Clock::now();
    send(0.0f, "");
  }
  void update(std::size_t done) override {
    std::lock_guard lock(mutex_);
    const auto now = Clock::now();
    if (now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    send(total_ > 0 ? std::min(1.0f, static_cast<float>(done) / static_cast<float>(total_)) : 0.0f, "");
  }
  void end() override {
    std::lock_guard lock(mutex_);
    send(1.0f, "done");
  }
  // Polled per chunk by every precompute stage, from many threads: the gRPC checks (which
  // may lock) run at most every 5 ms, and once true the answer stays true. The call's own
  // deadline counts too, so an abandoned open stops whether or not gRPC noticed yet.
  bool cancelled() const override {
    if (stop_.load(std::memory_order_relaxed)) return true;
    if (draining_.load(std::memory_order_relaxed)) return stop_ = true;
    const std::int64_t now = Clock::now().time_since_epoch().count();
    std::int64_t last = last_poll_.load(std::memory_order_relaxed);
    if (now - last < std::chrono::duration_cast<Clock::duration>(std::chrono::milliseconds(5)).count() ||
        !last_poll_.compare_exchange_strong(last, now))
      return false;
    if (ctx_->IsCancelled() || std::chrono::system_clock::now() > ctx_->deadline()) stop_ = true;
    return stop_.load();
  }
  void finish(const v1::OpenSceneProgress& last) {
    std::lock_guard lock(mutex_);
    writer_->Write(last);
  }
  // A message of its own between the stages (the instant preview's announcement).
  void write(const v1::OpenSceneProgress& message) { finish(message); }

 private:
  void send(float fraction, const char* message) {
    v1::OpenSceneProgress p;
    p.set_stage(stage_);
    p.set_fraction(fraction);
    p.set_message(message);
    writer_->Write(p);
  }

  grpc::ServerContext* ctx_;
  grpc::ServerWriter<v1::OpenSceneProgress>* writer_;
  const std::atomic<bool>& draining_;
  mutable std::atomic<bool> stop_{false};
  mutable std::atomic<std::int64_t> last_poll_{0};
  std::mutex mutex_;
  std::string stage_;
  std::size_t total_ = 0;
  Clock::time_point last_;
};

void fillOpened(const SceneSession& s, v1::SceneOpened* o) {
  const auto& id = s.identity();
  const auto& r = s.resident();
  const auto& p = r.precomputation();
  o->set_scene_id(id.id);
  o->set_scene_token(id.token);
  o->set_version(s.version());
  o->set_artifact_reused(r.reused());
  o->set_cache_key(r.cacheKeyHex());
  o->set_backend(s.backendName());
  o->mutable_lightmap()->set_width(p.lightmap.width);
  o->mutable_lightmap()->set_height(p.lightmap.height);
  o->mutable_lightmap()->set_tile_size(32);
  if (p.has_grid) {
    auto* g = o->mutable_grid();
    g->set_present(true);
    g->mutable_origin()->set_x(p.grid.origin.x);
    g->mutable_origin()->set_y(p.grid.origin.y);
    g->mutable_origin()->set_z(p.grid.origin.z);
    g->mutable_spacing()->set_x(p.grid.spacing_m);
    g->mutable_spacing()->set_y(p.grid.spacing_m);
    g->mutable_spacing()->set_z(p.grid.spacing_m);
    g->set_nx(p.grid.dims.x);
    g->set_ny(p.grid.dims.y);
    g->set_nz(p.grid.dims.z);
  }
  o->set_bands(s.bands());
  for (const auto& l : s.lightIds()) o->add_light_ids(l);
  o->set_open_seconds(r.openSeconds());
}

// The instant preview's announcement: the scene as its preview result describes it.
void fillPreview(const SceneSession& s, double open_seconds, v1::SceneOpened* o) {
  const auto& id = s.identity();
  const auto snap = s.latest();
  o->set_scene_id(id.id);
  o->set_scene_token(id.token);
  o->set_backend(s.backendName());
  o->mutable_lightmap()->set_tile_size(32);
  if (snap) {
    o->set_version(snap->version);
    auto* g = o->mutable_grid();
    g->set_present(snap->grid.present);
    g->mutable_origin()->set_x(snap->grid.origin.x);
    g->mutable_origin()->set_y(snap->grid.origin.y);
    g->mutable_origin()->set_z(snap->grid.origin.z);
    g->mutable_spacing()->set_x(snap->grid.spacing_m);
    g->mutable_spacing()->set_y(snap->grid.spacing_m);
    g->mutable_spacing()->set_z(snap->grid.spacing_m);
    g->set_nx(snap->grid.dims.x);
    g->set_ny(snap->grid.dims.y);
    g->set_nz(snap->grid.dims.z);
  }
  o->set_bands(s.bands());
  for (const auto& l : s.lightIds()) o->add_light_ids(l);
  o->set_open_seconds(open_seconds);
}

// Threads that run the bodies of result calls, reused: 50 clients polling at 200 Hz would
// otherwise start 10,000 threads a second. A body that waits holds its thread, so a call that
// finds no idle thread starts one; a thread idle for a while exits. Never destroyed: idle
// threads may still wait on it while the process exits.
class BodyThreads {
 public:
  static BodyThreads& instance() {
    static auto* threads = new BodyThreads;
    return *threads;
  }
  // Throws std::system_error when a thread is needed and cannot be started (`body` not run).
  void run(std::function<void()> body) {
    {
      std::lock_guard lock(mutex_);
      if (idle_ > queue_.size()) {  // an idle thread not yet claimed
        queue_.push_back(std::move(body));
        ready_.notify_one();
        return;
      }
    }
    std::thread([this, body = std::move(body)]() mutable {
      body();
      body = nullptr;
      loop();
    }).detach();
  }

 private:
  static constexpr auto kIdleExit = std::chrono::seconds(10);
  void loop() {
    std::unique_lock lock(mutex_);
    for (;;) {
      ++idle_;
      const bool got = ready_.wait_for(lock, kIdleExit, [&] { return !queue_.empty(); });
      --idle_;
      if (!got) return;
      auto body = std::move(queue_.front());
      queue_.pop_front();
      lock.unlock();
      body();
      lock.lock();
    }
  }
  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::function<void()>> queue_;
  std::size_t idle_ = 0;  // threads waiting for a body
};

}  // namespace

// One call of Relight, GetTextures or Subscribe as gRPC callback reactor. Its body runs on a
// thread of its own while it lasts (BodyThreads), because it waits for results (SceneSession's waits block) and a
// gRPC callback thread must never block. The body hands over a result's messages at once;
// each write's completion starts the next on gRPC's thread, and the body waits only for the
// whole result (one thread hand-off per result, not per message, and a slow subscriber still
// skips versions). The last message of a call that ends with it goes out together with the
// status (one flush, one wake-up of the client).
// The reactor deletes itself once gRPC is done with the call and the body thread has ended.
class LightlinkService::ResultCall final : public grpc::ServerWriteReactor<grpc::ByteBuffer> {
 public:
  using Body = std::function<grpc::Status(ResultCall&)>;

  ResultCall(const char* rpc, Body body) {
    try {
      BodyThreads::instance().run([this, rpc, body = std::move(body)] { run(rpc, body); });
    } catch (const std::system_error&) {
      Finish(grpcError(grpc::StatusCode::RESOURCE_EXHAUSTED, fmt::format("{}: the daemon cannot start a thread", rpc)));
      release();
    }
  }

  // Sends the first `count` messages of `wire` (references to its slices, no copy) and
  // returns once all went out; false when the client is gone.
  bool write(std::shared_ptr<const WireResult> wire, std::size_t count) {
    if (count == 0) return true;
    const grpc::ByteBuffer* first = &wire->messages[0];
    {
      std::lock_guard lock(mutex_);
      batch_ = std::move(wire);
      batch_count_ = count;
      next_ = 1;
      write_done_ = false;
    }
    StartWrite(first);
    std::unique_lock lock(mutex_);
    written_.wait(lock, [&] { return write_done_; });
    batch_.reset();
    return write_ok_;
  }
  // The call's last message, sent with its status when the body returns OK.
  void writeLast(const grpc::ByteBuffer& message) { last_ = message; }

  void OnWriteDone(bool ok) override {
    const grpc::ByteBuffer* next = nullptr;
    {
      std::lock_guard lock(mutex_);
      if (ok && next_ < batch_count_) {
        next = &batch_->messages[next_++];  // alive: the body waits until the batch is done
      } else {
        write_ok_ = ok;
        write_done_ = true;
        written_.notify_one();
      }
    }
    if (next) StartWrite(next);
  }
  void OnDone() override { release(); }

 private:
  void run(const char* rpc, const Body& body) {
    grpc::Status status;
    // gRPC would answer UNKNOWN and log nothing.
    try {
      status = body(*this);
    } catch (const std::bad_alloc&) {
      logEvent(LogLevel::kError, "out_of_memory", {{"rpc", rpc}});
      status = grpcError(grpc::StatusCode::RESOURCE_EXHAUSTED, fmt::format("out of memory while answering {}", rpc));
    }
    if (last_ && status.ok()) StartWriteAndFinish(&*last_, grpc::WriteOptions(), status);
    else Finish(status);
    release();
  }
  // Two owners: gRPC (until OnDone) and the body thread (until it returns).
  void release() {
    if (refs_.fetch_sub(1, std::memory_order_acq_rel) == 1) delete this;
  }

  std::mutex mutex_;
  std::condition_variable written_;
  std::shared_ptr<const WireResult> batch_;  // the messages being written
  std::size_t batch_count_ = 0, next_ = 0;
  bool write_done_ = false, write_ok_ = false;
  std::optional<grpc::ByteBuffer> last_;
  std::atomic<int> refs_{2};
};

namespace {

using ResultCall = LightlinkService::ResultCall;

// Header of a GetTextures answer when nothing changed.
grpc::Status sendNotModified(const SceneSession& s, const Snapshot& snap, ResultCall& call) {
  v1::ResultMessage m;
  auto* h = m.mutable_header();
  h->mutable_scene()->set_scene_id(s.identity().id);
  h->set_version(snap.version);
  h->set_not_modified(true);
  h->set_backend(snap.backend);
  grpc::ByteBuffer bytes;
  bool own = false;
  if (auto st = grpc::SerializationTraits<v1::ResultMessage>::Serialize(m, &bytes, &own); !st.ok()) return st;
  call.writeLast(bytes);  // with the status: one flush
  return grpc::Status::OK;
}

// How a result ends its call: Relight and GetTextures send one result and finish, so their
// last message can go out with the call's status; a Subscribe stream goes on.
enum class CallEnds { kAfterThisResult, kLater };

// Sends a result from the snapshot's shared wire form (Snapshot::wire: `previous` and
// `delta` for a Subscribe stream). CANCELLED when a write fails: the client is gone.
grpc::Status sendWire(const Snapshot& snap, const SpecKey& spec, std::size_t chunk_bytes, ResultCall& call, CallEnds ends,
                      const Snapshot* previous = nullptr, bool delta = false) {
  const auto wire = snap.wire(spec, chunk_bytes, previous, delta);
  if (!wire) return grpcError(grpc::StatusCode::INTERNAL, "result: could not serialize the result messages");
  const std::size_t n = wire->messages.size();
  // The last message of a call's only result goes out with its status: one flush and one
  // wake-up of the client fewer.
  const std::size_t plain = ends == CallEnds::kAfterThisResult && n > 0 ? n - 1 : n;
  if (!call.write(wire, plain)) return grpcError(grpc::StatusCode::CANCELLED, "the client went away");
  if (plain < n) call.writeLast(wire->messages.back());
  return grpc::Status::OK;
}

}  // namespace

std::uint64_t residentSetBytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t size = 0, resident = 0;
  if (!(statm >> size >> resident)) return 0;
  return resident * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
}

LightlinkService::LightlinkService(const DaemonConfig& config, SceneRegistry& registry)
    : config_(config), registry_(registry), shared_(config.shared_memory_dir) {
  if (config_.session_idle_timeout_s <= 0.0) return;
  // Checks a tenth of the timeout apart (50 ms .. 5 s): a scene goes at most 10 % late.
  const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(std::clamp(config_.session_idle_timeout_s / 10.0, 0.05, 5.0)));
  reaper_ = std::thread([this, period] {
    std::unique_lock lock(reaper_mutex_);
    while (!reaper_cv_.wait_for(lock, period, [&] { return reaper_stop_; })) {
      lock.unlock();
      if (!draining_.load()) closeIdleScenes();
      lock.lock();
    }
  });
}

LightlinkService::~LightlinkService() {
  {
    std::lock_guard lock(reaper_mutex_);
    reaper_stop_ = true;
  }
  reaper_cv_.notify_all();
  if (reaper_.joinable()) reaper_.join();
}

std::vector<std::string> LightlinkService::closeIdleScenes() {
  std::vector<std::string> closed;
  if (config_.session_idle_timeout_s <= 0.0) return closed;
  const auto timeout = std::chrono::duration<double>(config_.session_idle_timeout_s);
  for (const auto& s : registry_.list()) {
    const auto idle = s->idleFor();
    // A scene still opening (its instant preview shown) has an open call: never idle.
    if (!s->linked() || idle < timeout) continue;
    const std::string& id = s->identity().id;
    if (!registry_.close(id)) continue;  // closed meanwhile
    shared_.dropScene(id);
    {
      std::lock_guard lock(idle_mutex_);
      if (idle_closed_.size() >= 4096) idle_closed_.erase(idle_closed_.begin());
      idle_closed_[id] = std::chrono::system_clock::now();
    }
    logEvent(LogLevel::kInfo, "scene_idle_closed",
             {{"scene", id}, {"idle_s", std::chrono::duration<double>(idle).count()},
              {"timeout_s", config_.session_idle_timeout_s}});
    closed.push_back(id);
  }
  if (!closed.empty())
    if (Status saved = registry_.persistNow(); !saved)
      logEvent(LogLevel::kError, "sessions_write_failed", {{"error", saved.message()}});
  return closed;
}

template <typename Request>
grpc::ServerWriteReactor<grpc::ByteBuffer>* LightlinkService::startResultCall(
    const char* rpc, grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* request,
    grpc::Status (LightlinkService::*body)(grpc::ServerContextBase*, const Request&, ResultCall&)) {
  Request parsed;
  grpc::ByteBuffer bytes(*request);  // a reference to the received slices
  const bool ok = grpc::SerializationTraits<Request>::Deserialize(&bytes, &parsed).ok();
  return new ResultCall(rpc, [this, ctx, rpc, ok, parsed = std::move(parsed), body](ResultCall& call) {
    if (!ok) return grpcError(grpc::StatusCode::INVALID_ARGUMENT, fmt::format("{}: the request is not valid", rpc));
    return (this->*body)(ctx, parsed, call);
  });
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* LightlinkService::Relight(grpc::CallbackServerContext* ctx,
                                                                      const grpc::ByteBuffer* request) {
  return startResultCall("Relight", ctx, request, &LightlinkService::relight);
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* LightlinkService::GetTextures(grpc::CallbackServerContext* ctx,
                                                                          const grpc::ByteBuffer* request) {
  return startResultCall("GetTextures", ctx, request, &LightlinkService::getTextures);
}

grpc::ServerWriteReactor<grpc::ByteBuffer>* LightlinkService::Subscribe(grpc::CallbackServerContext* ctx,
                                                                        const grpc::ByteBuffer* request) {
  return startResultCall("Subscribe", ctx, request, &LightlinkService::subscribe);
}

LightlinkService::StreamSlot::StreamSlot(LightlinkService& service, std::string client)
    : service_(service), client_(std::move(client)) {
  std::lock_guard lock(service_.streams_mutex_);
  int& n = service_.streams_per_client_[client_];
  if (n >= service_.config_.max_streams_per_client) {
    if (n == 0) service_.streams_per_client_.erase(client_);
    return;
  }
  ++n;
  ++service_.active_streams_;
  acquired_ = true;
}

LightlinkService::StreamSlot::~StreamSlot() {
  if (!acquired_) return;
  std::lock_guard lock(service_.streams_mutex_);
  if (--service_.streams_per_client_[client_] == 0) service_.streams_per_client_.erase(client_);
  --service_.active_streams_;
}

grpc::Status LightlinkService::admit(grpc::ServerContextBase* ctx, bool new_work) const {
  const auto& md = ctx->client_metadata();
  const auto it = md.find("authorization");
  const bool present = it != md.end();
  const std::string_view value = present ? std::string_view(it->second.data(), it->second.size()) : std::string_view{};
  if (!config_.token.empty()) {
    // A blocked address is refused before the comparison: guesses teach it nothing.
    const std::string address = peerAddress(ctx->peer());
    if (const auto left = auth_failures_.blockedFor(address); left > AuthFailureLimiter::Clock::duration::zero())
      return grpcError(grpc::StatusCode::RESOURCE_EXHAUSTED,
                       fmt::format("authorization: too many failed attempts from this address; retry in {} s",
                                   std::chrono::ceil<std::chrono::seconds>(left).count()));
    if (std::string why = checkBearer(value, present, config_.token); !why.empty()) {
      logEvent(LogLevel::kWarn, "unauthenticated", {{"peer", ctx->peer()}, {"reason", why}});
      if (auth_failures_.recordFailure(address)) {
        const auto& limits = auth_failures_.limits();
        logEvent(LogLevel::kWarn, "auth_rate_limited",
                 {{"address", address},
                  {"failures", limits.max_failures},
                  {"backoff_s", std::chrono::duration_cast<std::chrono::seconds>(limits.backoff).count()}});
      }
      return grpcError(grpc::StatusCode::UNAUTHENTICATED, why);
    }
  }
  if (new_work && draining_.load())
    return grpcError(grpc::StatusCode::UNAVAILABLE, "daemon: draining (shutting down), no new work accepted");
  return grpc::Status::OK;
}

grpc::Status LightlinkService::lookup(grpc::ServerContextBase* ctx, const v1::SceneRef& ref,
                                      std::shared_ptr<SceneSession>* out) const {
  if (ref.scene_id().empty()) return grpcError(grpc::StatusCode::INVALID_ARGUMENT, "scene.scene_id: required");
  auto s = registry_.find(ref.scene_id());
  const std::string shown = ref.scene_id().substr(0, 64);
  if (!s) {
    // A scene of sessions.json still being re-opened after a restart: the call waits for
    // it within its deadline (token checked first, so a stranger does not wait).
    if (const auto token = registry_.restoringToken(ref.scene_id())) {
      if (!constantTimeEqual(ref.token(), *token))
        return grpcError(grpc::StatusCode::PERMISSION_DENIED, "token: does not match scene '" + shown + "'");
      // A wider margin than a long poll's: the restore keeps the cores busy meanwhile.
      if (registry_.waitRestored(ref.scene_id(), waitDeadline(ctx) - std::chrono::milliseconds(250),
                                 [&] { return ctx->IsCancelled() || draining_.load(); }))
        return grpcError(grpc::StatusCode::UNAVAILABLE,
                         "scene '" + shown + "' is still being restored after the daemon's restart; retry shortly");
      s = registry_.find(ref.scene_id());
    }
  }
  if (!s) {
    std::lock_guard lock(idle_mutex_);
    if (idle_closed_.count(ref.scene_id()))
      return grpcError(grpc::StatusCode::NOT_FOUND,
                       fmt::format("scene_id: scene '{}' was closed after {} s without a client call "
                                   "(the daemon's --session-idle-timeout); open it again",
                                   shown, config_.session_idle_timeout_s));
    return grpcError(grpc::StatusCode::NOT_FOUND, "scene_id: no scene '" + shown + "'");
  }
  if (!constantTimeEqual(ref.token(), s->identity().token))
    return grpcError(grpc::StatusCode::PERMISSION_DENIED, "token: does not match scene '" + shown + "'");
  s->touch();
  *out = std::move(s);
  return grpc::Status::OK;
}

grpc::Status LightlinkService::beginResultCall(grpc::ServerContextBase* ctx, const v1::SceneRef& ref,
                                               const v1::ResultSpec& spec, std::shared_ptr<SceneSession>* scene,
                                               std::optional<StreamSlot>* slot) {
  if (auto st = admit(ctx, true); !st.ok()) return st;
  if (auto st = lookup(ctx, ref, scene); !st.ok()) return st;
  if (Status v = validateSpec(spec, (*scene)->bands()); !v) return toGrpc(v);
  slot->emplace(*this, clientKey(ctx->peer()));
  if (!(*slot)->acquired())
    return grpcError(grpc::StatusCode::RESOURCE_EXHAUSTED, "streams: too many concurrent streams for this client");
  return grpc::Status::OK;
}

Clock::time_point LightlinkService::waitDeadline(grpc::ServerContextBase* ctx) const {
  // The call's own deadline, mapped onto the steady clock; none: kDefaultWait.
  const auto now_sys = std::chrono::system_clock::now();
  const auto d = ctx->deadline();
  const auto cap = Clock::now() + kDefaultWait;
  if (d >= now_sys + kDefaultWait) return cap;
  return Clock::now() + (d - now_sys);
}

grpc::Status LightlinkService::OpenScene(grpc::ServerContext* ctx, const v1::OpenSceneRequest* request,
                                         grpc::ServerWriter<v1::OpenSceneProgress>* writer) {
  if (auto st = admit(ctx, true); !st.ok()) return st;
  StreamSlot slot(*this, clientKey(ctx->peer()));
  if (!slot.acquired())
    return grpcError(grpc::StatusCode::RESOURCE_EXHAUSTED, "streams: too many concurrent streams for this client");
  // Cheap checks first, so a bad request never waits behind a precompute.
  if (auto o = precomputeOptionsFrom(*request); !o) return toGrpc(o.status());
  // Outside the scene roots: one answer for every path, existing or not (scene_roots.h).
  if (request->source_case() == v1::OpenSceneRequest::kPath)
    if (auto admitted = registry_.sceneRoots().admit(request->path()); !admitted)
      return grpcError(grpc::StatusCode::PERMISSION_DENIED, admitted.status().message());
  const int opening = ++opening_;
  struct Release {
    std::atomic<int>& n;
    ~Release() { --n; }
  } release{opening_};
  // A scene showing its instant preview is resident and still opening: counted once.
  if (registry_.sizeWithoutPreviews() + static_cast<std::size_t>(opening) >
      static_cast<std::size_t>(config_.max_scenes))
    return grpcError(grpc::StatusCode::RESOURCE_EXHAUSTED,
                     fmt::format("scenes: the daemon holds its limit of {} scenes (--max-scenes)", config_.max_scenes));

  StreamProgress progress(ctx, writer, draining_);
  const auto started = Clock::now();
  Expected<std::shared_ptr<SceneSession>> session = internalError("OpenScene: not run");
  try {
    session = registry_.open(*request, &progress, [&](const std::shared_ptr<SceneSession>& previewed) {
      v1::OpenSceneProgress m;
      m.set_stage("preview");
      m.set_fraction(1.0f);
      m.set_message("instant preview published; the links are being computed");
      fillPreview(*previewed, std::chrono::duration<double>(Clock::now() - started).count(), m.mutable_preview());
      progress.write(m);
    });
  } catch (const std::bad_alloc&) {
    session = resourceExhausted("out of memory while opening the scene");
  }
  if (!session) {
    if (session.status().code() == Code::kCancelled || ctx->IsCancelled() || draining_) {
      // Logged so an operator (and tests) can see how soon abandoned work stopped.
      logEvent(LogLevel::kInfo, "open_abandoned",
               {{"peer", ctx->peer()},
                {"reason", draining_ ? "draining" : ctx->IsCancelled() ? "client cancelled or deadline" : "deadline"},
                {"seconds", std::chrono::duration<double>(Clock::now() - started).count()}});
    }
    if (ctx->IsCancelled()) return grpcError(grpc::StatusCode::CANCELLED, "OpenScene cancelled by the client");
    if (draining_) return grpcError(grpc::StatusCode::UNAVAILABLE, "daemon: draining, open abandoned");
    if (session.status().code() == Code::kCancelled)
      return grpcError(grpc::StatusCode::DEADLINE_EXCEEDED, "OpenScene: the call's deadline passed; open abandoned");
    logEvent(LogLevel::kWarn, "open_failed",
             {{"peer", ctx->peer()}, {"code", codeName(session.status().code())}, {"error", session.status().message()}});
    return toGrpc(session.status());
  }
  v1::OpenSceneProgress last;
  last.set_stage("ready");
  last.set_fraction(1.0f);
  last.set_message((*session)->resident().note());
  fillOpened(**session, last.mutable_opened());
  progress.finish(last);
  return grpc::Status::OK;
}

grpc::Status LightlinkService::UpdateLights(grpc::ServerContext* ctx, const v1::UpdateLightsRequest* request,
                                            v1::UpdateLightsResponse* response) {
  if (auto st = admit(ctx, true); !st.ok()) return st;
  std::shared_ptr<SceneSession> s;
  if (auto st = lookup(ctx, request->scene(), &s); !st.ok()) return st;
  return answerUpdate(ctx, *s, "UpdateLights", [&] { return s->update(*request); }, request->wait_ms(), response);
}

grpc::Status LightlinkService::SetScenario(grpc::ServerContext* ctx, const v1::SetScenarioRequest* request,
                                           v1::SetScenarioResponse* response) {
  if (auto st = admit(ctx, true); !st.ok()) return st;
  std::shared_ptr<SceneSession> s;
  if (auto st = lookup(ctx, request->scene(), &s); !st.ok()) return st;
  std::optional<relight::LightSet> previous;
  auto names = s->setScenario(*request, &previous);
  if (!names) return toGrpc(names.status());
  // Acknowledged only once sessions.json holds it; otherwise it is undone.
  if (Status p = registry_.persistNow(); !p) {
    s->restoreScenario(request->name(), std::move(previous));
    return grpcError(grpc::StatusCode::UNAVAILABLE, "the scenario could not be persisted: " + p.message());
  }
  logEvent(LogLevel::kInfo, "scenario_set",
           {{"scene", s->identity().id}, {"name", request->name()}, {"removed", request->has_remove()}});
  for (const std::string& n : *names) response->add_scenarios(n);
  return grpc::Status::OK;
}

grpc::Status LightlinkService::UseScenarios(grpc::ServerContext* ctx, const v1::UseScenariosRequest* request,
                                            v1::UpdateLightsResponse* response) {
  if (auto st = admit(ctx, true); !st.ok()) return st;
  std::shared_ptr<SceneSession> s;
  if (auto st = lookup(ctx, request->scene(), &s); !st.ok()) return st;
  return answerUpdate(ctx, *s, "UseScenarios", [&] { return s->useScenarios(*request); }, request->wait_ms(),
                      response);
}

grpc::Status LightlinkService::answerUpdate(grpc::ServerContext* ctx, SceneSession& session, const char* rpc,
                                            const std::function<Expected<std::uint64_t>()>& change,
                                            std::uint32_t wait_ms, v1::UpdateLightsResponse* response) {
  SceneSession* s = &session;
  Expected<std::uint64_t> v = internalError("{}: not run", rpc);
  try {
    v = change();
  } catch (const std::bad_alloc&) {
    logEvent(LogLevel::kError, "out_of_memory", {{"rpc", rpc}, {"scene", s->identity().id}});
    return grpcError(grpc::StatusCode::RESOURCE_EXHAUSTED, "out of memory while updating the lights");
  }
  if (!v) {
    // Not persisted (disk full, I/O error): nothing changed, the client may retry.
    if (v.status().code() == Code::kIoError) return grpcError(grpc::StatusCode::UNAVAILABLE, v.status().message());
    logEvent(LogLevel::kDebug, "update_rejected", {{"scene", s->identity().id}, {"error", v.status().message()}});
    return toGrpc(v.status());
  }
  // Durable: the version is in the journal (SceneSession::update).
  response->set_version(*v);
  if (wait_ms > 0) {
    const auto deadline = std::min(waitDeadline(ctx), Clock::now() + std::chrono::milliseconds(wait_ms));
    auto snap = s->waitForVersion(*v, deadline, [&] { return ctx->IsCancelled(); });
    response->set_relit(snap != nullptr);
  } else {
    auto snap = s->latest();
    response->set_relit(snap && snap->version >= *v);
  }
  return grpc::Status::OK;
}

grpc::Status LightlinkService::sendResult(grpc::ServerContextBase* ctx, const Snapshot& snap, const SpecKey& spec,
                                          bool shared_memory, ResultCall& call) {
  if (shared_memory && shared_.enabled() && isLocalPeer(ctx->peer())) {
    const auto wire = snap.wire(spec, config_.chunk_bytes);
    if (!wire) return grpcError(grpc::StatusCode::INTERNAL, "result: could not serialize the result messages");
    auto header = shared_.header(snap, spec, config_.chunk_bytes, *wire);
    if (header) {
      // The one message goes out with the call's status: one flush and one wake-up of the
      // client instead of two.
      call.writeLast(**header);
      return grpc::Status::OK;
    }
    // No file (no space, an old result): the stream still works.
    logEvent(LogLevel::kDebug, "shared_memory_skipped", {{"scene", snap.scene_id}, {"reason", header.status().message()}});
  }
  return sendWire(snap, spec, config_.chunk_bytes, call, CallEnds::kAfterThisResult);
}

grpc::Status LightlinkService::relight(grpc::ServerContextBase* ctx, const v1::RelightRequest& request,
                                       ResultCall& call) {
  std::shared_ptr<SceneSession> s;
  std::optional<StreamSlot> slot;
  if (auto st = beginResultCall(ctx, request.scene(), request.spec(), &s, &slot); !st.ok()) return st;
  const std::uint64_t newest = s->version();
  if (request.version() > newest)
    return grpcError(grpc::StatusCode::OUT_OF_RANGE, fmt::format("version: {} is newer than the scene's newest version {}",
                                                                 request.version(), newest));
  auto snap = s->waitForVersion(request.version(), waitDeadline(ctx), [&] { return ctx->IsCancelled() || draining_; });
  if (!snap) {
    if (ctx->IsCancelled()) return grpcError(grpc::StatusCode::CANCELLED, "cancelled");
    if (s->closed()) return grpcError(grpc::StatusCode::NOT_FOUND, "scene_id: the scene was closed");
    if (draining_) return grpcError(grpc::StatusCode::UNAVAILABLE, "daemon: draining");
    return grpcError(grpc::StatusCode::DEADLINE_EXCEEDED,
                     fmt::format("version: no result >= {} within the deadline", request.version()));
  }
  return sendResult(ctx, *snap, SpecKey::from(request.spec(), snap->bands), request.shared_memory(), call);
}

grpc::Status LightlinkService::getTextures(grpc::ServerContextBase* ctx, const v1::GetTexturesRequest& request,
                                           ResultCall& call) {
  std::shared_ptr<SceneSession> s;
  std::optional<StreamSlot> slot;
  if (auto st = beginResultCall(ctx, request.scene(), request.spec(), &s, &slot); !st.ok()) return st;
  if (request.wait_ms() > kMaxWaitMs)
    return grpcError(grpc::StatusCode::INVALID_ARGUMENT,
                     fmt::format("wait_ms: {} is above the limit of {}", request.wait_ms(), kMaxWaitMs));
  const auto stop = [&] { return ctx->IsCancelled() || draining_.load(); };
  auto snap = s->latest();
  // Right after OpenScene the first result may still be computing: wait for it.
  if (!snap) snap = s->waitForVersion(0, waitDeadline(ctx), stop);
  if (!snap) return grpcError(grpc::StatusCode::UNAVAILABLE, "scene: no result computed yet");
  if (snap->version == request.last_seen_version() && request.wait_ms() > 0) {
    // Long poll: hold the call until a newer result is published. Results are published
    // in increasing version order, so "newer" is "version > the one the client has". The
    // answer leaves a little before the call's deadline, so a client whose deadline is
    // shorter than wait_ms gets not_modified rather than DEADLINE_EXCEEDED.
    const auto by_call = waitDeadline(ctx) - kAnswerMargin;
    const auto deadline = std::min(by_call, Clock::now() + std::chrono::milliseconds(request.wait_ms()));
    if (auto newer = s->waitForVersion(snap->version + 1, deadline, stop)) {
      snap = std::move(newer);
    } else {
      if (ctx->IsCancelled()) return grpcError(grpc::StatusCode::CANCELLED, "cancelled");
      if (s->closed()) return grpcError(grpc::StatusCode::NOT_FOUND, "scene_id: the scene was closed");
      // Deadline or drain: the plain answer, not modified.
    }
  }
  if (snap->version == request.last_seen_version()) return sendNotModified(*s, *snap, call);
  return sendResult(ctx, *snap, SpecKey::from(request.spec(), snap->bands), request.shared_memory(), call);
}

grpc::Status LightlinkService::subscribe(grpc::ServerContextBase* ctx, const v1::SubscribeRequest& request,
                                         ResultCall& call) {
  std::shared_ptr<SceneSession> s;
  std::optional<StreamSlot> slot;
  if (auto st = beginResultCall(ctx, request.scene(), request.spec(), &s, &slot); !st.ok()) return st;
  s->addSubscriber(1);
  struct Unsubscribe {
    SceneSession& s;
    ~Unsubscribe() { s.addSubscriber(-1); }
  } unsubscribe{*s};

  std::uint64_t last_sequence = 0;
  std::shared_ptr<const Snapshot> previous;  // the result this stream sent last
  const auto stop = [&] { return ctx->IsCancelled() || draining_.load(); };
  while (true) {
    auto snap = s->waitForNewer(last_sequence, Clock::now() + std::chrono::seconds(1), stop);
    if (!snap) {
      if (ctx->IsCancelled()) return grpcError(grpc::StatusCode::CANCELLED, "cancelled");
      // Drain or close: the stream ends cleanly, the client sees OK after the last full result.
      if (draining_ || s->closed()) return grpc::Status::OK;
      continue;
    }
    last_sequence = snap->sequence;
    if (snap->version <= request.after_version()) continue;
    // Streams that sent the same previous result send the same bytes: one wire form for
    // all of them (Snapshot::wire), full or delta.
    const SpecKey spec = SpecKey::from(request.spec(), snap->bands);
    if (auto st = sendWire(*snap, spec, config_.chunk_bytes, call, CallEnds::kLater, previous.get(),
                            request.deltas()); !st.ok())
      return st;
    previous = std::move(snap);
  }
}

grpc::Status LightlinkService::GetLights(grpc::ServerContext* ctx, const v1::GetLightsRequest* request,
                                         v1::GetLightsResponse* response) {
  if (auto st = admit(ctx, false); !st.ok()) return st;
  std::shared_ptr<SceneSession> s;
  if (auto st = lookup(ctx, request->scene(), &s); !st.ok()) return st;
  std::uint64_t version = 0;
  const relight::LightSet lights = s->lightSet(&version);
  response->set_version(version);
  response->set_light_set_json(lights.toJson().dump(2));
  for (const auto& e : lights.lights()) *response->add_lights() = toProtoLight(e);
  return grpc::Status::OK;
}

namespace {

// The scene written back as .glb with its lightmap UVs (charts::writeGltfWithLightmapUv), in
// a folder of its own under the cache directory that is removed afterwards (the writer may
// copy images next to its output).
Expected<std::string> lightmapGlb(const std::string& cache_dir, const SceneSession& s) {
  namespace fs = std::filesystem;
  static std::atomic<std::uint64_t> serial{0};
  const fs::path dir = fs::path(cache_dir) / fmt::format(".uvs.{}.{}", ::getpid(), serial++);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return ioError("gltf: cannot create {}: {}", dir.string(), ec.message());
  struct Remove {
    fs::path dir;
    ~Remove() {
      std::error_code ignored;
      fs::remove_all(dir, ignored);
    }
  } remove{dir};
  const fs::path out = dir / "scene_lm.glb";
  const auto& r = s.resident();
  if (Status w = charts::writeGltfWithLightmapUv(s.identity().source_path, r.scene(), r.atlas(), out.string()); !w)
    return w;
  std::ifstream in(out, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!in.good() && !in.eof()) return ioError("gltf: cannot read {}", out.string());
  return bytes;
}

}  // namespace

grpc::Status LightlinkService::GetLightmapUvs(grpc::ServerContext* ctx, const v1::GetLightmapUvsRequest* request,
                                              grpc::ServerWriter<v1::LightmapUvsMessage>* writer) {
  if (auto st = admit(ctx, true); !st.ok()) return st;
  std::shared_ptr<SceneSession> s;
  if (auto st = lookup(ctx, request->scene(), &s); !st.ok()) return st;
  if (!s->linked())
    return grpcError(grpc::StatusCode::UNAVAILABLE,
                     "scene: its lightmap UVs exist once the precompute is done (OpenScene's last message); "
                     "the instant preview has none");
  const auto& r = s->resident();
  const auto& scene = r.scene();
  const auto& atlas = r.atlas();
  std::string glb;
  if (request->gltf()) {
    auto bytes = lightmapGlb(config_.cache_dir, *s);
    if (!bytes) return toGrpc(bytes.status());
    glb = std::move(*bytes);
  }
  const auto& p = r.precomputation();
  v1::LightmapUvsMessage m;
  auto* h = m.mutable_header();
  h->set_width(p.lightmap.width);
  h->set_height(p.lightmap.height);
  h->set_texel_size_m(atlas.texel_size_m);
  h->set_generated(atlas.generated);
  h->set_meshes(static_cast<std::uint32_t>(scene.meshes.size()));
  h->set_glb_bytes(glb.size());
  if (!writer->Write(m)) return grpcError(grpc::StatusCode::CANCELLED, "the client went away");

  // About --chunk-bytes of arrays per message, well below the send limit: a vertex costs 8
  // bytes of uv and at most 5 of source index, a triangle index 4 bytes.
  const std::size_t budget = config_.chunk_bytes;
  const std::size_t verts_per_message = budget / 16, indices_per_message = budget / 8;
  for (std::size_t i = 0; i < scene.meshes.size(); ++i) {
    const auto& inst = scene.meshes[i];
    const bool lit = charts::isLightmapped(scene, atlas, i);
    const std::vector<std::uint32_t>* source =
        i < atlas.meshes.size() ? &atlas.meshes[i].source_vertex : nullptr;
    const std::size_t nv = lit ? inst.uv1.size() : 0, ni = lit ? inst.indices.size() : 0;
    std::size_t v0 = 0, i0 = 0;
    do {
      v1::LightmapUvsMessage out;
      auto* mesh = out.mutable_mesh();
      mesh->set_index(static_cast<std::uint32_t>(i));
      mesh->set_vertex_offset(static_cast<std::uint32_t>(v0));
      mesh->set_vertex_count(static_cast<std::uint32_t>(nv));
      mesh->set_index_offset(static_cast<std::uint32_t>(i0));
      mesh->set_index_count(static_cast<std::uint32_t>(ni));
      if (v0 == 0 && i0 == 0) {
        mesh->set_name(inst.name);
        mesh->set_node(inst.gltf_node);
        mesh->set_mesh(inst.gltf_mesh);
        mesh->set_primitive(inst.gltf_primitive);
        mesh->set_lightmapped(lit);
      }
      const std::size_t v1n = std::min(nv, v0 + verts_per_message), i1n = std::min(ni, i0 + indices_per_message);
      if (v1n > v0) {
        mesh->mutable_uv()->assign(reinterpret_cast<const char*>(inst.uv1.data() + v0), (v1n - v0) * sizeof(glm::vec2));
        if (source && !source->empty())
          for (std::size_t k = v0; k < v1n; ++k) mesh->add_source_vertex((*source)[k]);
      }
      if (i1n > i0)
        mesh->mutable_indices()->assign(reinterpret_cast<const char*>(inst.indices.data() + i0),
                                        (i1n - i0) * sizeof(std::uint32_t));
      v0 = v1n;
      i0 = i1n;
      if (!writer->Write(out)) return grpcError(grpc::StatusCode::CANCELLED, "the client went away");
    } while (v0 < nv || i0 < ni);
  }
  for (std::size_t off = 0; off < glb.size(); off += config_.chunk_bytes) {
    v1::LightmapUvsMessage out;
    out.mutable_glb()->set_offset(off);
    out.mutable_glb()->set_data(glb.substr(off, config_.chunk_bytes));
    if (!writer->Write(out)) return grpcError(grpc::StatusCode::CANCELLED, "the client went away");
  }
  return grpc::Status::OK;
}

grpc::Status LightlinkService::ListScenes(grpc::ServerContext* ctx, const v1::ListScenesRequest*,
                                          v1::ListScenesResponse* response) {
  if (auto st = admit(ctx, false); !st.ok()) return st;
  for (const auto& s : registry_.list()) {
    auto* out = response->add_scenes();
    const auto st = s->stats();
    out->set_scene_id(s->identity().id);
    out->set_name(s->identity().name);
    out->set_source(s->identity().source_label);
    out->set_version(st.version);
    out->set_result_version(st.result_version);
    out->set_backend(s->backendName());
    for (const std::string& n : s->scenarioNames()) out->add_scenarios(n);
  }
  for (const auto& r : registry_.restoring()) {
    auto* out = response->add_scenes();
    out->set_scene_id(r.id);
    out->set_name(r.name);
    out->set_source(r.source_label);
    out->set_version(r.version);
    out->set_backend("restoring");  // re-opened in the background after a restart
  }
  return grpc::Status::OK;
}

grpc::Status LightlinkService::CloseScene(grpc::ServerContext* ctx, const v1::CloseSceneRequest* request,
                                          v1::CloseSceneResponse*) {
  if (auto st = admit(ctx, false); !st.ok()) return st;
  std::shared_ptr<SceneSession> s;
  if (auto st = lookup(ctx, request->scene(), &s); !st.ok()) return st;
  if (!registry_.close(s->identity().id))
    return grpcError(grpc::StatusCode::NOT_FOUND, "scene_id: the scene was already closed");
  shared_.dropScene(s->identity().id);
  // Durable like an update: a close acknowledged and then undone by a crash would bring the
  // scene (and its token) back after the restart.
  if (Status saved = registry_.persistNow(); !saved) {
    logEvent(LogLevel::kError, "sessions_write_failed", {{"error", saved.message()}});
    return grpcError(grpc::StatusCode::UNAVAILABLE,
                     "sessions: the scene is closed, but the close could not be persisted (" + saved.message() +
                         "); it may come back after a restart");
  }
  return grpc::Status::OK;
}

grpc::Status LightlinkService::Health(grpc::ServerContext* ctx, const v1::HealthRequest*,
                                      v1::HealthResponse* response) {
  if (auto st = admit(ctx, false); !st.ok()) return st;
  response->set_status(draining_ ? v1::HealthResponse::STATUS_DRAINING : v1::HealthResponse::STATUS_SERVING);
  response->set_protocol_version(1);
  response->set_daemon_version("0.1.0");
  // Probing creates a GL context once per process; only when the daemon may use the GPU.
  if (config_.backend != "cpu") {
    const auto& probe = gpu::probeGpu();
    response->set_gpu_available(probe.available);
    response->set_gpu_renderer(probe.available ? probe.renderer : probe.error);
  }
  return grpc::Status::OK;
}

grpc::Status LightlinkService::Stats(grpc::ServerContext* ctx, const v1::StatsRequest* request,
                                     v1::StatsResponse* response) {
  if (auto st = admit(ctx, false); !st.ok()) return st;
  response->set_uptime_ms(static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - started_).count()));
  response->set_scenes(static_cast<std::uint32_t>(registry_.size()));
  response->set_active_streams(static_cast<std::uint32_t>(active_streams_.load()));
  response->set_rss_bytes(residentSetBytes());
  response->set_shared_memory_files(static_cast<std::uint32_t>(shared_.fileCount()));
  response->set_shared_memory_bytes(shared_.byteCount());
  if (!request->scene().scene_id().empty()) {
    std::shared_ptr<SceneSession> s;
    if (auto st = lookup(ctx, request->scene(), &s); !st.ok()) return st;
    const auto st = s->stats();
    auto* out = response->add_scene();
    out->set_scene_id(s->identity().id);
    out->set_version(st.version);
    out->set_result_version(st.result_version);
    out->set_updates(st.updates);
    out->set_relights(st.relights);
    out->set_coalesced(st.coalesced);
    out->set_last_relight_ms(st.last_relight_ms);
    out->set_mean_relight_ms(st.mean_relight_ms);
    out->set_resident_bytes(st.resident_bytes);
    out->set_artifact_bytes(st.artifact_bytes);
    out->set_subscribers(st.subscribers);
    out->set_previews(st.previews);
    out->set_instant_previews(st.instant_previews);
    out->set_backend(s->backendName());
    out->set_backend_note(s->backendNote());
  }
  return grpc::Status::OK;
}

void LightlinkService::beginDrain() {
  draining_ = true;
  for (const auto& s : registry_.list()) s->wakeAll();
}

}  // namespace lightlink::service
