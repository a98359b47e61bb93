// Accel: the ray-tracing acceleration structure every lightlink stage traces against.
//
// core/rt is a narrow facade over Embree 3: one Accel owns one RTCDevice and one committed
// RTCScene (RAII, released in the right order), built once from a scene::Scene and then
// queried read-only from any number of threads. Embree never appears in this header, so
// callers neither include nor link it; Embree's error callback is routed into our Status
// (returned from build(), later ones via deviceStatus()).
//
// Conventions shared by every query:
//  - Rays are in world space (metres). `dir` need not be unit length: t, tnear and tfar are
//    in units of |dir| (Embree's contract), so hit point = origin + t * dir.
//  - Every triangle is double-sided for hits. Hit::ng is the unnormalised geometric normal
//    cross(v1 - v0, v2 - v0) of the triangle as stored (glTF counter-clockwise = front);
//    a hit with dot(ng, dir) > 0 struck the back face. Which side matters is the caller's
//    decision, not the BVH's.
//  - Hit::mesh indexes Scene::meshes of the scene the Accel was built from, Hit::triangle
//    indexes that mesh's triangles (indices[3*triangle .. 3*triangle+2]); u, v are Embree's
//    barycentrics: p = (1-u-v)*v0 + u*v1 + v*v2.
//  - Alpha cut-outs (materials with alphaMode MASK, or BLEND traced as a mask at 0.5) are
//    holes for every query: a hit where the base colour's alpha is below the threshold is
//    skipped and the ray goes on. A mesh with cast_shadows == false is skipped by occluded()
//    (shadow rays) only; intersect() still hits it (core/rt/cutout.h).
//  - The Accel copies the geometry it needs; the Scene may be destroyed after build().
//
// Epsilons are relative to the size of the built geometry (DESIGN.md sec. 6: mm- and
// km-scale scenes must both work): see rayEpsilon() and offsetOrigin().
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>

#include <glm/glm.hpp>

#include "core/common/aabb.h"
#include "core/common/status.h"
#include "core/scene/scene.h"

namespace lightlink::rt {

inline constexpr std::uint32_t kNoHit = std::numeric_limits<std::uint32_t>::max();

struct Ray {
  glm::vec3 origin{0.0f};           // world space, metres
  float tnear = 0.0f;               // hits with t < tnear are ignored (units of |dir|)
  glm::vec3 dir{0.0f, 0.0f, 1.0f};  // world space; any non-zero length
  float tfar = std::numeric_limits<float>::infinity();  // hits with t > tfar are ignored
};

// True when a ray along ray_dir strikes the side opposite to the geometric normal ng (the
// back face of the triangle). Hit::backFacing, and the same test on a fan's hit arrays.
inline bool backFacing(const glm::vec3& ng, const glm::vec3& ray_dir) { return glm::dot(ng, ray_dir) > 0.0f; }

struct Hit {
  std::uint32_t mesh = kNoHit;  // index into Scene::meshes, kNoHit for a miss
  std::uint32_t triangle = 0;   // index into that mesh's triangles (indices / 3)
  float u = 0.0f;               // barycentrics, p = (1-u-v)*v0 + u*v1 + v*v2
  float v = 0.0f;
  float t = std::numeric_limits<float>::infinity();  // units of |ray.dir|
  glm::vec3 ng{0.0f};                                // unnormalised geometric normal, world space

