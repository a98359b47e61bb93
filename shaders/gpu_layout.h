// One source of truth for the GPU relight's structs and binding indices, included both by
// C++ (gpu) and, through the build-time include expansion, by every GLSL shader here.
//
// The file is valid C++ and GLSL at once: in C++ the GLSL vector types are glm aliases and
// every struct gets a static_assert on its std430 size, so a field added on one side only
// fails the build instead of shifting data silently. Binding indices are per shader (each
// compute program binds at most 12 storage buffers, within the 16 per stage that NVIDIA and Mesa offer).
// Units: positions in metres, light intensities as in docs/units.md (candela, lux).
#ifdef __cplusplus
#pragma once
#include <cstdint>
#include <glm/glm.hpp>
namespace lightlink::gpu::glsl {
using vec4 = glm::vec4;
using ivec4 = glm::ivec4;
using mat4 = glm::mat4;
#define LL_CONST inline constexpr int
#else
#define LL_CONST const int
#endif

// Light kinds (GpuLight.kind_views.x).
LL_CONST kLightPoint = 0;
LL_CONST kLightSpot = 1;
LL_CONST kLightDirectional = 2;

// One KHR_lights_punctual light, world space.
struct GpuLight {
  vec4 position_range;     // xyz position (point/spot), w range in metres (0 = infinite)
  vec4 direction_cos_outer;  // xyz unit direction light travels, w cos(outer cone)
  vec4 color_intensity;    // rgb linear colour, w intensity (cd or lux)
  vec4 cos_inner_baked;    // x cos(inner cone), y 1 = baked into lightmap texels, zw unused
  ivec4 kind_views;        // x kind, y first shadow view, z view count (1 or 6), w unused
};

// One shadow-map view (a layer of the shadow map array): clip from world, and how to turn a
// world point into the stored depth metric. mode 0: distance to `eye` (point and spot
// lights); mode 1: distance along `eye_dir` from the plane through `eye` (directional).
struct GpuShadowView {
  mat4 clip_from_world;
  vec4 eye_mode;        // xyz eye, w mode
  vec4 dir_texel;       // xyz view direction (mode 1), w texel footprint: world size of one
                        // texel at unit distance (mode 0) or absolute (mode 1)
};

// One emitting triangle of the emitter sampler (core/relight/emitter_direct.h), world space;
// the power pick's doubles (cdf, w_t, A_t) go in a separate double array (kEmPick).
struct GpuEmitter {
  vec4 p0_inv_pick;       // xyz first vertex (m), w 1 / P(t) of the power pick
  vec4 e1_inv_pdf_area;   // xyz v1 - v0 (m), w 1 / pdf_A of the power pick (m^2)
  vec4 e2_layer;          // xyz v2 - v0 (m), w its layer (a small integer as a float)
  vec4 normal_two_sided;  // xyz unit geometric normal (glTF front), w 1 when double-sided
  vec4 radiance;          // rgb L_e, constant over the triangle (docs/units.md), w unused
};

// ---- bindings, per shader -------------------------------------------------------------
// shadow.vert / shadow.frag: uniforms only.
// light_points.comp: direct light at a set of points (surfels or lightmap caches).
LL_CONST kLpPositions = 0;   // vec4: xyz position, w unused
LL_CONST kLpNormals = 1;     // vec4: xyz unit normal
LL_CONST kLpLights = 2;      // GpuLight[]
LL_CONST kLpViews = 3;       // GpuShadowView[]
LL_CONST kLpValid = 4;       // uint per point (caches) — unused for surfels
LL_CONST kLpAlbedo = 5;      // vec4 per point (surfels)
LL_CONST kLpGiven = 6;       // vec4 given irradiance per point (parity runs)
LL_CONST kLpOut = 7;         // vec4: surfels rho * E, caches E
LL_CONST kLpOut2 = 8;        // vec4: surfels: copy of out (the bounce radiosity starts at b0)
LL_CONST kLpShadowUnit = 0;  // texture unit of the shadow map array
// leaf_flux.comp
LL_CONST kLfRadiosity = 0;   // vec4 per surfel
LL_CONST kLfArea = 1;        // float per surfel
LL_CONST kLfLeaf = 2;        // uint per surfel: its leaf node
LL_CONST kLfFlux = 3;        // vec4 per node
// pull.comp, radiosity.comp
LL_CONST kPuNodes = 0;       // ivec4 per node: left, right, floatBitsToInt(1 / area), 0
LL_CONST kPuFlux = 1;        // vec4 per node
LL_CONST kPuRad = 2;         // vec4 per node
// cache_light.comp
LL_CONST kClOffsets = 0;     // uint, caches + 1
LL_CONST kClNode = 1;        // uint per link
LL_CONST kClCoeffs = 2;      // packed fp16 pairs: projected coefficients / runtime (direction)
LL_CONST kClOmega = 3;       // packed fp16 pairs: runtime solid angle / pi
LL_CONST kClRad = 4;         // vec4 node radiosity
LL_CONST kClValid = 5;       // uint per cache
LL_CONST kClSkyVis = 6;      // float per cache x link coefficients
LL_CONST kClSkyMatrix = 7;   // float, 3 x nc x ncl
LL_CONST kClOut = 8;         // float per cache x 3 nc
// gather.comp
LL_CONST kGaBegin = 0;       // uint, surfels + 1
LL_CONST kGaCache = 1;       // uint per entry
LL_CONST kGaWeight = 2;      // float per entry
LL_CONST kGaFromGrid = 3;    // uint per surfel
LL_CONST kGaLightmapSh = 4;  // float
LL_CONST kGaGridSh = 6;      // float
LL_CONST kGaSurfel = 7;      // vec4 per surfel: xyz normal, w area
LL_CONST kGaAlbedoEmit = 8;  // vec4 x 2 per surfel: albedo, emitted radiosity
LL_CONST kGaB0 = 9;          // vec4 per surfel, rho * E direct
LL_CONST kGaB = 10;          // vec4 per surfel, read and written
LL_CONST kGaPartials = 11;   // vec2 per workgroup: added, total flux
LL_CONST kGatherGroup = 256; // surfels per workgroup = CPU chunk (same partial sums)
// fill.comp
LL_CONST kFiTarget = 0;
LL_CONST kFiBegin = 1;
LL_CONST kFiSource = 2;
LL_CONST kFiData = 3;        // float, stride per item
LL_CONST kFiValid = 4;       // uint per texel (dilation)
LL_CONST kFiDirect = 5;      // vec4 per texel (dilation)
// texels.comp
LL_CONST kTxCacheOfTexel = 0;
LL_CONST kTxHasValue = 1;
LL_CONST kTxCacheSh = 2;
LL_CONST kTxCacheDirect = 3;
LL_CONST kTxTexelSh = 4;
LL_CONST kTxTexelDirect = 5;
LL_CONST kTxTexelValid = 6;
// emitter_points.comp (+ common_bvh.glsl): the emitters' sampled light at a set of points.
LL_CONST kEmEmitters = 0;      // GpuEmitter[]
LL_CONST kEmPick = 1;          // double x 4 per emitter: cdf, w_t, A_t, 0
LL_CONST kEmPositions = 2;     // vec4 per point: xyz position
LL_CONST kEmNormals = 3;       // vec4 per point: xyz unit normal (irradiance mode)
LL_CONST kEmRotation = 4;      // vec2 per point: Cranley-Patterson rotation (r0, r1)
LL_CONST kEmValid = 5;         // uint per point: 0 gets zeros
LL_CONST kEmOut = 6;           // float: points x layers x stride
LL_CONST kEmRays = 7;          // uint per point: shadow rays traced
LL_CONST kEmBvhNodes = 8;      // vec4 x 2 per node (core/rt/flat_bvh.h)
LL_CONST kEmBvhTriangles = 9;  // vec4 x 3 per triangle
LL_CONST kEmLocalPickMax = 64;  // EmitterSampler::kLocalPickMax
// bandwidth.comp (benchmark)
LL_CONST kBwSource = 0;
LL_CONST kBwDest = 1;

#ifdef __cplusplus
static_assert(sizeof(GpuLight) == 80, "GpuLight must match its std430 layout");
static_assert(sizeof(GpuShadowView) == 96, "GpuShadowView must match its std430 layout");
static_assert(sizeof(GpuEmitter) == 80, "GpuEmitter must match its std430 layout");
#undef LL_CONST
}  // namespace lightlink::gpu::glsl
#endif
