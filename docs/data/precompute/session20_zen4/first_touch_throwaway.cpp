#include <sys/mman.h>
#include <cstdlib>
#include <cstring>
#include <cstdio>
#include <chrono>
int main(int argc,char**argv){
  size_t bytes = 37u<<20; int huge = atoi(argv[1]);
  // some prior allocation churn like the bench: 129 MB touched and kept
  size_t pre = size_t(atoi(argv[2]))<<20; char* q = (char*)malloc(pre+1); for(size_t i=0;i<pre;i+=4096) q[i]=1;
  auto t0=std::chrono::steady_clock::now();
  char* p=(char*)aligned_alloc(2<<20, bytes);
  if(huge) madvise(p, bytes, MADV_HUGEPAGE);
  for(size_t i=0;i<bytes;i+=4096) p[i]=1;
  auto t1=std::chrono::steady_clock::now();
  printf("huge=%d pre=%zuMB first touch of 37 MB: %.2f ms\n",huge,pre>>20,std::chrono::duration<double,std::milli>(t1-t0).count());
  free(p); free(q);
}
