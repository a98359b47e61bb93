// Cache lighting (seed 000 eq. 5, sec 4.7): L_cache = sum_links B_node F_node (+ sky), both
// link forms. LANES threads share one cache and stride over its links, so a warp reads
// LANES consecutive links (contiguous fp16 coefficients) per step; the partial sums meet in
// shared memory and each lane then finishes a strided subset of the 3 * NC outputs.
// Defines: BANDS (output), LINK_NC (coefficients per stored link, projected), RUNTIME,
// LANES (threads per cache, divides 64).
#version 450
layout(local_size_x = 64) in;
#include "gpu_layout.h"
#include "common_sh.glsl"
#define CACHES_PER_GROUP (64 / LANES)
#define OUT_STRIDE (3 * NC)

layout(std430, binding = kClOffsets) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = kClNode) readonly buffer LinkNode { uint link_node[]; };
layout(std430, binding = kClCoeffs) readonly buffer Coeffs { uint coeffs[]; };
layout(std430, binding = kClOmega) readonly buffer Omega { uint omega[]; };
layout(std430, binding = kClRad) readonly buffer Rad { vec4 rad[]; };
layout(std430, binding = kClValid) readonly buffer Valid { uint valid[]; };
layout(std430, binding = kClSkyVis) readonly buffer SkyVis { float sky_vis[]; };
layout(std430, binding = kClSkyMatrix) readonly buffer SkyMatrix { float sky_matrix[]; };
layout(std430, binding = kClOut) writeonly buffer Out { float result[]; };

uniform uint u_cache_count;
uniform int u_sky;       // 1: add sky_matrix * sky_vis
uniform int u_link_nc;   // coefficients per stored link (sky visibility too)

shared float partial[64 * OUT_STRIDE];

float halfAt(uint h) {
  vec2 pair = unpackHalf2x16(coeffs[h >> 1]);
  return (h & 1u) == 0u ? pair.x : pair.y;
}

void main() {
  uint local = gl_LocalInvocationID.x;
  uint lane = local % LANES, slot = local / LANES;
  uint cache = gl_WorkGroupID.x * CACHES_PER_GROUP + slot;
  bool live = cache < u_cache_count && valid[cache] != 0u;
  float acc[OUT_STRIDE];
  for (int i = 0; i < OUT_STRIDE; ++i) acc[i] = 0.0;
  if (live) {
    uint k1 = offsets[cache + 1];
    for (uint k = offsets[cache] + lane; k < k1; k += LANES) {
      vec3 br = rad[link_node[k]].xyz;
#ifdef RUNTIME
      vec3 d = decodeOctahedral(coeffs[k]);
      vec2 w2 = unpackHalf2x16(omega[k >> 1]);
      float kl[4];
      capBandFactors((k & 1u) == 0u ? w2.x : w2.y, kl);
      float y[NC];
      evalBasis(d, y);
      for (int i = 0; i < NC; ++i) {
        float f = kl[bandOf(i)] * y[i];
        acc[i] += br.r * f;
        acc[NC + i] += br.g * f;
        acc[2 * NC + i] += br.b * f;
      }
#else
      uint h0 = k * uint(LINK_NC);
      for (int i = 0; i < NC; ++i) {
        float f = halfAt(h0 + uint(i));
        acc[i] += br.r * f;
        acc[NC + i] += br.g * f;
        acc[2 * NC + i] += br.b * f;
      }
#endif
    }
  }
  for (int i = 0; i < OUT_STRIDE; ++i) partial[local * OUT_STRIDE + i] = acc[i];
  // Shared writes are made visible explicitly (barrier() alone orders execution only).
  memoryBarrierShared();
  barrier();
  uint row0 = slot * LANES;
  for (uint i = lane; i < uint(OUT_STRIDE) && cache < u_cache_count; i += uint(LANES)) {
    float s = 0.0;
    if (live) {
      for (uint l = 0u; l < LANES; ++l) s += partial[(row0 + l) * OUT_STRIDE + i];
      if (u_sky != 0) {
        uint a = i % uint(NC), ch = i / uint(NC);
        float sky = 0.0;
        for (int j = 0; j < u_link_nc; ++j)
          sky += sky_matrix[(ch * uint(NC) + a) * uint(u_link_nc) + uint(j)] * sky_vis[cache * uint(u_link_nc) + uint(j)];
        s += sky;
      }
    }
    result[cache * OUT_STRIDE + i] = s;
  }
}
