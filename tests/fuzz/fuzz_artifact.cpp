// libFuzzer target: arbitrary bytes as an artifact (.llk) through artifact::Artifact::open,
// precompute::open and a relight of what opens; checksums are also repaired so mutations
// reach past them (tests/fuzz/fuzz_inputs.h).
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/fuzz_inputs.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)lightlink::fuzz::openArtifactBytes({data, size});
  return 0;
}
