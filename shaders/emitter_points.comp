// The emitters' sampled light at a set of points, one workgroup of LANES lanes (1..32,
// default 32) per point: the estimator of core/relight/emitter_direct.cpp (EmitterSampler)
// step for step, its samples spread over the lanes (sample i on lane i % LANES), its shadow
// rays traced through the flat BVH (common_bvh.glsl). Each round's LANES contributions meet in
// shared memory and are added to their triangle's layer in sample order, each output by one
// lane, so the sums run in the host's order for any LANES. Default: irradiance per layer at points with a normal (surfels, lightmap
// caches), out = sum / N. MODE_SH (with BANDS): the SH of the radiance arriving over the whole
// sphere (grid caches), 3 planar channel blocks per layer.
//
// Same samples as the host: the pick, its stratification and the spherical-triangle set-up
// and sampling in double (as the host, with the trigonometry written out below), so sample
// points agree to rounding and a shadow test differs only where a sample lands within
// rounding of an occluder's edge.
#version 450
#ifndef LANES
#define LANES 32
#endif
layout(local_size_x = LANES) in;  // one workgroup per point: its lanes share the samples
#include "gpu_layout.h"
#define BVH_NODES kEmBvhNodes
#define BVH_TRIANGLES kEmBvhTriangles
#include "common_bvh.glsl"
#ifdef MODE_SH
#include "common_sh.glsl"
#define STRIDE (3 * NC)
#else
#define STRIDE 3
#endif

layout(std430, binding = kEmEmitters) readonly buffer Emitters { GpuEmitter emitters[]; };
layout(std430, binding = kEmPick) readonly buffer Pick { double pick[]; };
layout(std430, binding = kEmPositions) readonly buffer Positions { vec4 positions[]; };
layout(std430, binding = kEmNormals) readonly buffer Normals { vec4 normals[]; };
layout(std430, binding = kEmRotation) readonly buffer Rotation { vec2 rotation[]; };
layout(std430, binding = kEmValid) readonly buffer Valid { uint valid[]; };
layout(std430, binding = kEmOut) buffer Out { float result[]; };
layout(std430, binding = kEmRays) writeonly buffer Rays { uint rays[]; };

uniform uint u_first;      // point of this dispatch's first workgroup
uniform uint u_count;      // points in all
uniform int u_samples;     // N per point
uniform int u_emitters;    // emitting triangles
uniform int u_layers;
uniform int u_local;       // 1: each point picks by its own weights (<= kEmLocalPickMax emitters)
uniform int u_has_bvh;     // 0: nothing casts a shadow
uniform float u_eps;       // Accel::rayEpsilon(), metres

const double kPiD = 3.14159265358979323846LF;
const double kMinSphericalSr = 3e-4LF, kMaxSphericalSr = 6.22LF;

const uint kLanes = uint(LANES);

// The point's own pick (u_local): cdf, 1 / P(t), 1 / pdf_A; its weights while it is built.
shared double l_cdf[kEmLocalPickMax];
shared double l_weight[kEmLocalPickMax];
shared float l_inv_pick[kEmLocalPickMax];
shared float l_inv_pdf_area[kEmLocalPickMax];
shared bool l_none;  // no emitter can light the point
// One round of samples: light (rgb) and layer (w, -1: none) per lane, and its direction.
shared vec4 round_light[kLanes];
shared vec3 round_dir[kLanes];
shared uint traced_total;

double cdfAt(int e) { return u_local != 0 ? l_cdf[e] : pick[4 * e]; }
float invPick(int e) { return u_local != 0 ? l_inv_pick[e] : emitters[e].p0_inv_pick.w; }
float invPdfArea(int e) { return u_local != 0 ? l_inv_pdf_area[e] : emitters[e].e1_inv_pdf_area.w; }

// Accel::offsetOrigin.
vec3 offsetOrigin(vec3 p, vec3 n, vec3 dir) {
  float largest = max(abs(p.x), max(abs(p.y), abs(p.z)));
  float distance = u_eps + 16.0 * 1.1920928955078125e-7 * largest;
  float n_len2 = dot(n, n);
  if (!(n_len2 > 0.0)) {
    float d_len2 = dot(dir, dir);
    return d_len2 > 0.0 ? p + dir * (distance / sqrt(d_len2)) : p;
  }
  float side = dot(n, dir) >= 0.0 ? 1.0 : -1.0;
  return p + n * (side * distance / sqrt(n_len2));
}

