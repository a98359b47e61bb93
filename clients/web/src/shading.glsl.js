// The surface shader: the same lighting as `lightlink render` (clients/viewer/render.cpp),
// written out as linear radiance to a float target (alpha 1 = geometry) that tonemap.js
// exposes and tone maps. Static lightmapped meshes (LIGHTMAPPED): the four bilinear taps of
// the lightmap at uv1, each weighted by its validity, the SH evaluated at the shading
// normal, plus baked direct; other meshes, and lightmapped ones where no tap is valid: the
// grid's eight trilinear taps weighted by validity, plus the direct light of every light
// (unshadowed here: render traces a shadow ray). Then albedo / pi * E + emission, the albedo
// and emission being glTF's factors times their textures (baseColorTexture, emissiveTexture).

// Defines: LIGHTMAPPED, LIGHTMAP_BANDS, DIRECT_FINER, GRID_BANDS, LIGHT_COUNT (materials.js);
// ALBEDO_MAP / EMISSIVE_MAP with ALBEDO_UV / EMISSIVE_UV = vUv0 or vUv1 (the texCoord glTF names),
// and USES_UV0 / USES_UV1 for the uv sets the mesh's shader reads.
export const vertexShader = /* glsl */ `
in vec3 position;
in vec3 normal;
#ifdef USES_UV0
in vec2 uv;
out vec2 vUv0;
#endif
#ifdef USES_UV1
in vec2 uv1;
out vec2 vUv1;
#endif
uniform mat4 modelMatrix, viewMatrix, projectionMatrix;
out vec3 vWorldPosition, vWorldNormal;
void main() {
  vec4 world = modelMatrix * vec4(position, 1.0);
  vWorldPosition = world.xyz;
  vWorldNormal = transpose(inverse(mat3(modelMatrix))) * normal;  // normals under any scale
#ifdef USES_UV0
  vUv0 = uv;
#endif
#ifdef USES_UV1
  vUv1 = uv1;
#endif
  gl_Position = projectionMatrix * viewMatrix * world;
}
`;

