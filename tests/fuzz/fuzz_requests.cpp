// libFuzzer target: a kind byte + a serialized v1 request (OpenScene, UpdateLights, Relight,
// GetTextures, Subscribe) through the daemon's validation (service/validation.cpp) and, for
// an accepted update or open light set, a relight of the fuzz scene with the new lights.
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/fuzz_check.h"
#include "tests/fuzz/fuzz_service_inputs.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lightlink::fuzz;
  const RequestVerdict v = applyRequestBytes({data, size});
  require(v.validation.code() != lightlink::Code::kInternal, "request validation", v.validation);
  require(!v.relit || bool(v.relight), "relight after an accepted request", v.relight);
  return 0;
}
