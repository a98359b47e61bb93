// Client: one gRPC channel, thin wrappers that translate requests in and statuses out.
#include "clients/client/client.h"

#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>

#include <grpcpp/grpcpp.h>

#include "clients/client/shared_result.h"
#include "proto/lightlink.grpc.pb.h"

namespace lightlink::client {
namespace {

// The daemon sends messages of at most 4 MiB; leave headroom so a daemon configured with a
// slightly larger chunk does not break clients. Requests carry at most a 64 MiB glTF.
constexpr int kMaxReceiveBytes = 8 << 20;
constexpr int kMaxSendBytes = (64 << 20) + (1 << 20);

Status fromGrpc(const char* rpc, const grpc::Status& s) {
  if (s.ok()) return {};
  return Status(codeForGrpc(s.error_code()),
                fmt::format("{}: {}: {}", rpc, grpcCodeName(s.error_code()), s.error_message()));
}

v1::ResultSpec toProto(const ResultSpec& spec) {
  v1::ResultSpec p;
  p.set_skip_lightmap(!spec.lightmap);
  p.set_skip_grid(!spec.grid);
  p.set_bands(spec.bands);
  p.set_component(spec.component == Component::kIndirect ? v1::COMPONENT_INDIRECT
                  : spec.component == Component::kDirect ? v1::COMPONENT_DIRECT
                                                         : v1::COMPONENT_BOTH);
  p.set_precision(spec.precision == Precision::kFloat ? v1::PRECISION_FLOAT : v1::PRECISION_HALF);
  return p;
}

void setRef(v1::SceneRef* ref, const SceneHandle& scene) {
  ref->set_scene_id(scene.id);
  ref->set_token(scene.token);
}

Expected<std::string> readFile(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return notFound("{}: cannot open {}", path, what);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// How the generated stub starts a Relight or GetTextures call.
template <typename Request>
using ResultCallStarter = std::unique_ptr<grpc::ClientReader<v1::ResultMessage>> (v1::Lightlink::Stub::*)(
    grpc::ClientContext*, const Request&);

// Reads the one result (header + chunks) a Relight or GetTextures stream carries. When the
// header names a shared-memory file instead, the chunks are read from it (shared_result.h);
// if that fails, `*shared_unreadable` is set and the error returned, for the caller to ask
// again on the stream.
template <typename Request>
Expected<Textures> readOneResult(const char* rpc, v1::Lightlink::Stub& stub, ResultCallStarter<Request> start,
                                 grpc::ClientContext& ctx, const Request& request, bool* shared_unreadable = nullptr) {
  std::unique_ptr<grpc::ClientReader<v1::ResultMessage>> reader = (stub.*start)(&ctx, request);
  ResultAssembler assembler;
  v1::ResultMessage msg;
  std::optional<v1::SharedResult> shared;
  while (reader->Read(&msg)) {
    if (msg.has_header() && msg.header().has_shared()) shared = msg.header().shared();
    if (Status status = assembler.add(msg); !status) {
      // A torn or malformed result: stop the call, drain what is in flight, report.
      ctx.TryCancel();
      while (reader->Read(&msg)) {
      }
      (void)reader->Finish();
      return Status(status.code(), fmt::format("{}: {}", rpc, status.message()));
    }
  }
  if (Status s = fromGrpc(rpc, reader->Finish()); !s) return s;
  if (shared) {
    if (Status s = readSharedResult(*shared, assembler); !s) {
      if (shared_unreadable) *shared_unreadable = true;
      return Status(s.code(), fmt::format("{}: {}", rpc, s.message()));
    }
  }
  auto t = assembler.take();
  if (!t) return Status(t.status().code(), fmt::format("{}: {}", rpc, t.status().message()));
  return t;
}

}  // namespace

const char* grpcCodeName(int code) {
  static const char* const kNames[] = {"OK",
                                       "CANCELLED",
                                       "UNKNOWN",
                                       "INVALID_ARGUMENT",
                                       "DEADLINE_EXCEEDED",
                                       "NOT_FOUND",
                                       "ALREADY_EXISTS",
                                       "PERMISSION_DENIED",
                                       "RESOURCE_EXHAUSTED",
                                       "FAILED_PRECONDITION",
                                       "ABORTED",
                                       "OUT_OF_RANGE",
                                       "UNIMPLEMENTED",
                                       "INTERNAL",
                                       "UNAVAILABLE",
                                       "DATA_LOSS",
                                       "UNAUTHENTICATED"};
  return code >= 0 && code < int(std::size(kNames)) ? kNames[code] : "UNKNOWN";
}

Code codeForGrpc(int code) {
  switch (grpc::StatusCode(code)) {
    case grpc::OK: return Code::kOk;
    case grpc::INVALID_ARGUMENT:
    case grpc::OUT_OF_RANGE:
    case grpc::FAILED_PRECONDITION:
    case grpc::ALREADY_EXISTS:
    case grpc::PERMISSION_DENIED:
    case grpc::UNAUTHENTICATED: return Code::kInvalidInput;
    case grpc::RESOURCE_EXHAUSTED: return Code::kResourceExhausted;
    case grpc::NOT_FOUND: return Code::kNotFound;
    case grpc::UNIMPLEMENTED: return Code::kUnsupported;
    case grpc::UNAVAILABLE:
    case grpc::DEADLINE_EXCEEDED:
    case grpc::CANCELLED: return Code::kIoError;
    default: return Code::kInternal;
  }
}

SceneHandle SceneHandle::fromIdToken(std::string id, std::string token) {
  SceneHandle h;
  h.id = std::move(id);
  h.token = std::move(token);
  h.info.set_scene_id(h.id);
  return h;
}

struct Client::Impl {
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::Lightlink::Stub> rpc;  // gRPC's generated client ("Stub" is its class name)
  std::string authorization;  // "Bearer <token>" or empty
  std::chrono::milliseconds call_timeout{0};

