// ResultStream: turns an encoded snapshot into the header + chunk messages of one result,
// full or as a tile delta against the previous result sent on the same stream.
//
// Full result: every payload as consecutive chunks of at most `chunk_bytes`, offsets
// covering [0, size) in order. Delta (Subscribe with `deltas`): the lightmap is compared
// tile by tile (LightmapInfo.tile_size texels per side, edge tiles clipped) across all
// lightmap payloads; only changed tiles are sent, each payload's tile data in tile-local
// row-major order; grid payloads are sent whole when any byte changed. The writer callback
// returns false when the client is gone, which stops the send.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "proto/lightlink.pb.h"
#include "service/snapshot.h"

namespace lightlink::service {

using MessageWriter = std::function<bool(const v1::ResultMessage&)>;

struct HeaderExtras {
  std::string scene_id;
  std::uint64_t skipped_versions = 0;
};

// The header of a result (full or delta) without changed tiles and payload size.
void fillHeader(const Snapshot& s, const EncodedResult& e, const HeaderExtras& extras, v1::ResultHeader* h);

// Sends a full result. Returns false when a write failed.
bool sendFull(const Snapshot& s, const EncodedResult& e, const HeaderExtras& extras, std::size_t chunk_bytes,
              const MessageWriter& write);

// Sends `e` as a delta against `previous` (same spec, same scene). Returns false when a
// write failed.
bool sendDelta(const Snapshot& s, const EncodedResult& e, const EncodedResult& previous, const HeaderExtras& extras,
               std::size_t chunk_bytes, const MessageWriter& write);

// Lightmap tiles whose bytes differ between two encodings of the same spec, in index order.
std::vector<std::uint32_t> changedTiles(const EncodedResult& e, const EncodedResult& previous, int width, int height,
                                        int tile_size);

}  // namespace lightlink::service
