// Reading a result the daemon delivered through shared memory (proto SharedResult,
// docs/service.md "Shared-memory delivery").
//
// A client on the daemon's machine that asks with `shared_memory` gets one header naming a
// file that holds the result's chunk messages, written once by the daemon for every client
// with the same spec. The file is read into a buffer the calling thread reuses and each
// record is parsed as the ResultMessage it is, as a received message would be.
#pragma once

#include "clients/client/textures.h"
#include "core/common/status.h"
#include "proto/lightlink.pb.h"
#include "proto/shared_result_format.h"

namespace lightlink::client {

// Feeds the chunk messages of `shared` to `assembler` (which has had the header). Errors:
// NotFound when the file is gone or cannot be opened (removed, another user's daemon),
// InvalidInput naming what is wrong when it is not the size the header names, has another
// magic or format version, or holds a truncated or malformed record.
Status readSharedResult(const v1::SharedResult& shared, ResultAssembler& assembler);

}  // namespace lightlink::client
