// One bounce gather (DESIGN.md sec 4 "Bounces"): each surfel reads its weighted caches
// (lightmap bilinear, or grid trilinear), turns the SH radiance into irradiance at its
// normal and sets B = b0 + rho * E_indirect. Each workgroup of kGatherGroup surfels (the CPU
// chunk) also writes its sum of |Phi_k - Phi_{k-1}| and of total flux, which the host adds
// in double in group order for the stop test.
#version 450
layout(local_size_x = 256) in;
#include "gpu_layout.h"
#include "common_sh.glsl"
#define STRIDE (3 * NC)

layout(std430, binding = kGaBegin) readonly buffer Begin { uint gather_begin[]; };
layout(std430, binding = kGaCache) readonly buffer Cache { uint gather_cache[]; };
layout(std430, binding = kGaWeight) readonly buffer Weight { float gather_weight[]; };
layout(std430, binding = kGaFromGrid) readonly buffer FromGrid { uint from_grid[]; };
layout(std430, binding = kGaLightmapSh) readonly buffer LightmapSh { float lm_sh[]; };
layout(std430, binding = kGaGridSh) readonly buffer GridSh { float grid_sh[]; };
layout(std430, binding = kGaSurfel) readonly buffer Surfel { vec4 normal_area[]; };
layout(std430, binding = kGaAlbedoEmit) readonly buffer AlbedoEmit { vec4 albedo_emit[]; };
layout(std430, binding = kGaB0) readonly buffer B0 { vec4 b0[]; };
layout(std430, binding = kGaB) buffer B { vec4 b[]; };
layout(std430, binding = kGaPartials) writeonly buffer Partials { vec2 partials[]; };

uniform uint u_count;

shared vec2 red[256];

void main() {
  uint s = gl_GlobalInvocationID.x;
  vec2 sums = vec2(0.0);
  if (s < u_count) {
    float acc[STRIDE];
    for (int i = 0; i < STRIDE; ++i) acc[i] = 0.0;
    bool grid = from_grid[s] != 0u;
    for (uint g = gather_begin[s]; g < gather_begin[s + 1]; ++g) {
      uint off = gather_cache[g] * uint(STRIDE);
      float wt = gather_weight[g];
      if (grid) {
        for (int i = 0; i < STRIDE; ++i) acc[i] += wt * grid_sh[off + uint(i)];
      } else {
        for (int i = 0; i < STRIDE; ++i) acc[i] += wt * lm_sh[off + uint(i)];
      }
    }
    vec4 na = normal_area[s];
    float y[NC];
    evalBasis(na.xyz, y);
    vec3 e = vec3(0.0);
    for (int i = 0; i < NC; ++i) {
      float f = irradianceBandFactor(bandOf(i)) * y[i];
      e += f * vec3(acc[i], acc[NC + i], acc[2 * NC + i]);
    }
    e = max(e, vec3(0.0));
    vec3 albedo = albedo_emit[2 * s].rgb, emitted = albedo_emit[2 * s + 1].rgb;
    vec3 nb = b0[s].rgb + albedo * e;
    vec3 d = abs(nb - b[s].rgb) * na.w;
    vec3 phi = (nb + emitted) * na.w;
    sums = vec2(d.x + d.y + d.z, phi.x + phi.y + phi.z);
    b[s] = vec4(nb, 0.0);
  }
  red[gl_LocalInvocationID.x] = sums;
  memoryBarrierShared();
  barrier();
  for (uint w = 128u; w > 0u; w >>= 1) {
    if (gl_LocalInvocationID.x < w) red[gl_LocalInvocationID.x] += red[gl_LocalInvocationID.x + w];
    memoryBarrierShared();
    barrier();
  }
  if (gl_LocalInvocationID.x == 0u) partials[gl_WorkGroupID.x] = red[0];
}
