// libFuzzer target: arbitrary bytes as a bake's grid.raw through viewer::readGridRaw (what
// `lightlink render` and the game client read), then sampled as render samples it.
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/fuzz_inputs.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)lightlink::fuzz::readGridRawBytes({data, size});
  return 0;
}
