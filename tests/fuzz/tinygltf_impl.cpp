// Fuzz build only: tinygltf's implementation compiled into fuzz_gltf with the fuzzer's
// coverage instrumentation and sanitizers, so libFuzzer is guided inside the glTF parser
// too (Debian's libtinygltf.so is not instrumented: mutations that only change its paths
// look useless to the fuzzer). Object files of the executable come first at link time, so
// these definitions are the ones lightlink_scene's calls bind to; stb's decoders stay in
// Debian's libstb.
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
