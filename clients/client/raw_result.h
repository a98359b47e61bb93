// RawResult: a lightlink.v1.ResultMessage read straight from gRPC's receive buffer.
//
// Parsed by protobuf, a chunk's `data` (up to 1 MiB) is copied out of gRPC's slices into a
// std::string, then again by the ResultAssembler into the payload. With 50 clients polling a
// 1 MB lightmap on one machine, those copies were the clients' largest user-space cost in a
// perf profile of bench/service (docs/results.md, issue 7 third pass). Relight, GetTextures
// and Subscribe therefore read each message as a RawResultMessage (gRPC's ByteBuffer, kept
// without a copy) and decodeRawResult
// reads the chunk's small fields from the protobuf wire format itself, leaving `data` as
// pieces of the received slices that the assembler copies once, into place. Headers (small)
// are handed to protobuf. The decoder follows the protobuf encoding rules a parser must:
// unknown fields of any wire type are skipped, the last of repeated scalar or oneof fields
// wins, and anything truncated or malformed is an error naming what is wrong.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <grpcpp/impl/serialization_traits.h>
#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/slice.h>
#include <grpcpp/support/status.h>

#include "core/common/status.h"
#include "proto/lightlink.pb.h"

namespace lightlink::client {

// A received ResultMessage, undecoded.
struct RawResultMessage {
  grpc::ByteBuffer bytes;
};

// What decodeRawResult found: a header, or a chunk whose data lies in `data` (pieces of
// `slices`, which keep the received memory alive).
struct RawResult {
  enum class Kind { kNone, kHeader, kChunk };
  Kind kind = Kind::kNone;
  v1::ResultHeader header;
  int payload = 0;
  std::uint64_t offset = 0;
  std::uint32_t tile = 0;
  std::vector<std::span<const std::uint8_t>> data;
  std::size_t dataSize() const;

  std::vector<grpc::Slice> slices;
};

// Decodes `bytes` (a serialized lightlink.v1.ResultMessage) into `out` (reused: its vectors
// keep their capacity).
Status decodeRawResult(const grpc::ByteBuffer& bytes, RawResult& out);

}  // namespace lightlink::client

namespace grpc {

template <>
class SerializationTraits<lightlink::client::RawResultMessage, void> {
 public:
  static grpc::Status Serialize(const lightlink::client::RawResultMessage&, grpc::ByteBuffer*, bool*) {
    return grpc::Status(grpc::StatusCode::UNIMPLEMENTED, "RawResultMessage is receive-only");
  }
  static grpc::Status Deserialize(grpc::ByteBuffer* buffer, lightlink::client::RawResultMessage* m) {
    m->bytes.Swap(buffer);  // keeps gRPC's slices, no copy
    buffer->Clear();
    return grpc::Status::OK;
  }
};

}  // namespace grpc