  bool hit() const { return mesh != kNoHit; }
  // True when the ray struck the side opposite to ng (the back face of the triangle).
  bool backFacing(const glm::vec3& ray_dir) const { return rt::backFacing(ng, ray_dir); }
};

struct AccelOptions {
  // Dynamic meshes (MeshInstance::is_static == false) move at runtime, so nothing baked may
  // depend on them; by default they are left out of the BVH.
  bool static_only = true;
  // kHigh: SAH builder with spatial splits (slower build, fastest traversal) for the
  // precompute, where one build serves billions of rays. kFast: Embree's medium-quality
  // builder, for tools that trace a few rays once.
  enum class Quality { kFast, kHigh };
  Quality quality = Quality::kHigh;
  // Embree's robust (watertight) triangle test: a ray through a shared edge or vertex always
  // hits one of the triangles. Without it, rays leak through edges of small geometry far
  // from the origin (tests/rt AccelOffset.MillimetreBoxFarFromOrigin: ~1500 of 12000 rays
  // escape), which would read as sky visibility from inside closed rooms. It costs ~10-20 % of
  // closest-hit throughput (docs/results.md); off only to measure that.
  bool robust = true;
};

// Hint for batched queries; hits are the same either way (within float rounding of t, u,
// v), only speed differs.
// kCoherent traces 16-ray packets (rtcIntersect16): rays i..i+15 should be neighbours
// (camera pixels of one tile, a cache's stratified directions). kIncoherent hands groups of
// rays to Embree's stream API (rtcIntersect1M), which traces them one by one. Measured with
// bench/rt/ray_bench (docs/results.md, 115k-triangle city, one thread, closest hit): camera
// rays 21.7 Mrays/s as packets vs 3.3 single and 4.1 as a stream; diffuse rays 0.6 as
// packets (unrelated rays visit the union of their paths) vs 2.5 single and 2.7 as a stream.
enum class Coherence { kIncoherent, kCoherent };

// Rays that all leave one point (a fan), directions as three arrays: what link generation
// traces per cache. Same rays as Ray{origin, tnear, {dir_x[i], dir_y[i], dir_z[i]}, tfar}.
struct RayFan {
  glm::vec3 origin{0.0f};
  float tnear = 0.0f;
  float tfar = std::numeric_limits<float>::infinity();
  const float* dir_x = nullptr;
  const float* dir_y = nullptr;
  const float* dir_z = nullptr;
  std::size_t count = 0;
};

// A fan's hits as arrays of fan.count each (Hit's fields, one array per field). For a miss,
// mesh is kNoHit, t is the fan's tfar and the other fields are 0.
struct HitArrays {
  std::uint32_t* mesh = nullptr;
  std::uint32_t* triangle = nullptr;
  float* u = nullptr;
  float* v = nullptr;
  float* t = nullptr;
  float* ng_x = nullptr;
  float* ng_y = nullptr;
  float* ng_z = nullptr;
};

class Accel {
 public:
  // Fails with kInvalidInput when no triangle would be traced (empty scene, or only
  // dynamic meshes with static_only), on an index outside its mesh's positions or a
  // non-finite position (naming the mesh); with kInternal when Embree reports an error.
  static Expected<Accel> build(const scene::Scene& scene, const AccelOptions& options = {});

  Accel(Accel&&) noexcept;
  Accel& operator=(Accel&&) noexcept;
  Accel(const Accel&) = delete;
  Accel& operator=(const Accel&) = delete;
  ~Accel();

  // Closest hit along the ray, or a Hit with mesh == kNoHit.
  Hit intersect(const Ray& ray) const;
  // True when anything lies on the ray within [tnear, tfar].
  bool occluded(const Ray& ray) const;

  // Batched forms: same results as the single-ray calls, element by element. They run on
  // the calling thread and are safe to call concurrently from many TBB tasks; split large
  // batches across tasks yourself (chunks of a multiple of 16 rays keep packets full).
  // hits.size() / occluded.size() must equal rays.size(); occluded[i] = 1 when blocked.
  void intersect(std::span<const Ray> rays, std::span<Hit> hits,
                 Coherence coherence = Coherence::kIncoherent) const;
  void occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                Coherence coherence = Coherence::kIncoherent) const;

  // A fan in 16-ray packets (rtcIntersect16, coherent): the hits intersect() gives for the
  // same rays with Coherence::kCoherent, bit for bit. Rays and hits stay in arrays, as
  // Embree's packets hold them, so there is no conversion to and from Ray and Hit per ray
  // (precompute_bench traces the same rays both ways: this is the faster, most on open
  // scenes).
  void intersectFan(const RayFan& fan, const HitArrays& hits) const;

  // Bounds diagonal of the geometry in the BVH (metres); the yardstick for epsilons.
  float sceneScale() const;
  // 1e-5 * sceneScale(): Embree's hit distances carry an error of a few float ulps of the
  // vertex coordinates (~1.2e-7 relative each); 1e-5 is ~100 of those, so a ray leaving a
  // surface by this much does not find the surface again, yet it is 0.1 mm in a 10 m room,
  // far below any feature that matters for lighting.
  float rayEpsilon() const;
  // A ray origin for leaving the surface at p (geometric normal n_geom, either side) in
  // direction dir: p pushed along +n or -n, whichever side dir points to, by rayEpsilon()
  // plus 16 ulps of the largest coordinate of p. The second term covers geometry far from
  // the origin, where float spacing (not scene size) bounds the error of p itself, e.g. a
  // mm-scale prop placed 1 km away. Use with tnear = 0.
  glm::vec3 offsetOrigin(const glm::vec3& p, const glm::vec3& n_geom, const glm::vec3& dir) const;

  // Triangles in the BVH (dynamic meshes excluded when static_only).
  std::size_t triangleCount() const;
  // Bounds of the geometry in the BVH, world space.
  const Aabb& bounds() const;
  // OK, or the first error Embree reported after build() (queries cannot return a Status;
  // an error there is a bug on our side, e.g. an invalid argument).
  Status deviceStatus() const;

 private:
  struct Impl;
  explicit Accel(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace lightlink::rt
