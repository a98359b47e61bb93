#include <x86intrin.h>
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <vector>
#include <new>
struct V{float x,y,z;};
struct RowSetup{float shift,inv,z_scale;V t,b,n;};
__attribute__((noinline,target("arch=x86-64-v4"),optimize("fp-contract=off"))) void rowDirections(const RowSetup& r, const float* __restrict bj, const float* __restrict bc,
                                   const float* __restrict bs, const float* __restrict bsx, std::uint32_t strata,
                                   float* __restrict dx, float* __restrict dy, float* __restrict dz) {
  const float shift = r.shift, inv = r.inv, z_scale = r.z_scale;
  const V t = r.t, b = r.b, n = r.n;
  for (std::uint32_t sx = 0; sx < strata; ++sx) {
    const float sum = bj[sx] + shift;
    const float wrapped = sum - 1.0f;
    const float jitter = wrapped < 0.0f ? sum : wrapped;
    const float u = (bsx[sx] + jitter) * inv;
    const float z = 1.0f - z_scale * u;
    const float q = 1.0f - z * z;
    const float rad = std::sqrt(q);
    const float a = rad * bc[sx], c = rad * bs[sx];
    dx[sx] = a * t.x + c * b.x + z * n.x;
    dy[sx] = a * t.y + c * b.y + z * n.y;
    dz[sx] = a * t.z + c * b.z + z * n.z;
  }
}
int main(int argc,char**argv){int off=argc>1?atoi(argv[1]):0; const int N=1024;
 float* m[7]; for(int k=0;k<7;k++){m[k]=(float*)((char*)::operator new(N*4+4096,std::align_val_t{4096})+off*k);}
 for(int i=0;i<N;i++){m[0][i]=drand48();m[1][i]=cos(i);m[2][i]=sin(i);m[3][i]=i%32;}
 RowSetup r{0.3f,1/32.f,1.f,{1,0,0},{0,1,0},{0,0,1}};
 unsigned long long best=~0ull; for(int rep=0;rep<2000;rep++){auto a=__rdtsc();rowDirections(r,m[0],m[1],m[2],m[3],N,m[4],m[5],m[6]);auto b=__rdtsc(); if(b-a<best)best=b-a;}
 // cold-ish: flush tables
 unsigned long long cold=0; for(int rep=0;rep<200;rep++){for(int k=0;k<7;k++)for(int i=0;i<N;i+=16)_mm_clflush(m[k]+i); _mm_mfence(); auto a=__rdtsc();rowDirections(r,m[0],m[1],m[2],m[3],N,m[4],m[5],m[6]);auto b=__rdtsc(); cold+=b-a;}

 for(size_t pol: {64<<10, 256<<10, 512<<10, 1<<20, 2<<20, 4<<20}){ std::vector<char> P(pol,1); unsigned long long tot=0; volatile char sink=0;
   for(int rep=0;rep<300;rep++){ for(size_t i=0;i<pol;i+=64) sink+=P[i]++; auto a=__rdtsc();rowDirections(r,m[0],m[1],m[2],m[3],N,m[4],m[5],m[6]);auto b=__rdtsc(); tot+=b-a;}
   printf("pollute %zu KB: mean %llu\n", pol>>10, tot/300);}
 printf("off %d: hot best %llu ticks, flushed mean %llu\n",off,best,cold/200);}