export const fragmentShader = /* glsl */ `
precision highp float;
precision highp int;
precision highp sampler2D;
precision highp sampler2DArray;
precision highp sampler3D;

in vec3 vWorldPosition, vWorldNormal;
#ifdef USES_UV0
in vec2 vUv0;
#endif
#ifdef USES_UV1
in vec2 vUv1;
#endif
// glTF's baseColorTexture and emissiveTexture, sRGB textures: sampling returns linear values.
uniform sampler2D albedoMap, emissiveMap;
out vec4 fragColor;

uniform vec3 cameraPosition;
uniform vec3 albedo;      // linear base colour
uniform vec3 emission;    // emissive factor * strength (radiance, cd/m^2)

// The lightmap: shMap layer i = SH coefficient i (L1: 4, L2: 9), or layer 0 = irradiance.exr
// for an L0 bake (LIGHTMAP_BANDS 0, whose texels all count).
uniform sampler2DArray shMap;
uniform sampler2D validMap;
uniform ivec2 lightmapSize;
uniform sampler2DArray directMap;      // layer 0: direct.exr
uniform sampler2D directValidMap;      // DIRECT_FINER only
uniform ivec2 directSize;

// The grid: coefficient k of point (x, y, z) at texel (x, y, z + k * dims.z), A = validity.
uniform sampler3D gridMap;
uniform ivec3 gridDims;
uniform vec3 gridOrigin;
uniform float gridSpacing;

// Punctual lights (KHR_lights_punctual): type 0 point, 1 spot, 2 directional.
#if LIGHT_COUNT > 0
uniform int lightType[LIGHT_COUNT];
uniform vec3 lightPosition[LIGHT_COUNT], lightDirection[LIGHT_COUNT], lightIntensity[LIGHT_COUNT];
uniform float lightRange[LIGHT_COUNT], lightCosOuter[LIGHT_COUNT], lightCosInner[LIGHT_COUNT];
#endif

// docs/sh.md: E(n) = max(0, sum A_l L_lm Y_lm(n)), A = pi, 2 pi / 3, pi / 4; real orthonormal
// SH, no Condon-Shortley phase, index l*l + l + m, band 1 = (y, z, x).
vec3 shIrradiance(vec3 c[9], int bands, vec3 n) {
  const float A0 = 3.14159265, A1 = 2.09439510, A2 = 0.78539816;
  vec3 e = A0 * 0.28209479 * c[0];
  if (bands >= 2) e += A1 * 0.48860251 * (c[1] * n.y + c[2] * n.z + c[3] * n.x);
  if (bands >= 3)
    e += A2 * (1.09254843 * (c[4] * n.x * n.y + c[5] * n.y * n.z + c[7] * n.x * n.z)
               + 0.31539157 * c[6] * (3.0 * n.z * n.z - 1.0)
               + 0.54627421 * c[8] * (n.x * n.x - n.y * n.y));
  return max(e, vec3(0.0));
}

// The four bilinear taps of a size.x x size.y texel image at uv: texel (x, y) covers
// [x, x+1) x [y, y+1) of uv * size; taps beyond an edge clamp to it (render's bilinearTaps).
void bilinearTaps(vec2 uv, ivec2 size, out ivec2 texel[4], out float weight[4]) {
  vec2 f = clamp(uv * vec2(size) - 0.5, vec2(-1.0), vec2(size));
  vec2 f0 = floor(f), a = f - f0;
  ivec2 i0 = ivec2(f0);
  for (int k = 0; k < 4; ++k) {
    ivec2 d = ivec2(k & 1, k >> 1);
    texel[k] = clamp(i0 + d, ivec2(0), size - 1);
    weight[k] = (d.x == 1 ? a.x : 1.0 - a.x) * (d.y == 1 ? a.y : 1.0 - a.y);
  }
}

#ifdef LIGHTMAPPED
// Indirect (SH at n) + baked direct at uv; false where no valid texel surrounds uv.
bool sampleLightmap(vec2 uv, vec3 n, out vec3 e) {
  ivec2 texel[4];
  float weight[4];
  bilinearTaps(uv, lightmapSize, texel, weight);
  vec3 c[9];
  for (int i = 0; i < 9; ++i) c[i] = vec3(0.0);
  vec3 direct = vec3(0.0);
  float wsum = 0.0;
  for (int k = 0; k < 4; ++k) {
#if LIGHTMAP_BANDS > 0
    float w = weight[k] * texelFetch(validMap, texel[k], 0).r;
#else
    float w = weight[k];
#endif
    if (w <= 0.0) continue;
    for (int i = 0; i < LIGHTMAP_BANDS * LIGHTMAP_BANDS; ++i) c[i] += w * texelFetch(shMap, ivec3(texel[k], i), 0).rgb;
#if LIGHTMAP_BANDS == 0
    c[0] += w * texelFetch(shMap, ivec3(texel[k], 0), 0).rgb;
#elif !defined(DIRECT_FINER)
    direct += w * texelFetch(directMap, ivec3(texel[k], 0), 0).rgb;
#endif
    wsum += w;
  }
  if (wsum <= 0.0) return false;
#if LIGHTMAP_BANDS == 0
  e = c[0] / wsum;  // the irradiance map holds E for the surface's normal, direct included
#else
  // SH interpolates linearly: evaluating the weighted mean equals the mean of evaluations.
  for (int i = 0; i < 9; ++i) c[i] /= wsum;
#ifdef DIRECT_FINER
  bilinearTaps(uv, directSize, texel, weight);
  float dsum = 0.0;
  for (int k = 0; k < 4; ++k) {
    float w = weight[k] * texelFetch(directValidMap, texel[k], 0).r;
    direct += w * texelFetch(directMap, ivec3(texel[k], 0), 0).rgb;
    dsum += w;
  }
  if (dsum > 0.0) direct /= dsum;
#else
  direct /= wsum;
#endif
  e = shIrradiance(c, LIGHTMAP_BANDS, n) + direct;
#endif
  return true;
}
#endif

// Indirect irradiance from the grid at world position p for normal n (render's sampleGrid).
bool sampleGrid(vec3 p, vec3 n, out vec3 e) {
#if GRID_BANDS > 0
  vec3 g = clamp((p - gridOrigin) / gridSpacing, vec3(0.0), vec3(gridDims - 1));
  ivec3 i0 = clamp(ivec3(floor(g)), ivec3(0), gridDims - 1);
  vec3 a = clamp(g - vec3(i0), 0.0, 1.0);
  vec3 c[9];
  for (int i = 0; i < 9; ++i) c[i] = vec3(0.0);
  float wsum = 0.0;
  for (int corner = 0; corner < 8; ++corner) {
    ivec3 o = ivec3(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
    ivec3 i = min(i0 + o, gridDims - 1);
    float w = (o.x == 1 ? a.x : 1.0 - a.x) * (o.y == 1 ? a.y : 1.0 - a.y) * (o.z == 1 ? a.z : 1.0 - a.z);
    w *= texelFetch(gridMap, i, 0).a;
    if (w <= 0.0) continue;
    for (int k = 0; k < GRID_BANDS * GRID_BANDS; ++k) c[k] += w * texelFetch(gridMap, i + ivec3(0, 0, k * gridDims.z), 0).rgb;
    wsum += w;
  }
  if (wsum <= 0.0) return false;
  for (int k = 0; k < 9; ++k) c[k] /= wsum;
  e = shIrradiance(c, GRID_BANDS, n);
  return true;
#else
  return false;
#endif
}

// Direct irradiance of every light at p (core/scene/light_eval.cpp: cd and lux, inverse
// square, glTF's smooth range window and squared spot falloff), without shadows.
vec3 directLights(vec3 p, vec3 n) {
  vec3 e = vec3(0.0);
#if LIGHT_COUNT > 0
  for (int i = 0; i < LIGHT_COUNT; ++i) {
    if (lightType[i] == 2) { e += lightIntensity[i] * max(dot(n, -lightDirection[i]), 0.0); continue; }
    vec3 toLight = lightPosition[i] - p;
    float d2 = dot(toLight, toLight);
    if (!(d2 > 0.0)) continue;
    float d = sqrt(d2);
    vec3 wi = toLight / d;
    float cosTheta = dot(n, wi);
    if (cosTheta <= 0.0) continue;
    float falloff = 1.0;
    if (lightType[i] == 1) {
      float cosAngle = dot(lightDirection[i], -wi);
      if (lightCosInner[i] <= lightCosOuter[i]) falloff = cosAngle >= lightCosOuter[i] ? 1.0 : 0.0;
      else { float t = clamp((cosAngle - lightCosOuter[i]) / (lightCosInner[i] - lightCosOuter[i]), 0.0, 1.0); falloff = t * t; }
    }
    if (lightRange[i] > 0.0) { float r = d / lightRange[i]; float w = clamp(1.0 - r * r * r * r, 0.0, 1.0); falloff *= w * w; }
    e += lightIntensity[i] * (cosTheta / d2 * falloff);
  }
#endif
  return e;
}

void main() {
  vec3 ray = vWorldPosition - cameraPosition;
  // Shade the side the camera sees (render flips both normals the same way).
  vec3 ng = normalize(cross(dFdx(vWorldPosition), dFdy(vWorldPosition)));
  if (dot(ng, ray) > 0.0) ng = -ng;
  vec3 n = normalize(vWorldNormal);
  if (dot(n, ng) < 0.0) n = -n;
  vec3 e = vec3(0.0);
  bool fromLightmap = false;
#ifdef LIGHTMAPPED
  fromLightmap = sampleLightmap(vUv1, n, e);
#endif
  if (!fromLightmap) {
    sampleGrid(vWorldPosition, n, e);
    e += directLights(vWorldPosition, n);  // every light is baked: lightmaps hold their direct
  }
  vec3 base = albedo, glow = emission;
#ifdef ALBEDO_MAP
  base *= texture(albedoMap, ALBEDO_UV).rgb;
#endif
#ifdef EMISSIVE_MAP
  glow *= texture(emissiveMap, EMISSIVE_UV).rgb;
#endif
  fragColor = vec4(base / 3.14159265 * e + glow, 1.0);
}
`;
