// Result assembly: chunks -> payloads, delta tiles -> the previous image, half -> float.
#include "clients/client/textures.h"

#include <algorithm>
#include <cstring>

#include "core/common/half.h"
#include "proto/lightlink.pb.h"

namespace lightlink::client {

const char* payloadName(Payload p) {
  switch (p) {
    case Payload::kLightmapSh: return "LIGHTMAP_SH";
    case Payload::kLightmapDirect: return "LIGHTMAP_DIRECT";
    case Payload::kLightmapValid: return "LIGHTMAP_VALID";
    case Payload::kGridSh: return "GRID_SH";
    case Payload::kGridValid: return "GRID_VALID";
  }
  return "UNSPECIFIED";
}

namespace {

bool isLightmap(Payload p) {
  return p == Payload::kLightmapSh || p == Payload::kLightmapDirect || p == Payload::kLightmapValid;
}

bool validPayload(int v) { return v >= 1 && v < kPayloadSlots; }

}  // namespace

std::size_t ResultInfo::elementBytes(Payload p) const {
  switch (p) {
    case Payload::kLightmapSh:
    case Payload::kGridSh: return 3 * std::size_t(coeffCount()) * valueBytes();
    case Payload::kLightmapDirect: return 3 * valueBytes();
    case Payload::kLightmapValid:
    case Payload::kGridValid: return 1;
  }
  return 0;
}

std::size_t ResultInfo::elements(Payload p) const { return isLightmap(p) ? texels() : gridPoints(); }

int ResultInfo::tilesX() const { return tile_size > 0 ? (width + tile_size - 1) / tile_size : 0; }
int ResultInfo::tilesY() const { return tile_size > 0 ? (height + tile_size - 1) / tile_size : 0; }

ResultInfo ResultInfo::fromProto(const v1::ResultHeader& h) {
  ResultInfo r;
  r.scene_id = h.scene().scene_id();
  r.version = h.version();
  r.not_modified = h.not_modified();
  r.delta = h.delta();
  r.backend = h.backend();
  r.bands = h.bands();
  r.precision = h.precision() == v1::PRECISION_FLOAT ? Precision::kFloat : Precision::kHalf;
  r.component = h.component() == v1::COMPONENT_INDIRECT ? Component::kIndirect
                : h.component() == v1::COMPONENT_DIRECT ? Component::kDirect
                                                        : Component::kBoth;
  r.width = h.lightmap().width();
  r.height = h.lightmap().height();
  r.tile_size = h.lightmap().tile_size();
  r.has_grid = h.grid().present();
  r.grid_origin = {h.grid().origin().x(), h.grid().origin().y(), h.grid().origin().z()};
  r.grid_spacing = {h.grid().spacing().x(), h.grid().spacing().y(), h.grid().spacing().z()};
  r.nx = h.grid().nx();
  r.ny = h.grid().ny();
  r.nz = h.grid().nz();
  r.changed_tiles.assign(h.changed_tiles().begin(), h.changed_tiles().end());
  r.payload_bytes = h.payload_bytes();
  r.relight_ms = h.relight_ms();
  r.skipped_versions = h.skipped_versions();
  r.coalesced_updates = h.coalesced_updates();
  r.shared = h.has_shared();
  r.preview = h.preview();
  r.residual = h.residual();
  r.iterations = h.iterations();
  r.kind = h.kind() == v1::RESULT_KIND_INSTANT_PREVIEW ? ResultKind::kInstantPreview : ResultKind::kLinked;
  return r;
}

std::vector<float> Textures::floats(Payload p) const {
  std::vector<float> out;
  const auto& b = payloads[int(p)];
  if (p == Payload::kLightmapValid || p == Payload::kGridValid) {
    out.resize(b.size());
    for (std::size_t i = 0; i < b.size(); ++i) out[i] = b[i] ? 1.0f : 0.0f;
  } else if (info.precision == Precision::kHalf) {
    decodeHalf(b, out);
  } else {
    decodeFloat(b, out);
  }
  return out;
}

std::size_t Textures::totalBytes() const {
  std::size_t n = 0;
  for (const auto& p : payloads) n += p.size();
  return n;
}

void decodeHalf(std::span<const std::uint8_t> bytes, std::vector<float>& out) {
  const std::size_t n = bytes.size() / 2;
  out.resize(n);
  // Byte-wise little-endian read: correct on any host, and the compiler turns it into one
  // 16-bit load on x86. Imath's table gives the exact float of every half (subnormals,
  // infinities and NaN included).
  for (std::size_t i = 0; i < n; ++i) {
    const half_bits h = half_bits(bytes[2 * i] | (half_bits(bytes[2 * i + 1]) << 8));
    out[i] = fromHalf(h);
  }
}

void decodeFloat(std::span<const std::uint8_t> bytes, std::vector<float>& out) {
  const std::size_t n = bytes.size() / 4;
  out.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t u = std::uint32_t(bytes[4 * i]) | (std::uint32_t(bytes[4 * i + 1]) << 8) |
                            (std::uint32_t(bytes[4 * i + 2]) << 16) | (std::uint32_t(bytes[4 * i + 3]) << 24);
    std::memcpy(&out[i], &u, 4);
  }
}

