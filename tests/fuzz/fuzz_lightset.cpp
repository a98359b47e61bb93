// libFuzzer target: arbitrary bytes as light-set JSON (docs/lightset.md) through the core
// parser (LightSet::load, applyFile) and, in builds with the wire contract, the client
// library's parser (LightUpdate::fromLightSetText) and the daemon's applyUpdate. Accepted
// sets must round-trip and relight.
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/fuzz_check.h"
#include "tests/fuzz/fuzz_inputs.h"
#include "tests/fuzz/fuzz_service_inputs.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lightlink::fuzz;
  const LightSetVerdict v = loadLightSetBytes({data, size});
  require(v.round_trip.code() != lightlink::Code::kInternal, "light set round trip", v.round_trip);
  require(!v.relit || bool(v.relight), "relight of an applied light set", v.relight);
  const RequestVerdict c = lightSetThroughClient({data, size});
  require(c.validation.code() != lightlink::Code::kInternal, "client light set", c.validation);
  require(!c.relit || bool(c.relight), "relight of a client light set the daemon accepted", c.relight);
  return 0;
}