// Trigonometry in double, written out: GLSL has none, and the float built-ins are
// approximations on some drivers (Mesa's asin is a cubic, ~1e-4 rad), far too coarse for a
// solid angle that is a small difference of three angles.
// sin and cos by Taylor series on [-pi/4, pi/4] after reduction by quadrants (|x| < ~100).
void dsincos(double x, out double s, out double c) {
  const double kHalfPi = 1.57079632679489661923LF;
  double k = floor(x / kHalfPi + 0.5LF);
  double r = x - k * kHalfPi, r2 = r * r;
  double ts = r, tc = 1.0LF, ps = r, pc = 1.0LF;
  for (int i = 1; i <= 10; ++i) {
    ps *= -r2 / double((2 * i) * (2 * i + 1));
    pc *= -r2 / double((2 * i - 1) * (2 * i));
    ts += ps, tc += pc;
  }
  int q = int(k) & 3;
  s = q == 0 ? ts : q == 1 ? tc : q == 2 ? -ts : -tc;
  c = q == 0 ? tc : q == 1 ? -ts : q == 2 ? -tc : ts;
}
// atan2 refined by Newton's method on x sin t - y cos t = 0 from the float estimate.
double datan2(double y, double x) {
  double t = double(atan(float(y), float(x)));
  for (int i = 0; i < 3; ++i) {
    double s, c;
    dsincos(t, s, c);
    double d = x * c + y * s;
    if (d == 0.0LF) break;
    t -= (x * s - y * c) / d;
  }
  return t;
}
double dasin(double z) { return datan2(z, sqrt(max(0.0LF, 1.0LF - z * z))); }

double angleBetween(dvec3 a, dvec3 b) {
  if (dot(a, b) < 0.0LF) return kPiD - 2.0LF * dasin(min(1.0LF, length(a + b) * 0.5LF));
  return 2.0LF * dasin(min(1.0LF, length(b - a) * 0.5LF));
}

struct SphTri {
  bool ok;
  dvec3 a, b, c_perp;
  double cos_alpha, sin_alpha, cos_ab, omega;
};

SphTri setUpSphericalTriangle(dvec3 a, dvec3 b, dvec3 c) {
  SphTri t;
  t.ok = false;
  dvec3 n_ab = cross(a, b), n_bc = cross(b, c), n_ca = cross(c, a);
  double l_ab = length(n_ab), l_bc = length(n_bc), l_ca = length(n_ca);
  if (!(l_ab > 0.0LF && l_bc > 0.0LF && l_ca > 0.0LF)) return t;
  n_ab /= l_ab, n_bc /= l_bc, n_ca /= l_ca;
  double alpha = angleBetween(n_ab, -n_ca);
  t.omega = alpha + angleBetween(n_bc, -n_ab) + angleBetween(n_ca, -n_bc) - kPiD;
  if (!(t.omega >= kMinSphericalSr && t.omega <= kMaxSphericalSr)) return t;
  dvec3 c_perp = c - dot(c, a) * a;
  double lc = length(c_perp);
  if (!(lc > 0.0LF)) return t;
  t.a = a, t.b = b, t.c_perp = c_perp / lc;
  dsincos(alpha, t.sin_alpha, t.cos_alpha);
  t.cos_ab = dot(a, b);
  t.ok = true;
  return t;
}

bool sampleSphericalTriangle(SphTri t, double u0, double u1, out dvec3 w) {
  double sin_ap, cos_ap;
  dsincos(kPiD + u0 * t.omega, sin_ap, cos_ap);
  double sin_phi = sin_ap * t.cos_alpha - cos_ap * t.sin_alpha;
  double cos_phi = cos_ap * t.cos_alpha + sin_ap * t.sin_alpha;
  double k1 = cos_phi + t.cos_alpha;
  double k2 = sin_phi - t.sin_alpha * t.cos_ab;
  double denom = (k2 * sin_phi + k1 * cos_phi) * t.sin_alpha;
  w = t.b;
  if (denom == 0.0LF) return false;
  double cos_bp = clamp((k2 + (k2 * cos_phi - k1 * sin_phi) * t.cos_alpha) / denom, -1.0LF, 1.0LF);
  double sin_bp = sqrt(max(0.0LF, 1.0LF - cos_bp * cos_bp));
  dvec3 cp = cos_bp * t.a + sin_bp * t.c_perp;
  double cos_theta = 1.0LF - u1 * (1.0LF - dot(cp, t.b));
  double sin_theta = sqrt(max(0.0LF, 1.0LF - cos_theta * cos_theta));
  dvec3 cp_perp = cp - dot(cp, t.b) * t.b;
  double lp = length(cp_perp);
  if (lp > 0.0LF) w = cos_theta * t.b + sin_theta * (cp_perp / lp);
  return true;
}

