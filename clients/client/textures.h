// Textures: one relight result as a client holds it (proto/lightlink.proto "Payload layout"),
// and ResultAssembler, which builds it from the header + chunk messages of Relight,
// GetTextures and Subscribe.
//
// Payloads are kept as the bytes the daemon sent (half or float, little-endian), because that
// is what an engine uploads to a texture; `floats()` decodes one payload to float32 when a
// CPU consumer wants numbers. A full result's chunks must cover each payload in order, and
// each payload must have exactly the size its header implies (texels x values x bytes), so
// a torn or truncated result is an error, never a texture with a zero-filled tail. A delta
// result (Subscribe with deltas) carries only changed lightmap tiles: it is applied to the
// previous Textures of the same stream, tile rows copied into place, and yields a complete
// Textures again; the grid, when it changed, comes whole.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/common/status.h"

namespace lightlink::v1 {
class ResultMessage;
class ResultHeader;
}  // namespace lightlink::v1

namespace lightlink::client {

// Mirrors lightlink.v1.Payload (the numeric values are the wire values).
enum class Payload : int {
  kLightmapSh = 1,
  kLightmapDirect = 2,
  kLightmapValid = 3,
  kGridSh = 4,
  kGridValid = 5,
};
inline constexpr int kPayloadSlots = 6;  // indexed by the enum value; slot 0 unused
const char* payloadName(Payload p);

enum class Precision { kHalf, kFloat };
// Mirrors lightlink.v1.ResultKind: what computed a result.
enum class ResultKind {
  kLinked,          // the precomputed links: lightmap and grid, all bounces
  kInstantPreview,  // the grid lit without links while the links are computed; no lightmap
};
enum class Component { kBoth, kIndirect, kDirect };

struct Vec3 {
  float x = 0.0f, y = 0.0f, z = 0.0f;
};

// The header of a result (lightlink.v1.ResultHeader) as plain data.
struct ResultInfo {
  std::string scene_id;
  std::uint64_t version = 0;
  bool not_modified = false;
  bool delta = false;
  std::string backend;
  int bands = 0;
  Precision precision = Precision::kHalf;
  Component component = Component::kBoth;
  int width = 0, height = 0, tile_size = 0;  // lightmap texels; 0 x 0 when none was sent
  bool has_grid = false;
  Vec3 grid_origin, grid_spacing;            // metres
  int nx = 0, ny = 0, nz = 0;                // grid points per axis
  std::vector<std::uint32_t> changed_tiles;  // delta only
  std::uint64_t payload_bytes = 0;
  double relight_ms = 0.0;
  std::uint64_t skipped_versions = 0;
  std::uint64_t coalesced_updates = 0;
  bool preview = false;  // progressive daemon: not converged yet, more iterations follow
  float residual = 0.0f; // progressive daemon: last iteration's change over the total flux
  std::uint32_t iterations = 0;  // progressive daemon: bounce iterations since the light change
  // kInstantPreview: the grid a daemon publishes while the scene's links are computed (then
  // `preview` is true too); a linked result replaces it under a later version.
  ResultKind kind = ResultKind::kLinked;
  bool shared = false;   // the chunks came through a shared-memory file (ConnectOptions::shared_memory)

  int coeffCount() const { return bands * bands; }
  std::size_t texels() const { return std::size_t(width) * std::size_t(height); }
  std::size_t gridPoints() const { return std::size_t(nx) * std::size_t(ny) * std::size_t(nz); }
  std::size_t valueBytes() const { return precision == Precision::kHalf ? 2 : 4; }
  // Bytes per texel / grid point of a payload: 3 * bands^2 values for SH, 3 for direct,
  // 1 byte for validity.
  std::size_t elementBytes(Payload p) const;
  // Elements (texels or grid points) of a payload.
  std::size_t elements(Payload p) const;
  int tilesX() const;
  int tilesY() const;

  static ResultInfo fromProto(const v1::ResultHeader& header);
};

struct Textures {
  ResultInfo info;
  std::array<std::vector<std::uint8_t>, kPayloadSlots> payloads;

  bool has(Payload p) const { return !payloads[int(p)].empty(); }
  std::span<const std::uint8_t> bytes(Payload p) const { return payloads[int(p)]; }
  // A value payload (SH or direct) as float32; a validity payload as 0/1 floats.
  std::vector<float> floats(Payload p) const;
  std::size_t totalBytes() const;
};

// Little-endian half / float values -> float32. `bytes.size()` must be a multiple of the
// value size; returns the number of values written to `out` (resized).
void decodeHalf(std::span<const std::uint8_t> bytes, std::vector<float>& out);
void decodeFloat(std::span<const std::uint8_t> bytes, std::vector<float>& out);

// Feeds the messages of one result (header first) and produces the Textures. Reusable:
// after `take()` the next header starts a new result (Subscribe streams many).
class ResultAssembler {
 public:
  // Returns an error naming what is inconsistent: a chunk before the header, a payload the
  // header does not allow, a chunk out of order or beyond the payload, a tile index outside
  // the lightmap, more bytes than `payload_bytes`.
  Status add(const v1::ResultMessage& message);
  bool started() const { return started_; }
  // True once the header arrived and every byte it announced has been received.
  bool complete() const { return started_ && received_ == info_.payload_bytes; }
  const ResultInfo& info() const { return info_; }
  // The finished result. Full: checks each payload is whole. Delta: applies the tiles to
  // `base` (the previous result of the same stream), which must match in size, bands and
  // precision; its payloads are moved into the result (no copy of the unchanged texels), so
  // `base` is left empty on success. Not modified: returns a Textures with only `info`.
  Expected<Textures> take(Textures* base = nullptr);
  void reset();

 private:
  Status addHeader(const v1::ResultHeader& header);
  Status addChunk(int payload, std::uint64_t offset, std::uint32_t tile, std::span<const std::uint8_t> data);
  struct TileBuffer {
    std::vector<std::uint8_t> bytes;
  };
  bool started_ = false;
  ResultInfo info_;
  std::uint64_t received_ = 0;
  std::array<std::vector<std::uint8_t>, kPayloadSlots> full_;
  // Delta lightmap tiles: (payload, tile) -> tile-local bytes.
  std::map<std::pair<int, std::uint32_t>, TileBuffer> tiles_;
};

// Tile geometry: the texel rectangle of tile `tile` (ty * tiles_x + tx), clipped at the
// lightmap edge.
struct TileRect {
  int x0 = 0, y0 = 0, w = 0, h = 0;
};
TileRect tileRect(const ResultInfo& info, std::uint32_t tile);

// Copies tile-local rows (`tile_bytes`, row-major, `element_bytes` per texel) into the
// full-image payload `image` (info.width x info.height).
Status applyTile(const ResultInfo& info, std::uint32_t tile, std::size_t element_bytes,
                 std::span<const std::uint8_t> tile_bytes, std::vector<std::uint8_t>& image);

}  // namespace lightlink::client
