#include <stdio.h>
#include <time.h>
#include <x86intrin.h>
int main(){ struct timespec a,b; unsigned long long t0=__rdtsc(); clock_gettime(CLOCK_MONOTONIC,&a);
 unsigned long x=1; for(long i=0;i<1000000000L;i++){ __asm__ volatile("add $1, %0" : "+r"(x)); }
 clock_gettime(CLOCK_MONOTONIC,&b); unsigned long long t1=__rdtsc(); double s=(b.tv_sec-a.tv_sec)+(b.tv_nsec-a.tv_nsec)*1e-9;
 printf("%.3f s -> %.2f GHz core (1 add/cycle), tsc %.2f GHz\n", s, 1.0/s, (t1-t0)/s/1e9); return x==0; }
