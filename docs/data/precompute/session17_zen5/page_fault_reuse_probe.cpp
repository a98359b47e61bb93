#include <sys/mman.h>
#include <cstdlib>
#include <cstring>
#include <chrono>
#include <cstdio>
double touch(char* p, size_t bytes) {
  auto t0 = std::chrono::steady_clock::now();
  for (size_t i = 0; i < bytes; i += 4096) p[i] = 1;
  return std::chrono::duration<double,std::milli>(std::chrono::steady_clock::now()-t0).count();
}
int main(int argc, char** argv) {
  const size_t bytes = 40u << 20;
  size_t pre = size_t(atoi(argv[1])) << 20;
  if (pre) {
    char* q = (char*)aligned_alloc(2u << 20, pre); madvise(q, pre, MADV_HUGEPAGE);
    printf("pre %zu MB huge: %.2f ms\n", pre >> 20, touch(q, pre));
    free(q);
  }
  char* p = (char*)aligned_alloc(2u << 20, bytes); madvise(p, bytes, MADV_HUGEPAGE);
  printf("main 40 MB huge: %.2f ms\n", touch(p, bytes));
}
