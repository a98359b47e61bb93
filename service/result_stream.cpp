#include "service/result_stream.h"

#include <algorithm>
#include <cstring>

namespace lightlink::service {
namespace {

bool isLightmapPayload(v1::Payload p) {
  return p == v1::PAYLOAD_LIGHTMAP_SH || p == v1::PAYLOAD_LIGHTMAP_DIRECT || p == v1::PAYLOAD_LIGHTMAP_VALID;
}

bool sendPayloadChunks(const EncodedPayload& p, std::size_t chunk_bytes, v1::ResultMessage& msg,
                       const MessageWriter& write) {
  for (std::size_t off = 0; off < p.bytes.size(); off += chunk_bytes) {
    auto* c = msg.mutable_chunk();
    c->set_payload(p.kind);
    c->set_offset(off);
    c->set_tile(0);
    c->set_data(p.bytes.data() + off, std::min(chunk_bytes, p.bytes.size() - off));
    if (!write(msg)) return false;
  }
  return true;
}

struct TileRect {
  int x0, y0, w, h;
};

TileRect tileRect(std::uint32_t tile, int width, int height, int tile_size) {
  const int tiles_x = (width + tile_size - 1) / tile_size;
  const int tx = static_cast<int>(tile) % tiles_x, ty = static_cast<int>(tile) / tiles_x;
  const int x0 = tx * tile_size, y0 = ty * tile_size;
  return {x0, y0, std::min(tile_size, width - x0), std::min(tile_size, height - y0)};
}

}  // namespace

void fillHeader(const Snapshot& s, const EncodedResult& e, const HeaderExtras& extras, v1::ResultHeader* h) {
  h->mutable_scene()->set_scene_id(extras.scene_id);
  h->set_version(s.version);
  h->set_backend(s.backend);
  h->set_bands(e.spec.bands);
  h->set_precision(e.spec.precision);
  h->set_component(e.spec.component);
  if (e.spec.lightmap) {
    h->mutable_lightmap()->set_width(s.width);
    h->mutable_lightmap()->set_height(s.height);
  }
  h->mutable_lightmap()->set_tile_size(s.tile_size);
  if (e.spec.grid && s.grid.present) {
    auto* g = h->mutable_grid();
    g->set_present(true);
    g->mutable_origin()->set_x(s.grid.origin.x);
    g->mutable_origin()->set_y(s.grid.origin.y);
    g->mutable_origin()->set_z(s.grid.origin.z);
    g->mutable_spacing()->set_x(s.grid.spacing_m);
    g->mutable_spacing()->set_y(s.grid.spacing_m);
    g->mutable_spacing()->set_z(s.grid.spacing_m);
    g->set_nx(s.grid.dims.x);
    g->set_ny(s.grid.dims.y);
    g->set_nz(s.grid.dims.z);
  }
  h->set_relight_ms(s.relight_ms);
  h->set_skipped_versions(extras.skipped_versions);
  h->set_coalesced_updates(s.coalesced);
  h->set_preview(s.preview);
  h->set_residual(s.residual);
  h->set_iterations(static_cast<std::uint32_t>(std::max(0, s.iterations)));
  h->set_kind(s.instant_preview ? v1::RESULT_KIND_INSTANT_PREVIEW : v1::RESULT_KIND_LINKED);
}

bool sendFull(const Snapshot& s, const EncodedResult& e, const HeaderExtras& extras, std::size_t chunk_bytes,
              const MessageWriter& write) {
  v1::ResultMessage msg;
  auto* h = msg.mutable_header();
  fillHeader(s, e, extras, h);
  h->set_payload_bytes(e.total_bytes);
  if (!write(msg)) return false;
  for (const auto& p : e.payloads)
    if (!sendPayloadChunks(p, chunk_bytes, msg, write)) return false;
  return true;
}

std::vector<std::uint32_t> changedTiles(const EncodedResult& e, const EncodedResult& previous, int width, int height,
                                        int tile_size) {
  std::vector<std::uint32_t> changed;
  if (width <= 0 || height <= 0) return changed;
  const int tiles_x = (width + tile_size - 1) / tile_size, tiles_y = (height + tile_size - 1) / tile_size;
  for (std::uint32_t t = 0; t < static_cast<std::uint32_t>(tiles_x * tiles_y); ++t) {
    const TileRect r = tileRect(t, width, height, tile_size);
    bool differs = false;
    for (std::size_t i = 0; i < e.payloads.size() && !differs; ++i) {
      const auto& p = e.payloads[i];
      if (!isLightmapPayload(p.kind)) continue;
      const auto& q = previous.payloads[i];
      const std::size_t row_bytes = r.w * p.bytes_per_element;
      for (int y = r.y0; y < r.y0 + r.h && !differs; ++y) {
        const std::size_t at = (static_cast<std::size_t>(y) * width + r.x0) * p.bytes_per_element;
        differs = std::memcmp(p.bytes.data() + at, q.bytes.data() + at, row_bytes) != 0;
      }
    }
    if (differs) changed.push_back(t);
  }
  return changed;
}

bool sendDelta(const Snapshot& s, const EncodedResult& e, const EncodedResult& previous, const HeaderExtras& extras,
               std::size_t chunk_bytes, const MessageWriter& write) {
  // Same spec on the same stream, so the two encodings have the same payloads and sizes.
  const bool same_layout =
      e.payloads.size() == previous.payloads.size() &&
      std::equal(e.payloads.begin(), e.payloads.end(), previous.payloads.begin(),
                 [](const auto& a, const auto& b) { return a.kind == b.kind && a.bytes.size() == b.bytes.size(); });
  if (!same_layout) return sendFull(s, e, extras, chunk_bytes, write);

  const int width = e.spec.lightmap ? s.width : 0, height = e.spec.lightmap ? s.height : 0;
  const std::vector<std::uint32_t> tiles = changedTiles(e, previous, width, height, s.tile_size);
  std::vector<bool> grid_changed(e.payloads.size(), false);
  std::uint64_t bytes = 0;
  for (std::size_t i = 0; i < e.payloads.size(); ++i) {
    const auto& p = e.payloads[i];
    if (isLightmapPayload(p.kind)) {
      for (auto t : tiles) {
        const TileRect r = tileRect(t, width, height, s.tile_size);
        bytes += static_cast<std::uint64_t>(r.w) * r.h * p.bytes_per_element;
      }
    } else if (p.bytes != previous.payloads[i].bytes) {
      grid_changed[i] = true;
      bytes += p.bytes.size();
    }
  }
  v1::ResultMessage msg;
  auto* h = msg.mutable_header();
  fillHeader(s, e, extras, h);
  h->set_delta(true);
  for (auto t : tiles) h->add_changed_tiles(t);
  h->set_payload_bytes(bytes);
  if (!write(msg)) return false;

  std::string tile_bytes;
  for (std::size_t i = 0; i < e.payloads.size(); ++i) {
    const auto& p = e.payloads[i];
    if (!isLightmapPayload(p.kind)) {
      if (grid_changed[i] && !sendPayloadChunks(p, chunk_bytes, msg, write)) return false;
      continue;
    }
    for (auto t : tiles) {
      const TileRect r = tileRect(t, width, height, s.tile_size);
      const std::size_t row_bytes = r.w * p.bytes_per_element;
      tile_bytes.resize(row_bytes * r.h);
      for (int y = 0; y < r.h; ++y)
        std::memcpy(tile_bytes.data() + y * row_bytes,
                    p.bytes.data() + (static_cast<std::size_t>(r.y0 + y) * width + r.x0) * p.bytes_per_element,
                    row_bytes);
      for (std::size_t off = 0; off < tile_bytes.size(); off += chunk_bytes) {
        auto* c = msg.mutable_chunk();
        c->set_payload(p.kind);
        c->set_offset(off);
        c->set_tile(t);
        c->set_data(tile_bytes.data() + off, std::min(chunk_bytes, tile_bytes.size() - off));
        if (!write(msg)) return false;
      }
    }
  }
  return true;
}

}  // namespace lightlink::service