// Sample i of the point: its light (L_e * weight), layer and direction; false when it cannot
// contribute (no shadow ray). `traced`: a shadow ray was cast (it may be blocked: light 0).
// tri / tri_of_setup cache the spherical-triangle set-up of the lane's last triangle.
bool pointSample(int i, int n, int m, vec3 position, vec3 normal, bool sphere, double r0, double r1,
                 inout SphTri tri, inout int tri_of_setup, out vec3 light, out int layer, out vec3 w_unit,
                 out bool traced) {
  light = vec3(0.0), layer = -1, w_unit = vec3(0.0), traced = false;
  double u = double(i) / double(n) + r0;
  u -= floor(u);
  double v = double(bitfieldReverse(uint(i))) * (1.0LF / 4294967296.0LF) + r1;  // radicalInverse(i, 2)
  v -= floor(v);
  int lo_i = 0, hi_i = m;  // upper_bound(cdf, u)
  while (lo_i < hi_i) {
    int mid = (lo_i + hi_i) / 2;
    if (cdfAt(mid) > u) hi_i = mid;
    else lo_i = mid + 1;
  }
  int e = min(lo_i, m - 1);
  double lo = e > 0 ? cdfAt(e - 1) : 0.0LF;
  double ur = clamp((u - lo) / max(cdfAt(e) - lo, 1e-300LF), 0.0LF, 1.0LF);
  vec3 p0 = emitters[e].p0_inv_pick.xyz, e1 = emitters[e].e1_inv_pdf_area.xyz, e2 = emitters[e].e2_layer.xyz;
  vec3 ne = emitters[e].normal_two_sided.xyz;
  vec2 bary = vec2(0.0);
  float weight = 0.0, cos_r = 0.0, cos_e = 0.0;
  dvec3 x = dvec3(position), dv0 = dvec3(p0), ed1 = dvec3(e1), ed2 = dvec3(e2);
  if (e != tri_of_setup) {
    tri_of_setup = e;
    tri = setUpSphericalTriangle(normalize(dv0 - x), normalize(dv0 + ed1 - x), normalize(dv0 + ed2 - x));
  }
  dvec3 dir;
  bool spherical = tri.ok && sampleSphericalTriangle(tri, ur, v, dir);
  if (spherical) {
    // Where the sampled direction meets the triangle (Moller-Trumbore barycentrics).
    dvec3 s1 = cross(dir, ed2);
    double div = dot(s1, ed1);
    spherical = div != 0.0LF;
    if (spherical) {
      dvec3 sv = x - dv0;
      double b1 = clamp(dot(sv, s1) / div, 0.0LF, 1.0LF);
      double b2 = clamp(dot(dir, cross(sv, ed1)) / div, 0.0LF, 1.0LF);
      if (b1 + b2 > 1.0LF) {
        double sum = b1 + b2;
        b1 /= sum, b2 /= sum;
      }
      bary = vec2(float(b1), float(b2));
      cos_r = sphere ? 1.0 : float(dot(dvec3(normal), dir));
      cos_e = -float(dot(dvec3(ne), dir));
      weight = cos_r * float(tri.omega) * invPick(e);
    }
  }
  if (!spherical) {
    float su = float(sqrt(ur));
    bary = vec2(su * float(v), su * (1.0 - float(v)));  // uniform on the triangle
    vec3 w = p0 + bary.x * e1 + bary.y * e2 - position;
    float d2 = dot(w, w);
    if (!(d2 > 0.0)) return false;
    float inv_d = 1.0 / sqrt(d2);
    cos_r = sphere ? 1.0 : dot(normal, w) * inv_d;
    cos_e = -dot(ne, w) * inv_d;
    weight = cos_r * abs(cos_e) / d2 * invPdfArea(e);
  }
  if (emitters[e].normal_two_sided.w != 0.0) cos_e = abs(cos_e);
  if (cos_r <= 0.0 || cos_e <= 0.0) return false;  // behind the receiver or the emitter's back
  vec3 le = emitters[e].radiance.rgb;
  if (!(le.x > 0.0 || le.y > 0.0 || le.z > 0.0)) return false;
  vec3 q = p0 + bary.x * e1 + bary.y * e2;
  vec3 w = q - position;
  w_unit = normalize(w);
  // A grid cache has no surface to leave: step off the point along the ray itself.
  vec3 org = offsetOrigin(position, sphere ? w_unit : normal, w);
  vec3 rd = q - org;
  // Stop short of the emitter by the ray epsilon, so the emitter does not shadow itself.
  float tfar = max(0.0, 1.0 - u_eps / max(length(rd), 1e-30));
  traced = true;
  if (u_has_bvh != 0 && bvhOccluded(org, rd, 0.0, tfar)) return false;
  light = le * weight;
  layer = int(emitters[e].e2_layer.w);
  return true;
}

