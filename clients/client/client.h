// lightlink::client::Client: what an engine, an editor plugin or a tool links to talk to a
// lightlink daemon (proto/lightlink.proto, docs/clients.md).
//
// One Client owns one gRPC channel; it is thread-safe (every call makes its own context), so
// an editor can poll from a render thread while a UI thread sends light changes. Every call
// returns a lightlink Status/Expected: a gRPC failure becomes a Status whose message is
// "<Rpc>: <GRPC_CODE>: <daemon's message>" (the daemon's message names the bad field), and
// whose Code says whose fault it is (INVALID_ARGUMENT, PERMISSION_DENIED, UNAUTHENTICATED ->
// kInvalidInput; NOT_FOUND -> kNotFound; UNAVAILABLE, DEADLINE_EXCEEDED -> kIoError;
// UNIMPLEMENTED -> kUnsupported; the rest kInternal).
//
// Results arrive as Textures (textures.h): payload bytes as sent (half by default) with the
// header; GetTextures answers "not modified" with std::nullopt, at the cost of one small
// message. Subscribe keeps a local copy per stream and applies tile deltas to it, so the
// callback always sees a complete image.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "core/lights/scenarios.h"
#include "clients/client/light_update.h"
#include "clients/client/textures.h"
#include "core/common/status.h"
#include "proto/lightlink.pb.h"

namespace grpc {
class Channel;
class ClientContext;
}  // namespace grpc

namespace lightlink::client {

struct ConnectOptions {
  std::string target = "127.0.0.1:50051";  // host:port (gRPC target syntax)
  std::string bearer_token;   // daemon token, sent as `authorization: Bearer <token>`; empty = none
  std::string tls_root_cert;  // PEM file of the CA that signed the daemon's certificate; empty = plaintext
  std::string tls_server_name;  // overrides the name checked in the certificate (tests, IP targets)
  // How long connect() waits for the channel to come up; 0 = do not wait (connect lazily).
  std::chrono::milliseconds connect_timeout{5000};
  // Deadline of every call except OpenScene and Subscribe (0 = none).
  std::chrono::milliseconds call_timeout{30000};
  // true: a TCP connection of this client's own. gRPC otherwise shares one connection between
  // channels to the same target in a process; a benchmark simulating many game clients (or a
  // tool that must not queue behind a big transfer of another client) wants its own.
  bool own_connection = false;
  // true: Relight and GetTextures ask for results through shared memory (a file the daemon
  // wrote once for all its clients, docs/service.md "Shared-memory delivery"). The daemon
  // honours it only for a connection from its own machine; a result whose file cannot be
  // read is asked for again on the stream, so the answer is the same either way
  // (ResultInfo::shared tells which way it came).
  bool shared_memory = false;
};

// What the daemon needs to find (or precompute) a scene. Zeros / empty strings: the
// preset's value (proto OpenSceneRequest).
struct OpenOptions {
  std::string path;          // glTF/GLB on the daemon's machine, or
  std::string gltf_bytes;    // a self-contained .glb/.gltf sent inline (<= 64 MiB)
  // Bake options as `lightlink bake` takes them, keyed by flag name without "--"
  // (docs/cli.md "Bake options"): sent as OpenSceneRequest.options.
  std::map<std::string, std::string> options;
  // Deprecated typed aliases of some of those options (0 or empty = not given).
  std::string preset;        // draft | medium | high (daemon default medium)
  std::uint32_t surfels = 0;
  int links = 0, bands = 0, rays = 0;
  float grid_spacing_m = 0.0f, texel_size_m = 0.0f;
  std::string hierarchy;     // fast | hac
  v1::Backend backend = v1::BACKEND_AUTO;
  std::string lightset_json;  // docs/lightset.md, applied over the scene's lights
  std::string name;
  std::chrono::milliseconds timeout{0};  // 0 = none: a precompute may take minutes
  // Instant preview (docs/service.md "Preview while the precompute runs"): unset = the
  // daemon's default (on); false: the first version is the linked result.
  std::optional<bool> preview;
};

// A resident scene and the right to use it. `info` is what OpenScene reported.
struct SceneHandle {
  std::string id;
  std::string token;
  v1::SceneOpened info;
  // The scene's punctual light ids as far as this handle knows: OpenScene's list, kept
  // current by updateLights through this handle. Empty `ids_known`: built from id + token
  // alone (see LightUpdate::fromLightSetJson).
  std::set<std::string> light_ids;
  bool ids_known = false;

  // A handle for a scene someone else opened (its id and token).
  static SceneHandle fromIdToken(std::string id, std::string token);
};

// What a client asks of a result (proto ResultSpec).
struct ResultSpec {
  bool lightmap = true;
  bool grid = true;
  int bands = 0;  // 0 = all
  Component component = Component::kBoth;
  Precision precision = Precision::kHalf;
};

struct UpdateResult {
  std::uint64_t version = 0;
  bool relit = false;  // with wait_ms: a result >= version existed when the call returned
};

// A scene's current light set (proto GetLightsResponse).
struct LightSetState {
  std::uint64_t version = 0;
  std::string json;              // a light-set document, schema version 1 (docs/lightset.md)
  std::vector<v1::Light> lights; // every field set
};

// The lightmap UVs of one glTF primitive instance (proto MeshLightmapUv, arrays joined).
struct MeshUvs {
  std::string name;
  int node = -1, mesh = -1, primitive = -1;
  bool lightmapped = false;
  std::vector<std::uint32_t> source_vertex;  // lightmap vertex -> glTF vertex; empty = 1:1
  std::vector<float> uv;                     // (u, v) per lightmap vertex, glTF convention
  std::vector<std::uint32_t> indices;        // 3 per triangle, over the lightmap vertices
};

// A scene's lightmap UVs (proto GetLightmapUvs).
struct LightmapUvs {
  int width = 0, height = 0;
  float texel_size_m = 0.0f;
  bool generated = false;
  std::vector<MeshUvs> meshes;  // in the scene's mesh order
  std::string glb;              // the scene as .glb with TEXCOORD_1, when asked for
};

using ProgressCallback = std::function<void(const v1::OpenSceneProgress&)>;
// Told the scene once its instant preview is published, while openScene still waits for the
// precompute: the handle (its `info` describes the preview: version, grid, no lightmap) can be
// used from another thread for getTextures, subscribe, relight and updateLights at once.
using PreviewCallback = std::function<void(const SceneHandle&)>;
// Return false to end the subscription.
using TexturesCallback = std::function<bool(const Textures&)>;

class Subscription;

class Client {
 public:
  static Expected<Client> connect(const ConnectOptions& options);

