// fuzz_make_seed OUT.llk: writes the seed artifact of the artifact fuzzer, computed from the
// tiny fuzz scene (tests/fuzz/fuzz_inputs.h). Rerun it into tests/fuzz/corpus/artifact/ when
// the artifact format changes; the replay test fails while the committed seed is stale.
#include <cstdio>

#include "tests/fuzz/fuzz_inputs.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT.llk\n", argv[0]);
    return 2;
  }
  const lightlink::Status s = lightlink::fuzz::writeSeedArtifact(argv[1]);
  if (!s) {
    std::fprintf(stderr, "%s\n", s.toString().c_str());
    return 1;
  }
  return 0;
}
