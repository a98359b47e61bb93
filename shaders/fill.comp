// One level of a FillPlan (caches::FillPlan): targets [u_begin, u_end) of the level-sorted
// plan, none of which reads another target of the same level.
// Fill (lightmap/grid caches, per-cache direct): target = mean of all its sources.
// DILATE (texels): target = mean of its sources that hold a value; texel SH and direct
// light together, and the target becomes valid when any source was.
#version 450
layout(local_size_x = 64) in;
#include "gpu_layout.h"
layout(std430, binding = kFiTarget) readonly buffer Target { uint target[]; };
layout(std430, binding = kFiBegin) readonly buffer Begin { uint source_begin[]; };
layout(std430, binding = kFiSource) readonly buffer Source { uint source[]; };
layout(std430, binding = kFiData) buffer Data { float data[]; };
#ifdef DILATE
layout(std430, binding = kFiValid) buffer Valid { uint valid[]; };
layout(std430, binding = kFiDirect) buffer Direct { vec4 direct[]; };
#endif
uniform uint u_begin;
uniform uint u_end;
uniform uint u_stride;  // floats per item

void main() {
  uint t = u_begin + gl_GlobalInvocationID.x;
  if (t >= u_end) return;
  uint b0 = source_begin[t], b1 = source_begin[t + 1];
  uint dst = target[t] * u_stride;
#ifdef DILATE
  uint used = 0u;
  vec4 dir = vec4(0.0);
  for (uint k = b0; k < b1; ++k) {
    uint src_t = source[k];
    if (valid[src_t] == 0u) continue;
    ++used;
    for (uint i = 0u; i < u_stride; ++i) data[dst + i] += data[src_t * u_stride + i];
    dir += direct[src_t];
  }
  if (used == 0u) return;
  float inv = 1.0 / float(used);
  for (uint i = 0u; i < u_stride; ++i) data[dst + i] *= inv;
  direct[target[t]] = dir * inv;
  valid[target[t]] = 1u;
#else
  for (uint i = 0u; i < u_stride; ++i) data[dst + i] = 0.0;
  if (b1 == b0) return;
  float inv = 1.0 / float(b1 - b0);
  for (uint k = b0; k < b1; ++k)
    for (uint i = 0u; i < u_stride; ++i) data[dst + i] += data[source[k] * u_stride + i];
  for (uint i = 0u; i < u_stride; ++i) data[dst + i] *= inv;
#endif
}
