// Light caches: the points where incident radiance is gathered as SH (seed 000 sec 4.4).
//
// Lightmap caches sit at the centres of lightmap texels covered by static triangles, on
// the triangle (conservative coverage: a texel the triangle only grazes still gets a
// cache, at the nearest point of the triangle, so bilinear lookups at chart edges never
// read an empty texel). Grid caches sit on a uniform grid for dynamic objects.
//
// Validity (seed 000 Fig. 7a): a cache whose rays mostly hit back faces is inside
// geometry or behind a wall. A lightmap cache whose texel centre fails moves to the valid
// point of its texel's own footprint (a stratified pattern over the texel square, on the
// triangles of its mesh that cover it) nearest the centre; it never leaves its texel, so a
// texel at a contact line keeps the light of that line. If no point of the footprint is
// valid, the texel is either covered by a one-sided sheet lying on it (most of the back faces
// it sees are nearer than a texel: a card or rug over a floor), and then it keeps its centre
// and its own, dark, value -- filling it from lit neighbours would make the sheet cast no
// shadow -- or it is inside geometry and, like such grid caches, is marked invalid. Invalid caches are never shown black: the FillPlan says
// from which valid neighbours each one is filled after relighting.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/aabb.h"
#include "core/common/progress.h"
#include "core/common/status.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::caches {

struct ValidityOptions {
  int rays = 64;                      // stratified directions per validity test
  float max_backface_fraction = 0.25f;  // above this, the cache is behind/inside geometry
  std::uint64_t seed = 0x11c4c4e5;
  // Polled for cancellation: a cancelled placement returns Code::kCancelled.
  const Progress* progress = nullptr;
};

struct LightmapCacheOptions {
  int resolution = 0;  // page width = height in texels (the unwrap's resolution)
  int pages = 1;       // pages stacked along v: the atlas is resolution x (pages * resolution)
  ValidityOptions validity;
  // A texel whose centre fails validity, or lies in a sealed pocket (every validity ray
  // stops within a texel), searches its footprint for a valid, open point (caches); false:
  // an invalid centre is invalid at once and filled from its neighbours, a sealed one kept
  // (the direct layer's texels, a quarter of a cache's size or less, where the search would
  // cost more than it gives).
  bool footprint_search = true;
};

// Structure of arrays, one entry per cache; caches are ordered by texel index (row-major),
// which is deterministic and keeps neighbouring texels close in memory.
struct LightmapCaches {
  int width = 0;
  int height = 0;
  std::vector<glm::vec3> position;   // world, metres (in the texel footprint, after validity)
  std::vector<glm::vec3> normal;     // world, unit: the hemisphere axis (geometric normal)
  std::vector<std::uint32_t> texel;  // y * width + x
  std::vector<std::uint32_t> mesh;   // Scene::meshes index
  std::vector<std::uint32_t> triangle;
  std::vector<std::uint8_t> valid;   // 1 = usable, 0 = behind/inside geometry
  // 1 = moved from the texel centre by the validity test; 2 = invalid because every valid
  // point of its footprint lies in a sealed pocket (a closed void no light reaches).
  std::vector<std::uint8_t> pushed;
  std::vector<std::int32_t> cache_of_texel;  // width*height, -1 where no triangle covers
  std::size_t degenerate_uv_triangles = 0;   // skipped: zero area in the lightmap

  std::size_t size() const { return position.size(); }
  std::size_t validCount() const;
};

// Places lightmap caches for every static mesh with a lightmap UV (uv1 in [0,1]).
// Needs the Accel of the same scene for the validity test.
Expected<LightmapCaches> placeLightmapCaches(const scene::Scene& scene, const rt::Accel& accel,
                                             const LightmapCacheOptions& options);

struct GridCacheOptions {
  float spacing_m = 0.0f;  // distance between grid points; 0 = derive from `resolution`
  int resolution = 16;     // points along the longest axis when spacing_m == 0
  Aabb volume;             // empty = the scene bounds
  ValidityOptions validity;
};

struct GridCaches {
  glm::vec3 origin{0.0f};  // world position of grid point (0,0,0)
  float spacing_m = 0.0f;
  glm::ivec3 dims{0};      // points per axis; index = (z * dims.y + y) * dims.x + x
  std::vector<glm::vec3> position;
  std::vector<std::uint8_t> valid;

  std::size_t size() const { return position.size(); }
  std::size_t validCount() const;
};

Expected<GridCaches> placeGridCaches(const scene::Scene& scene, const rt::Accel& accel,
                                     const GridCacheOptions& options);

// Fraction of `rays` stratified directions (hemisphere around `normal`, or the whole
// sphere when `normal` is zero) that hit a back face of a single-sided material.
// `contact_m` > 0: the back of a double-sided surface nearer than that counts too: the ray
// started on or behind that surface (a cache on the contact line of two double-sided walls,
// where half the hemisphere lies outside the room), which seeing a sheet's back from a real
// distance (a floor under a double-sided rug) is not.
float backfaceFraction(const scene::Scene& scene, const rt::Accel& accel, const glm::vec3& p,
                       const glm::vec3& normal, const ValidityOptions& options, float contact_m = 0.0f);

// What a validity probe saw: the fraction of its rays that hit a back face of a single-sided
// material, the fraction that hit one closer than `near_m` (unit-length directions), and the
// farthest any ray went (infinity when one escaped): a point whose rays all stop within a
// texel sits in a sealed pocket of the level, which no light reaches.
struct BackfaceProbe {
  float fraction = 0.0f;
  float near_fraction = 0.0f;
  float reach = 0.0f;
};
BackfaceProbe probeBackfaces(const scene::Scene& scene, const rt::Accel& accel, const glm::vec3& p,
                             const glm::vec3& normal, const ValidityOptions& options, float near_m,
                             float contact_m = 0.0f);

// How every cache that has no value of its own gets one after relighting: target caches
// are filled in order, each from the average of its sources (valid caches or targets
// filled earlier), so applying the plan front to back is one pass with no branches.
struct FillPlan {
  std::vector<std::uint32_t> target;         // cache (or texel, for dilation) to fill
  std::vector<std::uint32_t> source_begin;   // CSR offsets into source, size target+1
  std::vector<std::uint32_t> source;         // indices in the same space as target
  std::size_t unreachable = 0;               // targets with no valid cache anywhere near
};

// Invalid lightmap caches filled from valid caches in the 8 neighbouring texels,
// repeated outward until every invalid cache that touches a valid region is filled.
FillPlan planLightmapFill(const LightmapCaches& caches);
// Invalid grid caches filled from valid ones among their 26 neighbours, layer by layer.
FillPlan planGridFill(const GridCaches& grid);

// Texel dilation across seams and into gutters (seed 000 sec 3.2): for `passes` rounds,
// every texel without a cache takes the average of its 8 neighbours that have one (or
// were dilated in an earlier round). Indices are texels (y * width + x).
FillPlan planDilation(const LightmapCaches& caches, int passes);

}  // namespace lightlink::caches
