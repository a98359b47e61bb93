// Lightmap caches to texels: a texel copies its cache's SH and direct light when the cache
// holds a value (valid or filled), else it is zero and not valid (dilation may fill it).
#version 450
layout(local_size_x = 64) in;
#include "gpu_layout.h"
layout(std430, binding = kTxCacheOfTexel) readonly buffer CacheOfTexel { int cache_of_texel[]; };
layout(std430, binding = kTxHasValue) readonly buffer HasValue { uint has_value[]; };
layout(std430, binding = kTxCacheSh) readonly buffer CacheSh { float cache_sh[]; };
layout(std430, binding = kTxCacheDirect) readonly buffer CacheDirect { vec4 cache_direct[]; };
layout(std430, binding = kTxTexelSh) writeonly buffer TexelSh { float texel_sh[]; };
layout(std430, binding = kTxTexelDirect) writeonly buffer TexelDirect { vec4 texel_direct[]; };
layout(std430, binding = kTxTexelValid) writeonly buffer TexelValid { uint texel_valid[]; };
uniform uint u_count;
uniform uint u_stride;
void main() {
  uint t = gl_GlobalInvocationID.x;
  if (t >= u_count) return;
  int c = cache_of_texel[t];
  bool ok = c >= 0 && has_value[c] != 0u;
  for (uint i = 0u; i < u_stride; ++i) texel_sh[t * u_stride + i] = ok ? cache_sh[uint(c) * u_stride + i] : 0.0;
  texel_direct[t] = ok ? cache_direct[c] : vec4(0.0);
  texel_valid[t] = ok ? 1u : 0u;
}