  Client(Client&&) noexcept;
  Client& operator=(Client&&) noexcept;
  ~Client();

  Expected<SceneHandle> openScene(const OpenOptions& options, const ProgressCallback& progress = {},
                                  const PreviewCallback& on_preview = {});
  // Applies `update` (all or nothing). wait_ms > 0: returns once the new version is relit or
  // after wait_ms (then relit = false). Keeps `scene.light_ids` current.
  Expected<UpdateResult> updateLights(SceneHandle& scene, const LightUpdate& update, std::uint32_t wait_ms = 0);
  // A light-set JSON file/text (docs/lightset.md) converted with the handle's light ids.
  Expected<UpdateResult> updateLightsFromJson(SceneHandle& scene, const std::string& json_text,
                                              std::uint32_t wait_ms = 0);
  // Lighting scenarios (docs/service.md "Lighting scenarios"). setScenario stores a named
  // light set: `light_set_json` applied over the scene's own lights, or, when it is empty,
  // the scene's current light set; returns the scene's scenario names afterwards.
  Expected<std::vector<std::string>> setScenario(const SceneHandle& scene, const std::string& name,
                                                 const std::string& light_set_json);
  Expected<std::vector<std::string>> removeScenario(const SceneHandle& scene, const std::string& name);
  // The scene's light set becomes the weighted blend of scenarios (a new version, as
  // updateLights). The handle's light ids are unknown afterwards (a blend renames them).
  Expected<UpdateResult> useScenarios(SceneHandle& scene, const std::vector<lights::ScenarioWeight>& weights,
                                      std::uint32_t wait_ms = 0);
  // The newest result with version >= `version` (0 = newest), waiting for it up to the
  // call deadline.
  Expected<Textures> relight(const SceneHandle& scene, std::uint64_t version = 0, const ResultSpec& spec = {});
  // Poll: std::nullopt when the newest result is `last_seen_version` ("not modified").
  // Long poll with wait_ms > 0 (<= 60000): when nothing is newer, the daemon answers the
  // moment a newer result exists, or std::nullopt after wait_ms; the call's deadline is
  // the client's call_timeout plus wait_ms. A loop of long polls sees each new version one
  // round trip after it is published, without a poll interval.
  Expected<std::optional<Textures>> getTextures(const SceneHandle& scene, std::uint64_t last_seen_version,
                                                const ResultSpec& spec = {}, std::uint32_t wait_ms = 0);
  // A server stream of results (blocking reader); see Subscription.
  Expected<std::unique_ptr<Subscription>> subscribe(const SceneHandle& scene, const ResultSpec& spec = {},
                                                    bool deltas = true, std::uint64_t after_version = 0);
  // Same, calling `callback` for each complete result until it returns false or the stream
  // ends (scene closed, daemon draining). Returns the stream's final status.
  Status subscribe(const SceneHandle& scene, const TexturesCallback& callback, const ResultSpec& spec = {},
                   bool deltas = true, std::uint64_t after_version = 0);
  // The scene's current light set: version, light-set JSON and proto lights.
  Expected<LightSetState> getLights(const SceneHandle& scene);
  // The lightmap UVs the scene is lit with; `gltf` true: also the scene as .glb with them.
  Expected<LightmapUvs> getLightmapUvs(const SceneHandle& scene, bool gltf = false);
  Expected<std::vector<v1::SceneSummary>> listScenes();
  Status closeScene(const SceneHandle& scene);
  Expected<v1::HealthResponse> health();
  // Daemon-wide figures, plus the scene's when `scene` is given.
  Expected<v1::StatsResponse> stats(const SceneHandle* scene = nullptr);

  const ConnectOptions& options() const { return options_; }

 private:
  struct Impl;
  Client(ConnectOptions options, std::unique_ptr<Impl> impl);
  ConnectOptions options_;
  std::unique_ptr<Impl> impl_;
};

// A Subscribe stream. next() blocks until the next complete result, applies it to the
// stream's local copy (deltas: changed tiles copied in place) and returns that copy, valid
// until the next call; nullptr when the stream ended cleanly (scene closed, daemon draining,
// cancel()). cancel() may be called from another thread.
class Subscription {
 public:
  ~Subscription();
  Expected<const Textures*> next();
  void cancel();
  const Textures& current() const { return current_; }

 private:
  friend class Client;
  struct Stream;
  Subscription() = default;
  std::unique_ptr<Stream> stream_;
  Textures current_;
  bool have_current_ = false;
  bool done_ = false;
};

// gRPC status code name ("INVALID_ARGUMENT") and the lightlink Code it maps to.
const char* grpcCodeName(int code);
Code codeForGrpc(int code);

}  // namespace lightlink::client
