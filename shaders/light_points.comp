// Direct light of the punctual lights at a set of points, shadowed by the shadow maps.
// MODE_SURFELS: out = rho * sum_lights E (the surfels' direct radiosity b0), out2 = out
// unless u_keep_out2 (a warm start keeps b, the last solution, in out2).
// MODE_CACHES: out = sum over *baked* lights of E at valid lightmap caches (baked direct).
// Lights are summed in light-set order, as the CPU relight sums its per-light arrays.
#version 450
layout(local_size_x = 64) in;
#include "gpu_layout.h"
#include "common_light.glsl"

layout(std430, binding = kLpPositions) readonly buffer Positions { vec4 positions[]; };
layout(std430, binding = kLpNormals) readonly buffer Normals { vec4 normals[]; };
layout(std430, binding = kLpLights) readonly buffer Lights { GpuLight lights[]; };
layout(std430, binding = kLpViews) readonly buffer Views { GpuShadowView views[]; };
layout(std430, binding = kLpValid) readonly buffer Valid { uint valid[]; };
layout(std430, binding = kLpAlbedo) readonly buffer Albedo { vec4 albedo[]; };
layout(std430, binding = kLpGiven) readonly buffer Given { vec4 given[]; };
layout(std430, binding = kLpOut) writeonly buffer Out { vec4 result[]; };
layout(std430, binding = kLpOut2) writeonly buffer Out2 { vec4 result2[]; };
layout(binding = kLpShadowUnit) uniform sampler2DArray shadow_map;

uniform uint u_count;
uniform int u_light_count;
uniform int u_use_given;  // surfels: E given per point (parity runs); caches: emitter E to add
uniform int u_keep_out2;  // surfels: 1 leaves out2 as it is
uniform float u_bias;        // constant depth bias, metres (relative to the scene size)
uniform float u_normal_offset;  // texels of normal offset
uniform float u_slope_bias;     // texels of depth bias

// Visibility of the light from p (0..1, 3x3 PCF) through one of the light's views.
float shadowVisibility(GpuLight l, vec3 p, vec3 n) {
  int first = l.kind_views.y, count = l.kind_views.z;
  if (count == 0) return 1.0;
  int vi = first;
  vec3 from_light = p - l.position_range.xyz;
  if (count == 6) {
    // Cube faces +x, -x, +y, -y, +z, -z: the major axis picks the face.
    vec3 a = abs(from_light);
    if (a.x >= a.y && a.x >= a.z) vi += from_light.x >= 0.0 ? 0 : 1;
    else if (a.y >= a.z) vi += from_light.y >= 0.0 ? 2 : 3;
    else vi += from_light.z >= 0.0 ? 4 : 5;
  }
  GpuShadowView v = views[vi];
  bool ortho = v.eye_mode.w > 0.5;
  float dist = ortho ? dot(p - v.eye_mode.xyz, v.dir_texel.xyz) : length(p - v.eye_mode.xyz);
  float texel = ortho ? v.dir_texel.w : v.dir_texel.w * dist;  // world size of one texel at p
  // Normal offset: look the map up from a point pushed off the surface, so the surface's own
  // depth (rasterised at texel resolution) does not shadow it.
  vec3 q = p + n * (u_normal_offset * texel);
  vec4 clip = v.clip_from_world * vec4(q, 1.0);
  if (clip.w <= 0.0) return 1.0;
  vec2 uv = clip.xy / clip.w * 0.5 + 0.5;
  float ref = ortho ? dot(q - v.eye_mode.xyz, v.dir_texel.xyz) : length(q - v.eye_mode.xyz);
  ref -= u_bias + u_slope_bias * texel;
  ivec3 size = textureSize(shadow_map, 0);
  ivec2 centre = ivec2(floor(uv * vec2(size.xy)));
  float lit = 0.0;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      ivec2 t = clamp(centre + ivec2(dx, dy), ivec2(0), size.xy - 1);
      float stored = texelFetch(shadow_map, ivec3(t, vi), 0).r;
      lit += ref <= stored ? 1.0 : 0.0;
    }
  return lit / 9.0;
}

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= u_count) return;
#ifdef MODE_CACHES
  if (valid[i] == 0u) {
    result[i] = vec4(0.0);
    return;
  }
#endif
  vec3 p = positions[i].xyz, n = normals[i].xyz;
  vec3 e = vec3(0.0);
#ifdef MODE_SURFELS
  if (u_use_given != 0) e = given[i].xyz;
#endif
  for (int li = 0; li < u_light_count; ++li) {
    GpuLight l = lights[li];
#ifdef MODE_CACHES
    if (l.cos_inner_baked.y == 0.0) continue;
#endif
    vec3 el = irradianceFrom(l, p, n);
    if (el == vec3(0.0)) continue;
    e += el * shadowVisibility(l, p, n);
  }
#ifdef MODE_CACHES
  if (u_use_given != 0) e += given[i].xyz;  // emitters' direct light (sampled on the host)
#endif
#ifdef MODE_SURFELS
  vec4 b0 = vec4(albedo[i].rgb * e, 0.0);
  result[i] = b0;
  if (u_keep_out2 == 0) result2[i] = b0;
#else
  result[i] = vec4(e, 0.0);
#endif
}
