// fuzz_make_seed OUT.llk: writes the seed artifact of the artifact fuzzer, computed from the
// tiny fuzz scene (tests/fuzz/fuzz_inputs.h). Rerun it into tests/fuzz/corpus/artifact/ when
// the artifact format changes; the replay test fails while the committed seed is stale.
// fuzz_make_seed --bake-outputs DIR: writes the seeds of fuzz_lightmap_exr and fuzz_grid_raw
// (a bake of the same scene) into DIR.
// fuzz_make_seed --requests DIR: writes the seeds of fuzz_requests (builds with the service).
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "tests/fuzz/fuzz_inputs.h"
#ifdef LIGHTLINK_FUZZ_SERVICE
#include "tests/fuzz/fuzz_service_inputs.h"
#endif

int main(int argc, char** argv) {
  lightlink::Status s;
  if (argc == 2) {
    s = lightlink::fuzz::writeSeedArtifact(argv[1]);
  } else if (argc == 3 && std::strcmp(argv[1], "--bake-outputs") == 0) {
    s = lightlink::fuzz::writeSeedBakeOutputs(argv[2]);
#ifdef LIGHTLINK_FUZZ_SERVICE
  } else if (argc == 3 && std::strcmp(argv[1], "--requests") == 0) {
    for (const auto& [name, bytes] : lightlink::fuzz::requestSeeds()) {
      std::ofstream out(std::filesystem::path(argv[2]) / name, std::ios::binary | std::ios::trunc);
      out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
      if (!out) s = lightlink::ioError("cannot write {}", name);
    }
#endif
  } else {
    std::fprintf(stderr, "usage: %s OUT.llk | --bake-outputs DIR | --requests DIR\n", argv[0]);
    return 2;
  }
  if (!s) {
    std::fprintf(stderr, "%s\n", s.toString().c_str());
    return 1;
  }
  return 0;
}
