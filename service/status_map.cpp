#include "service/status_map.h"

namespace lightlink::service {

grpc::Status grpcError(grpc::StatusCode code, std::string message) {
  if (message.size() > kMaxErrorMessage) {
    message.resize(kMaxErrorMessage);
    message += "...";
  }
  return {code, message};
}

grpc::Status toGrpc(const Status& s) {
  switch (s.code()) {
    case Code::kOk: return grpc::Status::OK;
    case Code::kInvalidInput: return grpcError(grpc::StatusCode::INVALID_ARGUMENT, s.message());
    case Code::kUnsupported: return grpcError(grpc::StatusCode::FAILED_PRECONDITION, s.message());
    case Code::kNotFound: return grpcError(grpc::StatusCode::NOT_FOUND, s.message());
    case Code::kIoError: return grpcError(grpc::StatusCode::INTERNAL, s.message());
    case Code::kInternal: return grpcError(grpc::StatusCode::INTERNAL, s.message());
    case Code::kResourceExhausted: return grpcError(grpc::StatusCode::RESOURCE_EXHAUSTED, s.message());
    case Code::kCancelled: return grpcError(grpc::StatusCode::CANCELLED, s.message());
  }
  return grpcError(grpc::StatusCode::UNKNOWN, s.message());
}

}  // namespace lightlink::service
