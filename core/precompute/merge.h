// Merge: the parts of a sharded precompute assembled into the artifact one machine writes.
//
// `lightlink precompute SCENE --shard I/N` runs every stage but links only shard I's range
// of the caches, and savePart() writes the artifact's sections in the artifact's order with
// the link sections cut to that range, plus a "shard" section saying which range. mergeParts
// opens all N parts (checksums verified), checks that they are the N shards of one run
// (same cache key, same N, each index once, the ranges the split gives, the same bytes in
// every section that is not a link section) and writes, atomically, the artifact: non-link
// sections from part 0, link arrays concatenated in shard order (offsets rebased), the
// surfels' "seen" flags OR-ed. The result is byte-identical to `lightlink precompute SCENE`
// without --shard, and it is opened with precompute::open (every structural check) before it
// replaces anything under the output name. Every rejection names the part (docs/farm.md).
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "core/common/status.h"

namespace lightlink::precompute {

struct MergeResult {
  std::uint64_t cache_key = 0;
  int shards = 0;
  std::uint64_t bytes = 0;  // the artifact's size
};

Expected<MergeResult> mergeParts(std::span<const std::string> part_paths, const std::string& output_path);

}  // namespace lightlink::precompute
