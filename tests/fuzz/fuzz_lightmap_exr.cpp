// libFuzzer target: arbitrary bytes as one of a bake's lightmap EXRs through viewer::readLightlinkExr
// (OpenEXR, then lightlink's checks), then sampled as `lightlink render` samples it.
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/fuzz_inputs.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)lightlink::fuzz::readLightmapExrBytes({data, size});
  return 0;
}
