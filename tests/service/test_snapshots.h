// A small snapshot for the in-process service tests (payload encoding, tile deltas, the wire
// form, shared-memory files): 70 x 40 texels, 2 bands, tiles 3 x 2 (edge tiles clipped).
#pragma once

#include <cstddef>

#include "service/snapshot.h"

namespace lightlink::service::testing {

// Fills `s` in place (Snapshots hold mutexes: never moved) with values that differ per texel.
inline void fillSnapshot(Snapshot& s, float base) {
  s.version = 1;
  s.bands = 2;
  s.width = 70;
  s.height = 40;
  const std::size_t texels = 70 * 40;
  s.lightmap_sh.resize(texels * 12);
  for (std::size_t i = 0; i < s.lightmap_sh.size(); ++i) s.lightmap_sh[i] = base + 0.001f * static_cast<float>(i % 977);
  s.direct.assign(texels * 3, base);
  s.texel_valid.assign(texels, 1);
}

}  // namespace lightlink::service::testing
