// Snapshot: one relight result as the daemon serves it, immutable once published.
//
// The relight worker of a scene builds a Snapshot from its RelightResult and publishes it
// as std::shared_ptr<const Snapshot>; every reader (Relight, GetTextures, Subscribe streams)
// holds the pointer for as long as it sends, so a result is never torn by the next relight.
// The wire form of a result depends on the client's ResultSpec (lightmap/grid, band prefix,
// component, half/float); it is encoded at most once per (snapshot, spec) and the encoded
// bytes are shared by all readers with that spec (proto/lightlink.proto "Payload layout").
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>
#include <vector>

#include <glm/glm.hpp>
#include <grpcpp/support/byte_buffer.h>

#include "proto/lightlink.pb.h"

namespace lightlink::service {

// A ResultSpec with defaults resolved (bands 0 -> the result's bands).
struct SpecKey {
  bool lightmap = true;
  bool grid = true;
  int bands = 0;
  v1::Component component = v1::COMPONENT_BOTH;
  v1::Precision precision = v1::PRECISION_HALF;

  static SpecKey from(const v1::ResultSpec& spec, int result_bands);
  auto tie() const { return std::tie(lightmap, grid, bands, component, precision); }
  bool operator<(const SpecKey& o) const { return tie() < o.tie(); }
  bool operator==(const SpecKey& o) const { return tie() == o.tie(); }
};

struct EncodedPayload {
  v1::Payload kind = v1::PAYLOAD_UNSPECIFIED;
  std::string bytes;                 // little-endian values, layout of the proto
  std::size_t bytes_per_element = 0; // per texel (lightmap payloads) or grid point
};

// A result in wire form for one spec: the payloads in the order they are sent.
struct EncodedResult {
  SpecKey spec;
  std::vector<EncodedPayload> payloads;
  std::uint64_t total_bytes = 0;
  std::size_t half_clamped = 0;  // values beyond the half range, clamped when encoding
};

// A full result serialized for the wire: the header message, then the chunk messages, as
// sendFull (result_stream.h) produces them. Shared by every reader (service/service.h).
struct WireResult {
  std::vector<grpc::ByteBuffer> messages;
  std::uint64_t bytes = 0;  // serialized size of all messages
};

struct GridGeometry {
  bool present = false;
  glm::vec3 origin{0.0f};
  float spacing_m = 0.0f;
  glm::ivec3 dims{0};
};

class Snapshot {
 public:
  std::string scene_id;            // the scene this result belongs to (its headers name it)
  std::uint64_t version = 0;       // light-set version this result is for
  std::uint64_t sequence = 0;      // 1 for the scene's first result, +1 per result
  std::uint64_t coalesced = 0;     // updates folded into this result besides its own
  bool preview = false;            // progressive: not converged yet, more iterations follow
  float residual = 0.0f;           // progressive: last iteration's change over the total flux
  int iterations = 0;              // progressive: bounce iterations since the light change
  bool instant_preview = false;    // the preview grid lit without links (ResultKind); no lightmap
  double relight_ms = 0.0;
  std::string backend;             // "cpu" or "gpu"
  int bands = 0;
  int width = 0, height = 0;
  int tile_size = 32;
  std::vector<float> lightmap_sh;  // per texel 3 * bands^2 (R, G, B blocks)
  std::vector<float> direct;       // per texel RGB
  std::vector<std::uint8_t> texel_valid;
  GridGeometry grid;
  std::vector<float> grid_sh;      // per grid point 3 * bands^2
  std::shared_ptr<const std::vector<std::uint8_t>> grid_valid;  // static, shared by all results

  std::size_t bytes() const;
  // The wire form for `spec`, encoded on first use and cached (thread-safe).
  std::shared_ptr<const EncodedResult> encoded(const SpecKey& spec) const;
  // The result for `spec` in chunks of at most `chunk_bytes`, serialized once and cached
  // (thread-safe): what Relight, GetTextures and Subscribe send to every client asking for
  // it. A Subscribe stream passes `previous`, the result it sent last (same scene, same
  // spec): the header then counts the versions skipped since, and with `delta` only the
  // tiles changed since are sent (result_stream.h). Streams that sent the same previous
  // result share one wire form. Null when protobuf could not serialize a message (nothing
  // is cached then).
  std::shared_ptr<const WireResult> wire(const SpecKey& spec, std::size_t chunk_bytes, const Snapshot* previous = nullptr,
                                         bool delta = false) const;

 private:
  mutable std::mutex cache_mutex_;
  mutable std::map<SpecKey, std::shared_ptr<const EncodedResult>> cache_;
  mutable std::mutex wire_mutex_;
  // Key: spec, chunk bytes, the previous result's sequence (0: none), delta.
  using WireKey = std::tuple<SpecKey, std::size_t, std::uint64_t, bool>;
  mutable std::map<WireKey, std::shared_ptr<const WireResult>> wire_cache_;
};

// Encodes a snapshot for a spec (what Snapshot::encoded caches).
EncodedResult encodeSnapshot(const Snapshot& s, const SpecKey& spec);

}  // namespace lightlink::service
