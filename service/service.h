// LightlinkService: the gRPC handlers of lightlink.v1 (proto/lightlink.proto).
//
// GetLights and GetLightmapUvs read a scene back (its current light set, the lightmap UVs it
// is lit with) for editors that show or map what the daemon holds. A reaper thread closes the
// scenes no client named for --session-idle-timeout.
//
// Handlers are thin: admit the call (bearer token, draining, per-client stream limit),
// look up the scene and check its token, translate the request, call the registry or the
// scene session, translate the answer. All calls share `admit` and `lookup`, and the three
// result calls `beginResultCall`, instead of repeating the checks. Blocking waits (a result for a version, the next result of a
// subscription) poll the call's cancellation and the drain flag every ~50 ms, so no call
// outlives a cancelled client or a shutdown.
//
// Relight, GetTextures and Subscribe are gRPC callback methods with raw (ByteBuffer)
// messages, through the generated WithRawCallbackMethod_* mixins: each result is serialized
// once per (result, spec) into grpc::ByteBuffers (Snapshot::wire) and every caller is sent
// references to the same slices, never a re-encoding. Their bodies run on a thread of the
// call's own (ResultCall in service.cpp), since the scene's waits block and gRPC's callback
// threads must not.
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

#include <grpcpp/grpcpp.h>

#include "proto/lightlink.grpc.pb.h"
#include "service/auth_limiter.h"
#include "service/config.h"
#include "service/scene_registry.h"
#include "service/shared_results.h"

namespace lightlink::service {

// The generated service with the three result methods switched to raw callback handlers.
using LightlinkServiceBase = v1::Lightlink::WithRawCallbackMethod_Relight<
    v1::Lightlink::WithRawCallbackMethod_GetTextures<v1::Lightlink::WithRawCallbackMethod_Subscribe<v1::Lightlink::Service>>>;

class LightlinkService final : public LightlinkServiceBase {
 public:
  LightlinkService(const DaemonConfig& config, SceneRegistry& registry);
  ~LightlinkService() override;

  grpc::Status OpenScene(grpc::ServerContext* ctx, const v1::OpenSceneRequest* request,
                         grpc::ServerWriter<v1::OpenSceneProgress>* writer) override;
  grpc::Status UpdateLights(grpc::ServerContext* ctx, const v1::UpdateLightsRequest* request,
                            v1::UpdateLightsResponse* response) override;
  grpc::Status SetScenario(grpc::ServerContext* ctx, const v1::SetScenarioRequest* request,
                           v1::SetScenarioResponse* response) override;
  grpc::Status UseScenarios(grpc::ServerContext* ctx, const v1::UseScenariosRequest* request,
                            v1::UpdateLightsResponse* response) override;
  class ResultCall;  // the reactor of one result call (service.cpp)
  // Relight, GetTextures and Subscribe: the request arrives serialized, each response is a
  // serialized ResultMessage shared with every other caller of the same result (see above).
  grpc::ServerWriteReactor<grpc::ByteBuffer>* Relight(grpc::CallbackServerContext* ctx,
                                                      const grpc::ByteBuffer* request) override;
  grpc::ServerWriteReactor<grpc::ByteBuffer>* GetTextures(grpc::CallbackServerContext* ctx,
                                                          const grpc::ByteBuffer* request) override;
  grpc::ServerWriteReactor<grpc::ByteBuffer>* Subscribe(grpc::CallbackServerContext* ctx,
                                                        const grpc::ByteBuffer* request) override;
  grpc::Status GetLights(grpc::ServerContext* ctx, const v1::GetLightsRequest* request,
                         v1::GetLightsResponse* response) override;
  grpc::Status GetLightmapUvs(grpc::ServerContext* ctx, const v1::GetLightmapUvsRequest* request,
                              grpc::ServerWriter<v1::LightmapUvsMessage>* writer) override;
  grpc::Status ListScenes(grpc::ServerContext* ctx, const v1::ListScenesRequest* request,
                          v1::ListScenesResponse* response) override;
  grpc::Status CloseScene(grpc::ServerContext* ctx, const v1::CloseSceneRequest* request,
                          v1::CloseSceneResponse* response) override;
  grpc::Status Health(grpc::ServerContext* ctx, const v1::HealthRequest* request,
                      v1::HealthResponse* response) override;
  grpc::Status Stats(grpc::ServerContext* ctx, const v1::StatsRequest* request, v1::StatsResponse* response) override;

