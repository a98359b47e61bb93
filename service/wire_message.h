// WireMessage: a lightlink.v1.ResultMessage that is already serialized, sent as it is.
//
// A result goes to every client that polls, asks or streams. Built as a protobuf message
// per client, each send would copy the payload twice (into the message, then into gRPC's
// slices), a large share of the daemon's cycles with 50 clients polling a 1 MB lightmap
// (a perf profile of bench/service). Instead a result's messages are
// serialized once per (snapshot, spec) into grpc::ByteBuffers (Snapshot::wire) and every
// send passes a reference to the same slices: no copy and no serialization per client. The
// bytes on the wire are exactly the serialized ResultMessage, so any client parses them as
// it would a message built per send.
//
// gRPC picks a message type's (de)serialization through grpc::SerializationTraits; the
// handlers that send WireMessages are registered with that type (LightlinkService, split
// streaming), which is why the specialization lives here with the type.
#pragma once

#include <grpcpp/impl/serialization_traits.h>
#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/status.h>

namespace lightlink::service {

struct WireMessage {
  const grpc::ByteBuffer* bytes = nullptr;  // owned by the caller until the write returns
};

}  // namespace lightlink::service

namespace grpc {

template <>
class SerializationTraits<lightlink::service::WireMessage, void> {
 public:
  static grpc::Status Serialize(const lightlink::service::WireMessage& m, grpc::ByteBuffer* buffer, bool* own_buffer) {
    if (m.bytes == nullptr) return grpc::Status(grpc::StatusCode::INTERNAL, "WireMessage without bytes");
    *buffer = *m.bytes;  // a reference to the same slices, not a copy of the bytes
    *own_buffer = true;
    return grpc::Status::OK;
  }
  // The daemon only sends WireMessages.
  static grpc::Status Deserialize(grpc::ByteBuffer*, lightlink::service::WireMessage*) {
    return grpc::Status(grpc::StatusCode::UNIMPLEMENTED, "WireMessage is send-only");
  }
};

}  // namespace grpc
