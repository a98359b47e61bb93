// libFuzzer target: arbitrary bytes as a .gltf/.glb file through scene::loadGltf.
#include <cstddef>
#include <cstdint>

#include "tests/fuzz/fuzz_inputs.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  (void)lightlink::fuzz::loadGltfBytes({data, size});
  return 0;
}
