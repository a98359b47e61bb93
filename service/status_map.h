// The one place where lightlink Status values become gRPC statuses (STYLE.md: exceptions
// and core errors stop at the service edge). Messages are capped so a hostile input echoed
// in an error (a 64 MiB "id") cannot blow up the response.
#pragma once

#include <string>

#include <grpcpp/grpcpp.h>

#include "core/common/status.h"

namespace lightlink::service {

inline constexpr std::size_t kMaxErrorMessage = 1024;

grpc::Status toGrpc(const Status& status);
grpc::Status grpcError(grpc::StatusCode code, std::string message);

}  // namespace lightlink::service
