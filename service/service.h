// LightlinkService: the gRPC handlers of lightlink.v1 (proto/lightlink.proto).
//
// Handlers are thin: admit the call (bearer token, draining, per-client stream limit),
// look up the scene and check its token, translate the request, call the registry or the
// scene session, translate the answer. All calls share `admit` and `lookup`, and the three
// result calls `beginResultCall`, instead of repeating the checks. Blocking waits (a result for a version, the next result of a
// subscription) poll the call's cancellation and the drain flag every ~50 ms, so no call
// outlives a cancelled client or a shutdown.
#pragma once

#include <atomic>
#include <chrono>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <grpcpp/grpcpp.h>

#include "proto/lightlink.grpc.pb.h"
#include "service/auth_limiter.h"
#include "service/config.h"
#include "service/scene_registry.h"
#include "service/shared_results.h"
#include "service/wire_message.h"

namespace lightlink::service {

class LightlinkService final : public v1::Lightlink::Service {
 public:
  LightlinkService(const DaemonConfig& config, SceneRegistry& registry);

  grpc::Status OpenScene(grpc::ServerContext* ctx, const v1::OpenSceneRequest* request,
                         grpc::ServerWriter<v1::OpenSceneProgress>* writer) override;
  grpc::Status UpdateLights(grpc::ServerContext* ctx, const v1::UpdateLightsRequest* request,
                            v1::UpdateLightsResponse* response) override;
  // Relight, GetTextures and Subscribe send results serialized once per result and spec
  // (and, for Subscribe, per previous result) and shared by all their callers
  // (service/wire_message.h). The constructor registers them in place of the generated
  // handlers, as split-streaming methods whose responses are WireMessages (the same bytes
  // as a serialized ResultMessage).
  using RelightStreamer = grpc::ServerSplitStreamer<v1::RelightRequest, WireMessage>;
  using GetTexturesStreamer = grpc::ServerSplitStreamer<v1::GetTexturesRequest, WireMessage>;
  using SubscribeStreamer = grpc::ServerSplitStreamer<v1::SubscribeRequest, WireMessage>;
  grpc::Status RelightWire(grpc::ServerContext* ctx, RelightStreamer* stream);
  grpc::Status GetTexturesWire(grpc::ServerContext* ctx, GetTexturesStreamer* stream);
  grpc::Status SubscribeWire(grpc::ServerContext* ctx, SubscribeStreamer* stream);
  grpc::Status ListScenes(grpc::ServerContext* ctx, const v1::ListScenesRequest* request,
                          v1::ListScenesResponse* response) override;
  grpc::Status CloseScene(grpc::ServerContext* ctx, const v1::CloseSceneRequest* request,
                          v1::CloseSceneResponse* response) override;
  grpc::Status Health(grpc::ServerContext* ctx, const v1::HealthRequest* request,
                      v1::HealthResponse* response) override;
  grpc::Status Stats(grpc::ServerContext* ctx, const v1::StatsRequest* request, v1::StatsResponse* response) override;

  // SIGTERM: Health says DRAINING, new work is refused, open streams end at their next
  // message boundary.
  void beginDrain();
  bool draining() const { return draining_.load(); }
  int activeStreams() const { return active_streams_.load(); }
  const SharedResults& sharedResults() const { return shared_; }

 private:
  // Per-client stream accounting (RAII: released when the handler returns).
  class StreamSlot {
   public:
    StreamSlot(LightlinkService& service, std::string client);
    ~StreamSlot();
    StreamSlot(const StreamSlot&) = delete;
    StreamSlot& operator=(const StreamSlot&) = delete;
    bool acquired() const { return acquired_; }

   private:
    LightlinkService& service_;
    std::string client_;
    bool acquired_ = false;
  };

  grpc::Status admit(grpc::ServerContext* ctx, bool new_work) const;
  // Finds the scene and checks its token; waits (within the call's deadline) for a scene
  // still being restored after a restart, UNAVAILABLE when it is not back in time.
  grpc::Status lookup(grpc::ServerContext* ctx, const v1::SceneRef& ref, std::shared_ptr<SceneSession>* out) const;
  // The preamble of the calls that send results (Relight, GetTextures, Subscribe): admit
  // as new work, look the scene up and check its token, validate the spec, take a stream
  // slot of the client (released when `slot` is destroyed).
  grpc::Status beginResultCall(grpc::ServerContext* ctx, const v1::SceneRef& ref, const v1::ResultSpec& spec,
                               std::shared_ptr<SceneSession>* scene, std::optional<StreamSlot>* slot);
  // The same for the split-streaming handlers, which first read their one request message.
  template <typename Request>
  grpc::Status beginWireCall(grpc::ServerContext* ctx, grpc::ServerSplitStreamer<Request, WireMessage>* stream,
                             const char* rpc, Request* request, std::shared_ptr<SceneSession>* scene,
                             std::optional<StreamSlot>* slot);
  std::chrono::steady_clock::time_point waitDeadline(grpc::ServerContext* ctx) const;
  // Sends a full result: as one header naming a shared file when the client asked for shared
  // memory, is on this machine and delivery is on (service/shared_results.h), else as the
  // header and chunk messages of its wire form.
  template <typename Stream>
  grpc::Status sendResult(grpc::ServerContext* ctx, const Snapshot& snap, const SpecKey& spec, bool shared_memory,
                          Stream* stream);
  // Registers `handler` for the method `name` of lightlink.v1.Lightlink in place of the
  // generated one.
  template <typename Request>
  void replaceWithWireHandler(const char* name,
                              grpc::Status (LightlinkService::*handler)(grpc::ServerContext*,
                                                                        grpc::ServerSplitStreamer<Request, WireMessage>*));

  DaemonConfig config_;
  SceneRegistry& registry_;
  SharedResults shared_;
  std::atomic<bool> draining_{false};
  std::atomic<int> active_streams_{0};
  std::atomic<int> opening_{0};
  mutable AuthFailureLimiter auth_failures_;
  std::mutex streams_mutex_;
  std::map<std::string, int> streams_per_client_;
  const std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
};

// Resident set size of this process in bytes (/proc/self/statm), 0 when unavailable.
std::uint64_t residentSetBytes();

}  // namespace lightlink::service