TileRect tileRect(const ResultInfo& info, std::uint32_t tile) {
  TileRect r;
  const int tx_count = info.tilesX();
  if (tx_count == 0) return r;
  const int tx = int(tile % std::uint32_t(tx_count)), ty = int(tile / std::uint32_t(tx_count));
  r.x0 = tx * info.tile_size;
  r.y0 = ty * info.tile_size;
  r.w = std::max(0, std::min(info.tile_size, info.width - r.x0));
  r.h = std::max(0, std::min(info.tile_size, info.height - r.y0));
  return r;
}

Status applyTile(const ResultInfo& info, std::uint32_t tile, std::size_t element_bytes,
                 std::span<const std::uint8_t> tile_bytes, std::vector<std::uint8_t>& image) {
  if (info.tile_size <= 0) return invalidInput("delta result: lightmap tile_size {} is not positive", info.tile_size);
  if (tile >= std::uint32_t(info.tilesX() * info.tilesY()))
    return invalidInput("delta result: tile {} is outside the {}x{} tile grid", tile, info.tilesX(), info.tilesY());
  const TileRect r = tileRect(info, tile);
  const std::size_t row_bytes = std::size_t(r.w) * element_bytes;
  if (tile_bytes.size() != row_bytes * std::size_t(r.h))
    return invalidInput("delta result: tile {} has {} bytes, expected {} ({}x{} texels x {} bytes)", tile,
                        tile_bytes.size(), row_bytes * r.h, r.w, r.h, element_bytes);
  if (image.size() != info.texels() * element_bytes)
    return invalidInput("delta result: previous image has {} bytes, expected {}", image.size(),
                        info.texels() * element_bytes);
  for (int y = 0; y < r.h; ++y) {
    const std::size_t dst = (std::size_t(r.y0 + y) * std::size_t(info.width) + std::size_t(r.x0)) * element_bytes;
    std::memcpy(image.data() + dst, tile_bytes.data() + std::size_t(y) * row_bytes, row_bytes);
  }
  return {};
}

void ResultAssembler::reset() {
  started_ = false;
  info_ = {};
  received_ = 0;
  for (auto& p : full_) p.clear();
  tiles_.clear();
}

Status ResultAssembler::add(const v1::ResultMessage& message) {
  if (message.has_header()) return addHeader(message.header());
  if (!message.has_chunk()) return invalidInput("result stream: empty message");
  const v1::Chunk& c = message.chunk();
  const std::span<const std::uint8_t> data(reinterpret_cast<const std::uint8_t*>(c.data().data()), c.data().size());
  return addChunk(c.payload(), c.offset(), c.tile(), data);
}

Status ResultAssembler::addHeader(const v1::ResultHeader& header) {
  if (started_ && !complete())
    return invalidInput("result stream: header of version {} arrived before version {} was complete "
                        "({} of {} bytes)",
                        header.version(), info_.version, received_, info_.payload_bytes);
  reset();
  started_ = true;
  info_ = ResultInfo::fromProto(header);
  if (info_.bands < 0 || info_.bands > 4) return invalidInput("result header: bands {} is out of range", info_.bands);
  if (info_.width < 0 || info_.height < 0) return invalidInput("result header: negative lightmap size");
  if (info_.nx < 0 || info_.ny < 0 || info_.nz < 0) return invalidInput("result header: negative grid size");
  if (info_.delta && info_.tile_size <= 0)
    return invalidInput("result header: delta result with tile_size {}", info_.tile_size);
  return {};
}

