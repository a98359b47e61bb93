// The caches' samples in ray order as a throwaway cut_bench dumped them (per cache: a 32-bit
// count, then the 64-bit samples), for the sort variants' timings.
#pragma once
#include <cstdio>
#include <vector>
#include "core/links/cut.h"
inline std::vector<std::vector<lightlink::links::Sample>> readSamples(const char* path) {
  FILE* f = std::fopen(path, "rb");
  std::vector<std::vector<lightlink::links::Sample>> caches;
  std::uint32_t m;
  while (f && std::fread(&m, 4, 1, f) == 1) {
    std::vector<lightlink::links::Sample> v(m);
    if (std::fread(v.data(), 8, m, f) != m) break;
    caches.push_back(std::move(v));
  }
  return caches;
}