  // Closes the scenes no client named for --session-idle-timeout (as CloseScene does, the
  // close persisted); the reaper thread calls it every few seconds. Returns their ids.
  std::vector<std::string> closeIdleScenes();

  // SIGTERM: Health says DRAINING, new work is refused, open streams end at their next
  // message boundary.
  void beginDrain();
  bool draining() const { return draining_.load(); }
  int activeStreams() const { return active_streams_.load(); }
  const SharedResults& sharedResults() const { return shared_; }

 private:
  // Runs a light-set change (UpdateLights, UseScenarios) and answers it: the version, and
  // with `wait_ms` whether its result exists.
  grpc::Status answerUpdate(grpc::ServerContext* ctx, SceneSession& session, const char* rpc,
                            const std::function<Expected<std::uint64_t>()>& change, std::uint32_t wait_ms,
                            v1::UpdateLightsResponse* response);
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

  // Helpers take ServerContextBase: the synchronous and the callback methods share them.
  grpc::Status admit(grpc::ServerContextBase* ctx, bool new_work) const;
  // Finds the scene and checks its token; waits (within the call's deadline) for a scene
  // still being restored after a restart, UNAVAILABLE when it is not back in time.
  grpc::Status lookup(grpc::ServerContextBase* ctx, const v1::SceneRef& ref, std::shared_ptr<SceneSession>* out) const;
  // The preamble of the calls that send results (Relight, GetTextures, Subscribe): admit
  // as new work, look the scene up and check its token, validate the spec, take a stream
  // slot of the client (released when `slot` is destroyed).
  grpc::Status beginResultCall(grpc::ServerContextBase* ctx, const v1::SceneRef& ref, const v1::ResultSpec& spec,
                               std::shared_ptr<SceneSession>* scene, std::optional<StreamSlot>* slot);
  std::chrono::steady_clock::time_point waitDeadline(grpc::ServerContextBase* ctx) const;
  // The bodies of the three result calls, run by their ResultCall.
  grpc::Status relight(grpc::ServerContextBase* ctx, const v1::RelightRequest& request, ResultCall& call);
  grpc::Status getTextures(grpc::ServerContextBase* ctx, const v1::GetTexturesRequest& request, ResultCall& call);
  grpc::Status subscribe(grpc::ServerContextBase* ctx, const v1::SubscribeRequest& request, ResultCall& call);
  // Sends a full result: as one header naming a shared file when the client asked for shared
  // memory, is on this machine and delivery is on (service/shared_results.h), else as the
  // header and chunk messages of its wire form.
  grpc::Status sendResult(grpc::ServerContextBase* ctx, const Snapshot& snap, const SpecKey& spec, bool shared_memory,
                          ResultCall& call);
  // Parses the request of a result call and starts its reactor running `body`.
  template <typename Request>
  grpc::ServerWriteReactor<grpc::ByteBuffer>* startResultCall(
      const char* rpc, grpc::CallbackServerContext* ctx, const grpc::ByteBuffer* request,
      grpc::Status (LightlinkService::*body)(grpc::ServerContextBase*, const Request&, ResultCall&));

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
  // Ids closed for idleness, so a late call hears why its scene is gone (bounded).
  mutable std::mutex idle_mutex_;
  std::map<std::string, std::chrono::system_clock::time_point> idle_closed_;
  std::mutex reaper_mutex_;
  std::condition_variable reaper_cv_;
  bool reaper_stop_ = false;
  std::thread reaper_;
};

// Resident set size of this process in bytes (/proc/self/statm), 0 when unavailable.
std::uint64_t residentSetBytes();

}  // namespace lightlink::service
