// Any-hit shadow rays through the flat BVH of core/rt/flat_bvh.h (built with Embree's
// builder, uploaded by gpu/emitter_sampling.cpp): the same walk and tests as
// FlatBvh::occluded() on the host, which tests/rt checks against Embree. Double-sided, hits
// with t in [tnear, tfar] in units of |dir|; the watertight triangle test of Woop, Benthin
// and Wald (JCGT 2013), as Embree's robust mode.
// Expects BVH_NODES and BVH_TRIANGLES (storage binding indices) to be defined.

layout(std430, binding = BVH_NODES) readonly buffer BvhNodes { vec4 bvh_node[]; };        // 2 per node
layout(std430, binding = BVH_TRIANGLES) readonly buffer BvhTris { vec4 bvh_triangle[]; };  // 3 per triangle

const uint kBvhLeaf = 0x80000000u;
const int kBvhStack = 49;  // kBvhMaxDepth + 1
// The slab test's far distance grows by 1 + 2 gamma(3), so rounding never culls a box the ray crosses.
const float kSlabGrow = 1.0000003576279;

float bvhNonZero(float d) { return abs(d) < 1e-30 ? (d < 0.0 ? -1e-30 : 1e-30) : d; }

bool bvhHitsBox(vec3 lo, vec3 hi, vec3 org, vec3 inv_dir, float tnear, float tfar) {
  precise vec3 a = (lo - org) * inv_dir;
  precise vec3 b = (hi - org) * inv_dir;
  vec3 t0 = min(a, b), t1 = max(a, b) * kSlabGrow;
  float enter = max(tnear, max(t0.x, max(t0.y, t0.z)));
  float leave = min(tfar, min(t1.x, min(t1.y, t1.z)));
  return enter <= leave;
}

bool bvhHitsTriangle(uint t, vec3 org, ivec3 k, vec3 s, float tnear, float tfar) {
  precise vec3 A = bvh_triangle[3 * t].xyz - org;
  precise vec3 B = bvh_triangle[3 * t + 1].xyz - org;
  precise vec3 C = bvh_triangle[3 * t + 2].xyz - org;
  precise float ax = A[k.x] - s.x * A[k.z], ay = A[k.y] - s.y * A[k.z];
  precise float bx = B[k.x] - s.x * B[k.z], by = B[k.y] - s.y * B[k.z];
  precise float cx = C[k.x] - s.x * C[k.z], cy = C[k.y] - s.y * C[k.z];
  precise float u = cx * by - cy * bx, v = ax * cy - ay * cx, w = bx * ay - by * ax;
  if (u == 0.0 || v == 0.0 || w == 0.0) {  // on an edge: decide in double, as the paper does
    u = float(double(cx) * double(by) - double(cy) * double(bx));
    v = float(double(ax) * double(cy) - double(ay) * double(cx));
    w = float(double(bx) * double(ay) - double(by) * double(ax));
  }
  if ((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) return false;
  precise float det = u + v + w;
  if (det == 0.0) return false;
  precise float tt = u * (s.z * A[k.z]) + v * (s.z * B[k.z]) + w * (s.z * C[k.z]);
  return det > 0.0 ? (tt >= tnear * det && tt <= tfar * det) : (tt <= tnear * det && tt >= tfar * det);
}

// True when a triangle lies on org + t * dir for some t in [tnear, tfar].
bool bvhOccluded(vec3 org, vec3 dir, float tnear, float tfar) {
  vec3 inv_dir = 1.0 / vec3(bvhNonZero(dir.x), bvhNonZero(dir.y), bvhNonZero(dir.z));
  vec3 ad = abs(dir);
  ivec3 k;
  k.z = ad.x > ad.y ? (ad.x > ad.z ? 0 : 2) : (ad.y > ad.z ? 1 : 2);
  k.x = (k.z + 1) % 3;
  k.y = (k.x + 1) % 3;
  if (dir[k.z] < 0.0) k.xy = k.yx;
  vec3 s = vec3(dir[k.x] / dir[k.z], dir[k.y] / dir[k.z], 1.0 / dir[k.z]);
  uint stack[kBvhStack];
  int top = 0;
  stack[top++] = 0u;
  while (top > 0) {
    uint n = stack[--top];
    vec4 lo = bvh_node[2 * n], hi = bvh_node[2 * n + 1];
    if (!bvhHitsBox(lo.xyz, hi.xyz, org, inv_dir, tnear, tfar)) continue;
    uint a = floatBitsToUint(lo.w), b = floatBitsToUint(hi.w);
    if ((b & kBvhLeaf) != 0u) {
      uint count = b & ~kBvhLeaf;
      for (uint i = 0u; i < count; ++i)
        if (bvhHitsTriangle(a + i, org, k, s, tnear, tfar)) return true;
    } else {
      stack[top++] = b;
      stack[top++] = a;
    }
  }
  return false;
}
