// Entry functions of the fuzzers that need the wire contract (proto/lightlink.proto): the
// daemon's request validation (service/validation.cpp) fed with v1 request messages, and the
// client library's light-set parser (clients/client/light_update.cpp), whose requests go
// through the same validation. Built where the v1 messages are: builds with the service,
// and the fuzz build (which generates them without gRPC); the replay test runs them on the
// committed inputs in ordinary builds with the service.
//
// There is no structured protobuf mutator in Debian (libprotobuf-mutator is not packaged):
// the fuzzer mutates serialized messages. Protobuf's own parser is robust and well fuzzed,
// so every input that parses reaches the validation with arbitrary field values; seeds
// (`fuzz_make_seed --requests`) give the fuzzer valid messages of each kind to start from.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "core/common/status.h"

namespace lightlink::fuzz {

// Which message the bytes after the first one are. The first byte picks it (mod the count).
enum class RequestKind : std::uint8_t {
  kOpenScene = 0,     // OpenSceneRequest: precomputeOptionsFrom, backend, lightset_json merge
  kUpdateLights = 1,  // UpdateLightsRequest: applyUpdate on the fuzz scene's lights, then a relight
  kRelight = 2,       // RelightRequest: validateSpec(spec) against 1..4 result bands
  kGetTextures = 3,   // GetTexturesRequest: validateSpec(spec)
  kSubscribe = 4,     // SubscribeRequest: validateSpec(spec)
  kCount = 5,
};

struct RequestVerdict {
  bool parsed = false;  // the bytes parsed as the message
  Status validation;    // what the daemon would answer (before any scene work)
  bool relit = false;   // validation passed for an update or an open's light set
  Status relight;       // relightFuzzScene with the resulting lights: must succeed
};

// One request through the daemon's validation, as the handlers do it (docs/fuzzing.md).
RequestVerdict applyRequestBytes(std::span<const std::uint8_t> bytes);

// The bytes as light-set JSON text through client::LightUpdate::fromLightSetText (ids of
// the scene unknown, then known), and each request it builds through service::applyUpdate
// on the fuzz scene's lights, then a relight: a request the client builds and the daemon
// accepts must relight.
RequestVerdict lightSetThroughClient(std::span<const std::uint8_t> bytes);

// Seeds of fuzz_requests: one valid message of each kind (and a few variants), as
// (file name, bytes with the kind byte first).
std::vector<std::pair<std::string, std::vector<std::uint8_t>>> requestSeeds();

}  // namespace lightlink::fuzz
