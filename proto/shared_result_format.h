// The file format of a result delivered through shared memory (lightlink.proto,
// SharedResult), shared by the daemon that writes it (service/shared_results.h) and the
// client library that reads it (clients/client/shared_result.h): 8 magic bytes naming the
// format and its version, then records of a uint32 little-endian length and that many bytes
// of a serialized ResultMessage holding a Chunk.
#pragma once

namespace lightlink::v1 {

inline constexpr char kSharedResultMagic[8] = {'L', 'L', 'S', 'H', 'R', 'E', 'S', '1'};

}  // namespace lightlink::v1
