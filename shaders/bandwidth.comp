// Memory bandwidth yardstick for the benchmark: each thread reads uvec4s with a grid
// stride (coalesced) and, with COPY, writes them to the destination; without COPY it folds
// them into one value per thread that is written only if impossible, so the reads stay.
#version 450
layout(local_size_x = 256) in;
#include "gpu_layout.h"
layout(std430, binding = kBwSource) readonly buffer Source { uvec4 src[]; };
layout(std430, binding = kBwDest) writeonly buffer Dest { uvec4 dst[]; };
uniform uint u_count;  // uvec4 elements
void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  uvec4 acc = uvec4(0u);
  for (uint i = gl_GlobalInvocationID.x; i < u_count; i += stride) {
#ifdef COPY
    dst[i] = src[i];
#else
    acc ^= src[i];
#endif
  }
#ifndef COPY
  if (acc == uvec4(0xdeadbeefu, 1u, 2u, 3u)) dst[gl_GlobalInvocationID.x] = acc;
#endif
}
