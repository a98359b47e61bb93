#include <sys/mman.h>
#include <cstdlib>
#include <cstring>
#include <chrono>
#include <cstdio>
int main(int argc, char** argv) {
  const size_t bytes = 40u << 20;
  int mode = atoi(argv[1]);
  for (int round = 0; round < 3; ++round) {
    auto t0 = std::chrono::steady_clock::now();
    char* p;
    if (mode == 1) { p = (char*)aligned_alloc(2u << 20, bytes); madvise(p, bytes, MADV_HUGEPAGE); }
    else if (mode == 2) { p = (char*)aligned_alloc(2u << 20, bytes); madvise(p, bytes, MADV_NOHUGEPAGE); }
    else p = (char*)malloc(bytes);
    for (size_t i = 0; i < bytes; i += 4096) p[i] = 1;
    auto t1 = std::chrono::steady_clock::now();
    for (size_t i = 0; i < bytes; i += 64) p[i] = 2;
    auto t2 = std::chrono::steady_clock::now();
    printf("mode %d round %d: touch %.2f ms, retouch %.2f ms\n", mode, round, std::chrono::duration<double,std::milli>(t1-t0).count(), std::chrono::duration<double,std::milli>(t2-t1).count());
    free(p);
  }
}