  // Every call's context is set up here: the bearer token and, unless `no_deadline`, the
  // call deadline. One place, so no RPC forgets either.
  void prepare(grpc::ClientContext& ctx, std::chrono::milliseconds deadline) const {
    if (!authorization.empty()) ctx.AddMetadata("authorization", authorization);
    if (deadline.count() > 0) ctx.set_deadline(std::chrono::system_clock::now() + deadline);
  }
  void prepare(grpc::ClientContext& ctx) const { prepare(ctx, call_timeout); }
  // The deadline of a call that may wait `wait_ms` at the daemon: a waiting call must
  // outlive its wait.
  std::chrono::milliseconds waitingDeadline(std::uint32_t wait_ms) const {
    return call_timeout.count() > 0 ? call_timeout + std::chrono::milliseconds(wait_ms) : call_timeout;
  }
  // One Relight or GetTextures call. When its header named a shared-memory file that could
  // not be read (removed, another user's daemon), the same call again on the stream: the
  // request without shared_memory and, for a long poll, with wait_ms 0 (the daemon just
  // named a result newer than last_seen_version).
  template <typename Request>
  Expected<Textures> readResult(const char* rpc, ResultCallStarter<Request> start, Request req,
                                std::chrono::milliseconds deadline) const {
    bool shared_unreadable = false;
    {
      grpc::ClientContext ctx;
      prepare(ctx, deadline);
      auto t = readOneResult(rpc, *this->rpc, start, ctx, req, &shared_unreadable);
      if (t || !shared_unreadable) return t;
    }
    req.set_shared_memory(false);
    if constexpr (requires { req.set_wait_ms(0u); }) req.set_wait_ms(0);
    grpc::ClientContext ctx;
    prepare(ctx);
    return readOneResult(rpc, *this->rpc, start, ctx, req);
  }
};

Client::Client(ConnectOptions options, std::unique_ptr<Impl> impl)
    : options_(std::move(options)), impl_(std::move(impl)) {}
Client::Client(Client&&) noexcept = default;
Client& Client::operator=(Client&&) noexcept = default;
Client::~Client() = default;

Expected<Client> Client::connect(const ConnectOptions& options) {
  if (options.target.empty()) return invalidInput("target: empty (expected host:port)");
  std::shared_ptr<grpc::ChannelCredentials> creds;
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(kMaxReceiveBytes);
  args.SetMaxSendMessageSize(kMaxSendBytes);
  if (options.own_connection) args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  if (!options.tls_root_cert.empty()) {
    auto pem = readFile(options.tls_root_cert, "TLS root certificate");
    if (!pem) return pem.status();
    grpc::SslCredentialsOptions ssl;
    ssl.pem_root_certs = *pem;
    creds = grpc::SslCredentials(ssl);
    if (!options.tls_server_name.empty()) args.SetSslTargetNameOverride(options.tls_server_name);
  } else {
    creds = grpc::InsecureChannelCredentials();
  }
  auto impl = std::make_unique<Impl>();
  impl->channel = grpc::CreateCustomChannel(options.target, creds, args);
  if (!impl->channel) return invalidInput("target: cannot create a channel to '{}'", options.target);
  impl->rpc = v1::Lightlink::NewStub(impl->channel);
  if (!options.bearer_token.empty()) impl->authorization = "Bearer " + options.bearer_token;
  impl->call_timeout = options.call_timeout;
  if (options.connect_timeout.count() > 0 &&
      !impl->channel->WaitForConnected(std::chrono::system_clock::now() + options.connect_timeout))
    return ioError("target: no lightlink daemon answered at '{}' within {} ms", options.target,
                   options.connect_timeout.count());
  return Client(options, std::move(impl));
}

namespace {

SceneHandle handleOf(const v1::SceneOpened& opened) {
  SceneHandle h;
  h.id = opened.scene_id();
  h.token = opened.scene_token();
  h.light_ids.insert(opened.light_ids().begin(), opened.light_ids().end());
  h.ids_known = true;
  h.info = opened;
  return h;
}

}  // namespace

Expected<SceneHandle> Client::openScene(const OpenOptions& o, const ProgressCallback& progress,
                                        const PreviewCallback& on_preview) {
  if (o.path.empty() == o.gltf_bytes.empty()) return invalidInput("open: give exactly one of path and gltf_bytes");
  v1::OpenSceneRequest req;
  if (!o.path.empty()) req.set_path(o.path);
  else req.set_gltf_bytes(o.gltf_bytes);
  req.set_preset(o.preset);
  req.set_surfels(o.surfels);
  req.set_links(o.links);
  req.set_bands(o.bands);
  req.set_rays(o.rays);
  req.set_grid_spacing(o.grid_spacing_m);
  req.set_texel_size(o.texel_size_m);
  req.set_hierarchy(o.hierarchy);
  for (const auto& [name, value] : o.options) (*req.mutable_options())[name] = value;
  req.set_backend(o.backend);
  req.set_lightset_json(o.lightset_json);
  req.set_name(o.name);
  if (o.preview) req.set_preview(*o.preview);
  grpc::ClientContext ctx;
  impl_->prepare(ctx, o.timeout);
  auto reader = impl_->rpc->OpenScene(&ctx, req);
  v1::OpenSceneProgress msg;
  std::optional<v1::SceneOpened> opened;
  while (reader->Read(&msg)) {
    if (progress) progress(msg);
    if (msg.has_preview() && on_preview) on_preview(handleOf(msg.preview()));
    if (msg.has_opened()) opened = msg.opened();
  }
  if (Status s = fromGrpc("OpenScene", reader->Finish()); !s) return s;
  if (!opened) return internalError("OpenScene: the stream ended without an `opened` message");
  return handleOf(*opened);
}

Expected<UpdateResult> Client::updateLights(SceneHandle& scene, const LightUpdate& update, std::uint32_t wait_ms) {
  v1::UpdateLightsRequest req = update.proto();
  setRef(req.mutable_scene(), scene);
  req.set_wait_ms(wait_ms);
  grpc::ClientContext ctx;
  impl_->prepare(ctx, impl_->waitingDeadline(wait_ms));
  v1::UpdateLightsResponse resp;
  if (Status s = fromGrpc("UpdateLights", impl_->rpc->UpdateLights(&ctx, req, &resp)); !s) return s;
  if (scene.ids_known) update.applyToIds(scene.light_ids);
  return UpdateResult{resp.version(), resp.relit()};
}

Expected<UpdateResult> Client::updateLightsFromJson(SceneHandle& scene, const std::string& json_text,
                                                    std::uint32_t wait_ms) {
  auto update = LightUpdate::fromLightSetText(json_text, scene.ids_known ? &scene.light_ids : nullptr);
  if (!update) return update.status();
  return updateLights(scene, *update, wait_ms);
}

namespace {
Expected<std::vector<std::string>> scenarioNames(const Status& s, const v1::SetScenarioResponse& resp) {
  if (!s) return s;
  return std::vector<std::string>(resp.scenarios().begin(), resp.scenarios().end());
}
}  // namespace

Expected<std::vector<std::string>> Client::setScenario(const SceneHandle& scene, const std::string& name,
                                                       const std::string& light_set_json) {
  v1::SetScenarioRequest req;
  setRef(req.mutable_scene(), scene);
  req.set_name(name);
  if (light_set_json.empty()) req.set_from_current(true);
  else req.set_light_set_json(light_set_json);
  grpc::ClientContext ctx;
  impl_->prepare(ctx, impl_->call_timeout);
  v1::SetScenarioResponse resp;
  return scenarioNames(fromGrpc("SetScenario", impl_->rpc->SetScenario(&ctx, req, &resp)), resp);
}

Expected<std::vector<std::string>> Client::removeScenario(const SceneHandle& scene, const std::string& name) {
  v1::SetScenarioRequest req;
  setRef(req.mutable_scene(), scene);
  req.set_name(name);
  req.set_remove(true);
  grpc::ClientContext ctx;
  impl_->prepare(ctx, impl_->call_timeout);
  v1::SetScenarioResponse resp;
  return scenarioNames(fromGrpc("SetScenario", impl_->rpc->SetScenario(&ctx, req, &resp)), resp);
}

Expected<UpdateResult> Client::useScenarios(SceneHandle& scene, const std::vector<lights::ScenarioWeight>& weights,
                                            std::uint32_t wait_ms) {
  v1::UseScenariosRequest req;
  setRef(req.mutable_scene(), scene);
  for (const auto& w : weights) {
    auto* out = req.add_weights();
    out->set_name(w.name);
    out->set_weight(w.weight);
  }
  req.set_wait_ms(wait_ms);
  grpc::ClientContext ctx;
  impl_->prepare(ctx, impl_->waitingDeadline(wait_ms));
  v1::UpdateLightsResponse resp;
  if (Status s = fromGrpc("UseScenarios", impl_->rpc->UseScenarios(&ctx, req, &resp)); !s) return s;
  scene.light_ids.clear();
  scene.ids_known = false;
  return UpdateResult{resp.version(), resp.relit()};
}

Expected<Textures> Client::relight(const SceneHandle& scene, std::uint64_t version, const ResultSpec& spec) {
  v1::RelightRequest req;
  setRef(req.mutable_scene(), scene);
  req.set_version(version);
  *req.mutable_spec() = toProto(spec);
  req.set_shared_memory(options_.shared_memory);
  return impl_->readResult("Relight", &v1::Lightlink::Stub::Relight, std::move(req), impl_->call_timeout);
}

Expected<std::optional<Textures>> Client::getTextures(const SceneHandle& scene, std::uint64_t last_seen_version,
                                                      const ResultSpec& spec, std::uint32_t wait_ms) {
  v1::GetTexturesRequest req;
  setRef(req.mutable_scene(), scene);
  req.set_last_seen_version(last_seen_version);
  *req.mutable_spec() = toProto(spec);
  req.set_wait_ms(wait_ms);
  req.set_shared_memory(options_.shared_memory);
  auto t = impl_->readResult("GetTextures", &v1::Lightlink::Stub::GetTextures, std::move(req),
                             impl_->waitingDeadline(wait_ms));
  if (!t) return t.status();
  if (t->info.not_modified) return std::optional<Textures>{};
  return std::optional<Textures>(std::move(t).value());
}

struct Subscription::Stream {
  grpc::ClientContext ctx;
  std::unique_ptr<grpc::ClientReader<v1::ResultMessage>> reader;
  ResultAssembler assembler;
  v1::ResultMessage msg;
  std::atomic<bool> cancelled{false};
};

Subscription::~Subscription() {
  if (stream_ && !done_) {
    // Finish() on a live stream would block until the daemon ends it: cancel first.
    stream_->ctx.TryCancel();
    while (stream_->reader->Read(&stream_->msg)) {
    }
    (void)stream_->reader->Finish();
  }
}

void Subscription::cancel() {
  if (!stream_) return;
  stream_->cancelled = true;
  stream_->ctx.TryCancel();
}

Expected<const Textures*> Subscription::next() {
  if (done_) return static_cast<const Textures*>(nullptr);
  Stream& s = *stream_;
  while (s.reader->Read(&s.msg)) {
    if (Status st = s.assembler.add(s.msg); !st) return Status(st.code(), "Subscribe: " + st.message());
    if (!s.assembler.complete()) continue;
    auto t = s.assembler.take(have_current_ ? &current_ : nullptr);
    if (!t) return Status(t.status().code(), "Subscribe: " + t.status().message());
    current_ = std::move(t).value();
    have_current_ = true;
    return static_cast<const Textures*>(&current_);
  }
  done_ = true;
  const grpc::Status fin = s.reader->Finish();
  if (s.cancelled && fin.error_code() == grpc::CANCELLED) return static_cast<const Textures*>(nullptr);
  if (Status st = fromGrpc("Subscribe", fin); !st) return st;
  if (s.assembler.started() && !s.assembler.complete())
    return invalidInput("Subscribe: the stream ended inside the result of version {}", s.assembler.info().version);
  return static_cast<const Textures*>(nullptr);
}

Expected<std::unique_ptr<Subscription>> Client::subscribe(const SceneHandle& scene, const ResultSpec& spec,
                                                          bool deltas, std::uint64_t after_version) {
  v1::SubscribeRequest req;
  setRef(req.mutable_scene(), scene);
  *req.mutable_spec() = toProto(spec);
  req.set_deltas(deltas);
  req.set_after_version(after_version);
  std::unique_ptr<Subscription> sub(new Subscription());
  sub->stream_ = std::make_unique<Subscription::Stream>();
  impl_->prepare(sub->stream_->ctx, std::chrono::milliseconds(0));
  sub->stream_->reader = impl_->rpc->Subscribe(&sub->stream_->ctx, req);
  return sub;
}

Status Client::subscribe(const SceneHandle& scene, const TexturesCallback& callback, const ResultSpec& spec,
                         bool deltas, std::uint64_t after_version) {
  auto sub = subscribe(scene, spec, deltas, after_version);
  if (!sub) return sub.status();
  for (;;) {
    auto t = (*sub)->next();
    if (!t) return t.status();
    if (*t == nullptr) return {};
    if (!callback(**t)) {
      (*sub)->cancel();
      return {};
    }
  }
}

Expected<LightSetState> Client::getLights(const SceneHandle& scene) {
  v1::GetLightsRequest req;
  setRef(req.mutable_scene(), scene);
  grpc::ClientContext ctx;
  impl_->prepare(ctx);
  v1::GetLightsResponse resp;
  if (Status s = fromGrpc("GetLights", impl_->rpc->GetLights(&ctx, req, &resp)); !s) return s;
  LightSetState out;
  out.version = resp.version();
  out.json = resp.light_set_json();
  out.lights.assign(resp.lights().begin(), resp.lights().end());
  return out;
}

Expected<LightmapUvs> Client::getLightmapUvs(const SceneHandle& scene, bool gltf) {
  v1::GetLightmapUvsRequest req;
  setRef(req.mutable_scene(), scene);
  req.set_gltf(gltf);
  grpc::ClientContext ctx;
  impl_->prepare(ctx);
  auto reader = impl_->rpc->GetLightmapUvs(&ctx, req);
  LightmapUvs out;
  bool have_header = false;
  std::uint64_t glb_bytes = 0;
  v1::LightmapUvsMessage m;
  const auto bad = [](const std::string& why) -> Status { return internalError("GetLightmapUvs: {}", why); };
  std::optional<Status> broken;
  while (reader->Read(&m)) {
    if (broken) continue;  // drain the stream, then report
    if (m.has_header()) {
      const auto& h = m.header();
      out.width = h.width();
      out.height = h.height();
      out.texel_size_m = h.texel_size_m();
      out.generated = h.generated();
      out.meshes.resize(h.meshes());
      glb_bytes = h.glb_bytes();
      out.glb.reserve(glb_bytes);
      have_header = true;
    } else if (m.has_mesh()) {
      const auto& in = m.mesh();
      if (!have_header || in.index() >= out.meshes.size()) {
        broken = bad(fmt::format("mesh {} outside the header's {} meshes", in.index(), out.meshes.size()));
        continue;
      }
      MeshUvs& mesh = out.meshes[in.index()];
      if (in.vertex_offset() == 0 && in.index_offset() == 0) {
        mesh.name = in.name();
        mesh.node = in.node();
        mesh.mesh = in.mesh();
        mesh.primitive = in.primitive();
        mesh.lightmapped = in.lightmapped();
      }
      if (in.vertex_offset() * 2 != mesh.uv.size() || in.index_offset() != mesh.indices.size() ||
          in.uv().size() % 8 != 0 || in.indices().size() % 4 != 0) {
        broken = bad(fmt::format("mesh {}: parts out of order", in.index()));
        continue;
      }
      const std::size_t nuv = in.uv().size() / 4, nidx = in.indices().size() / 4;
      mesh.uv.resize(mesh.uv.size() + nuv);
      std::memcpy(mesh.uv.data() + mesh.uv.size() - nuv, in.uv().data(), in.uv().size());
      mesh.indices.resize(mesh.indices.size() + nidx);
      std::memcpy(mesh.indices.data() + mesh.indices.size() - nidx, in.indices().data(), in.indices().size());
      mesh.source_vertex.insert(mesh.source_vertex.end(), in.source_vertex().begin(), in.source_vertex().end());
    } else if (m.has_glb()) {
      if (m.glb().offset() != out.glb.size()) {
        broken = bad(fmt::format("glb chunk at offset {}, expected {}", m.glb().offset(), out.glb.size()));
        continue;
      }
      out.glb += m.glb().data();
    }
  }
  if (Status s = fromGrpc("GetLightmapUvs", reader->Finish()); !s) return s;
  if (broken) return *broken;
  if (!have_header) return bad("the stream had no header");
  if (out.glb.size() != glb_bytes) return bad(fmt::format("{} of {} glb bytes", out.glb.size(), glb_bytes));
  return out;
}

Expected<std::vector<v1::SceneSummary>> Client::listScenes() {
  grpc::ClientContext ctx;
  impl_->prepare(ctx);
  v1::ListScenesResponse resp;
  if (Status s = fromGrpc("ListScenes", impl_->rpc->ListScenes(&ctx, v1::ListScenesRequest{}, &resp)); !s) return s;
  return std::vector<v1::SceneSummary>(resp.scenes().begin(), resp.scenes().end());
}

Status Client::closeScene(const SceneHandle& scene) {
  v1::CloseSceneRequest req;
  setRef(req.mutable_scene(), scene);
  grpc::ClientContext ctx;
  impl_->prepare(ctx);
  v1::CloseSceneResponse resp;
  return fromGrpc("CloseScene", impl_->rpc->CloseScene(&ctx, req, &resp));
}

Expected<v1::HealthResponse> Client::health() {
  grpc::ClientContext ctx;
  impl_->prepare(ctx);
  v1::HealthResponse resp;
  if (Status s = fromGrpc("Health", impl_->rpc->Health(&ctx, v1::HealthRequest{}, &resp)); !s) return s;
  return resp;
}

Expected<v1::StatsResponse> Client::stats(const SceneHandle* scene) {
  v1::StatsRequest req;
  if (scene) setRef(req.mutable_scene(), *scene);
  grpc::ClientContext ctx;
  impl_->prepare(ctx);
  v1::StatsResponse resp;
  if (Status s = fromGrpc("Stats", impl_->rpc->Stats(&ctx, req, &resp)); !s) return s;
  return resp;
}

}  // namespace lightlink::client