void main() {
  uint p = u_first + gl_WorkGroupID.x;
  if (p >= u_count) return;  // uniform over the workgroup
  uint lane = gl_LocalInvocationID.x;
  const int block = STRIDE;
  uint base = p * uint(u_layers * block);
  // Output entry k of each layer belongs to lane k % LANES (RGB irradiance: lanes 0..2): the one
  // lane that zeroes, adds to and scales it, so lanes never touch each other's entries.
  for (int k = int(lane); k < block; k += int(kLanes))
    for (int l = 0; l < u_layers; ++l) result[base + uint(l * block + k)] = 0.0;
  int m = u_emitters, n = u_samples;
  if (valid[p] == 0u || m == 0 || n <= 0) {
    if (lane == 0u) rays[p] = 0u;
    return;
  }
  vec3 position = positions[p].xyz;
#ifdef MODE_SH
  const bool sphere = true;
  vec3 normal = vec3(0.0);
#else
  const bool sphere = false;
  vec3 normal = normals[p].xyz;
#endif
  if (lane == 0u) traced_total = 0u;
  if (u_local != 0) {
    // Weight 0 only where the triangle cannot light the point: entirely below its horizon,
    // or the point behind a one-sided emitter's plane. Weights per lane, their running sum on
    // lane 0 in triangle order (the host's).
    for (int e = int(lane); e < m; e += int(kLanes)) {
      vec3 v0 = emitters[e].p0_inv_pick.xyz;
      vec3 v1 = v0 + emitters[e].e1_inv_pdf_area.xyz, v2 = v0 + emitters[e].e2_layer.xyz;
      bool below = !sphere && dot(normal, v0 - position) <= 0.0 && dot(normal, v1 - position) <= 0.0 &&
                   dot(normal, v2 - position) <= 0.0;
      bool behind = emitters[e].normal_two_sided.w == 0.0 && dot(emitters[e].normal_two_sided.xyz, position - v0) <= 0.0;
      double w = 0.0LF;
      if (!below && !behind) {
        dvec3 d = (dvec3(v0) + dvec3(v1) + dvec3(v2)) / 3.0LF - dvec3(position);
        w = pick[4 * e + 1] / max(dot(d, d), pick[4 * e + 2]);
      }
      l_weight[e] = w;
    }
    barrier();
    if (lane == 0u) {
      double total = 0.0LF;
      for (int e = 0; e < m; ++e) {
        l_inv_pick[e] = float(l_weight[e]);  // the weight, until the total is known (as on the host)
        total += l_weight[e];
        l_cdf[e] = total;
      }
      l_none = !(total > 0.0LF);
      if (!l_none) {
        for (int e = 0; e < m; ++e) {
          double w = double(l_inv_pick[e]);
          l_cdf[e] /= total;
          l_inv_pick[e] = w > 0.0LF ? float(total / w) : 0.0;
          l_inv_pdf_area[e] = w > 0.0LF ? float(pick[4 * e + 2] * total / w) : 0.0;
        }
        l_cdf[m - 1] = 1.0LF;
      }
    }
    barrier();
    if (l_none) {
      if (lane == 0u) rays[p] = 0u;
      return;
    }
  }
  double r0 = double(rotation[p].x), r1 = double(rotation[p].y);
  int tri_of_setup = m;
  SphTri tri;
  tri.ok = false;
  uint traced_here = 0u;
  for (int first = 0; first < n; first += int(kLanes)) {
    int i = first + int(lane);
    vec3 light = vec3(0.0), w_unit = vec3(0.0);
    int layer = -1;
    bool traced = false;
    if (i < n && !pointSample(i, n, m, position, normal, sphere, r0, r1, tri, tri_of_setup, light, layer, w_unit, traced))
      layer = -1;
    traced_here += traced ? 1u : 0u;
    round_light[lane] = vec4(light, float(layer));
    round_dir[lane] = w_unit;
    barrier();
    int count = min(int(kLanes), n - first);
    for (int k = int(lane); k < block; k += int(kLanes)) {
      for (int j = 0; j < count; ++j) {  // in sample order, as the host sums
        int l = int(round_light[j].w);
        if (l < 0) continue;
        uint o = base + uint(l * block + k);
#ifdef MODE_SH
        float y[NC];
        evalBasis(round_dir[j], y);
        int channel = k / NC;
        float c = (round_light[j].xyz * (1.0 / float(n)))[channel];
        result[o] += c * y[k % NC];
#else
        result[o] += round_light[j][k];
#endif
      }
    }
    barrier();
  }
#ifndef MODE_SH
  for (int k = int(lane); k < block; k += int(kLanes))
    for (int l = 0; l < u_layers; ++l) result[base + uint(l * block + k)] /= float(n);
#endif
  atomicAdd(traced_total, traced_here);
  barrier();
  if (lane == 0u) rays[p] = traced_total;
}