Status ResultAssembler::addChunk(int payload, std::uint64_t offset, std::uint32_t tile,
                                 std::span<const std::uint8_t> data) {
  if (!started_) return invalidInput("result stream: chunk before the header");
  if (!validPayload(payload)) return invalidInput("chunk.payload: {} is not a known payload", payload);
  const Payload p = Payload(payload);
  if (isLightmap(p) && info_.texels() == 0)
    return invalidInput("chunk.payload: {} sent but the header has no lightmap", payloadName(p));
  if (!isLightmap(p) && (!info_.has_grid || info_.gridPoints() == 0))
    return invalidInput("chunk.payload: {} sent but the header has no grid", payloadName(p));
  const std::size_t size = data.size();
  received_ += size;
  if (received_ > info_.payload_bytes)
    return invalidInput("result stream: {} bytes received, header announced {}", received_, info_.payload_bytes);

  std::vector<std::uint8_t>* buf = nullptr;
  if (info_.delta && isLightmap(p)) {
    buf = &tiles_[{int(p), tile}].bytes;
    if (offset != buf->size())
      return invalidInput("chunk.offset: {} for {} tile {}, expected {}", offset, payloadName(p), tile, buf->size());
    if (std::find(info_.changed_tiles.begin(), info_.changed_tiles.end(), tile) == info_.changed_tiles.end())
      return invalidInput("chunk.tile: {} is not in the header's changed_tiles", tile);
  } else {
    buf = &full_[int(p)];
    const std::size_t expected = info_.elements(p) * info_.elementBytes(p);
    if (offset != buf->size())
      return invalidInput("chunk.offset: {} for {}, expected {} (chunks must arrive in order)", offset,
                          payloadName(p), buf->size());
    if (buf->size() + size > expected)
      return invalidInput("chunk: {} would grow to {} bytes, its size is {}", payloadName(p), buf->size() + size,
                          expected);
    if (buf->capacity() < expected) buf->reserve(expected);
  }
  // Byte ranges of the same type: one memmove, no zero fill first.
  buf->insert(buf->end(), data.begin(), data.end());
  return {};
}

Expected<Textures> ResultAssembler::take(Textures* base) {
  if (!started_) return invalidInput("result stream: ended without a header");
  if (!complete())
    return invalidInput("result stream: version {} ended after {} of {} bytes", info_.version, received_,
                        info_.payload_bytes);
  Textures t;
  t.info = info_;
  if (info_.not_modified) {
    reset();
    return t;
  }
  if (!info_.delta) {
    for (int i = 1; i < kPayloadSlots; ++i) {
      if (full_[i].empty()) continue;
      const std::size_t expected = info_.elements(Payload(i)) * info_.elementBytes(Payload(i));
      if (full_[i].size() != expected)
        return invalidInput("result: {} has {} bytes, expected {}", payloadName(Payload(i)), full_[i].size(), expected);
      t.payloads[i] = std::move(full_[i]);
    }
    reset();
    return t;
  }
  // Delta: start from the previous image, replace changed tiles and (if sent) the grid.
  if (!base) return invalidInput("delta result for version {} without a previous full result", info_.version);
  const ResultInfo& b = base->info;
  if (b.width != info_.width || b.height != info_.height || b.bands != info_.bands ||
      b.precision != info_.precision || b.tile_size != info_.tile_size)
    return invalidInput("delta result for version {}: {}x{} texels, {} bands does not match the previous result "
                        "({}x{}, {} bands)",
                        info_.version, info_.width, info_.height, info_.bands, b.width, b.height, b.bands);
  t.payloads = std::move(base->payloads);
  base->payloads = {};
  for (int i = 1; i < kPayloadSlots; ++i) {
    const Payload p = Payload(i);
    if (!isLightmap(p)) {
      if (full_[i].empty()) continue;
      const std::size_t expected = info_.elements(p) * info_.elementBytes(p);
      if (full_[i].size() != expected)
        return invalidInput("result: {} has {} bytes, expected {}", payloadName(p), full_[i].size(), expected);
      t.payloads[i] = std::move(full_[i]);
      continue;
    }
    if (t.payloads[i].empty()) continue;
    for (std::uint32_t tile : info_.changed_tiles) {
      auto it = tiles_.find({i, tile});
      if (it == tiles_.end())
        return invalidInput("delta result for version {}: changed tile {} has no {} data", info_.version, tile,
                            payloadName(p));
      if (Status s = applyTile(info_, tile, info_.elementBytes(p), it->second.bytes, t.payloads[i]); !s) return s;
    }
  }
  reset();
  return t;
}

}  // namespace lightlink::client
