#include "core/rt/accel.h"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <iterator>
#include <mutex>
#include <utility>
#include <vector>

#include <embree3/rtcore.h>

#include "core/rt/cutout.h"

#include "core/common/check.h"
#include "core/common/isa.h"

namespace lightlink::rt {
namespace {

// ---- RAII for Embree's reference-counted handles -------------------------------------

struct DeviceRelease {
  void operator()(RTCDeviceTy* d) const { rtcReleaseDevice(d); }
};
struct SceneRelease {
  void operator()(RTCSceneTy* s) const { rtcReleaseScene(s); }
};
struct GeometryRelease {
  void operator()(RTCGeometryTy* g) const { rtcReleaseGeometry(g); }
};
using DeviceHandle = std::unique_ptr<RTCDeviceTy, DeviceRelease>;
using SceneHandle = std::unique_ptr<RTCSceneTy, SceneRelease>;
using GeometryHandle = std::unique_ptr<RTCGeometryTy, GeometryRelease>;

const char* rtcErrorName(RTCError code) {
  switch (code) {
    case RTC_ERROR_NONE: return "none";
    case RTC_ERROR_UNKNOWN: return "unknown";
    case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
    case RTC_ERROR_CANCELLED: return "cancelled";
  }
  return "unrecognised error code";
}

// Receives Embree's error callback. Embree may call it from its build threads, hence the
// mutex; the first error is kept because later ones are usually consequences of it.
class ErrorSink {
 public:
  static void callback(void* user, RTCError code, const char* message) {
    static_cast<ErrorSink*>(user)->record(code, message);
  }
  void record(RTCError code, const char* message) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (first_.isOk())
      first_ =
          internalError("Embree error ({}): {}", rtcErrorName(code), message ? message : "(no message)");
  }
  Status first() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return first_;
  }
  // For a call that returned null: the error Embree reported, or a generic one if the
  // callback was not invoked (never an OK status, which Expected must not hold).
  Status failure(const char* call) const {
    Status status = first();
    return status.isOk() ? internalError("Embree: {} failed without reporting an error", call) : status;
  }

 private:
  mutable std::mutex mutex_;
  Status first_;
};

// Embree's hit record -> ours. geom_to_mesh is dense: geometry ids are attached 0, 1, 2...
// (its last entry, kNoHit, stands for a miss).
inline void fillHit(Hit& out, unsigned geom_id, unsigned prim_id, float u, float v, float t, float ngx,
                    float ngy, float ngz, const std::vector<std::uint32_t>& geom_to_mesh) {
  if (geom_id == RTC_INVALID_GEOMETRY_ID) {
    out = Hit{};
    return;
  }
  out.mesh = geom_to_mesh[geom_id];
  out.triangle = prim_id;
  out.u = u;
  out.v = v;
  out.t = t;
  // Embree's triangle Ng is cross(v1 - v0, v2 - v0), the glTF front-face convention
  // (counter-clockwise); tests/rt pins this down.
  out.ng = glm::vec3(ngx, ngy, ngz);
}

inline void fillRay(RTCRay& r, const Ray& ray) {
  r.org_x = ray.origin.x;
  r.org_y = ray.origin.y;
  r.org_z = ray.origin.z;
  r.tnear = ray.tnear;
  r.dir_x = ray.dir.x;
  r.dir_y = ray.dir.y;
  r.dir_z = ray.dir.z;
  r.time = 0.0f;
  r.tfar = ray.tfar;
  r.mask = 0xFFFFFFFFu;
  r.id = 0;
  r.flags = 0;
}

// Fills lanes [0, count) of a 16-wide SoA ray from rays[0 .. count); the remaining lanes
// get a harmless empty ray and valid = 0 so Embree skips them.
template <typename Ray16>
inline void fillRay16(Ray16& r, std::array<int, 16>& valid, const Ray* rays, std::size_t count) {
  for (std::size_t j = 0; j < 16; ++j) {
    const bool active = j < count;
    valid[j] = active ? -1 : 0;
    const Ray ray = active ? rays[j] : Ray{glm::vec3(0.0f), 0.0f, glm::vec3(0.0f, 0.0f, 1.0f), -1.0f};
    r.org_x[j] = ray.origin.x;
    r.org_y[j] = ray.origin.y;
    r.org_z[j] = ray.origin.z;
    r.tnear[j] = ray.tnear;
    r.dir_x[j] = ray.dir.x;
    r.dir_y[j] = ray.dir.y;
    r.dir_z[j] = ray.dir.z;
    r.time[j] = 0.0f;
    r.tfar[j] = ray.tfar;
    r.mask[j] = 0xFFFFFFFFu;
    r.id[j] = static_cast<unsigned>(j);
    r.flags[j] = 0;
  }
}

RTCIntersectContext makeContext(Coherence coherence) {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = coherence == Coherence::kCoherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                                                    : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  return context;
}

// Incoherent batches go through rtcIntersect1M / rtcOccluded1M in groups of this many
// rays, converted on the stack (80 bytes per RTCRayHit: 5 KiB, stays in L1).
constexpr std::size_t kStreamGroup = 64;

// offsetOrigin's second term, in float ulps of the largest coordinate of p. The hit
// distance Embree computes for a ray starting near a plane is off by a few ulps of the
// origin's coordinates (the origin - vertex differences round), and a p the caller
// interpolated from barycentrics carries a few more; 16 covers both with margin while
// staying ~2e-6 relative, so props of a few mm still work ten metres from the origin.
constexpr float kOffsetUlps = 16.0f;

// Embree filter functions (called for every candidate hit of a mesh that has a SurfaceFilter;
// valid[i] = 0 rejects lane i's hit and the traversal goes on).
void cutoutFilter(const RTCFilterFunctionNArguments* args) {
  const auto* f = static_cast<const SurfaceFilter*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    if (!f->opaqueAt(RTCHitN_primID(args->hit, args->N, i), RTCHitN_u(args->hit, args->N, i),
                     RTCHitN_v(args->hit, args->N, i)))
      args->valid[i] = 0;
  }
}

void occlusionFilter(const RTCFilterFunctionNArguments* args) {
  const auto* f = static_cast<const SurfaceFilter*>(args->geometryUserPtr);
  if (!f->cast_shadows) {
    for (unsigned i = 0; i < args->N; ++i) args->valid[i] = 0;
    return;
  }
  cutoutFilter(args);
}

}  // namespace

struct Accel::Impl {
  // Declared first so it is destroyed last: the device may report errors while releasing.
  ErrorSink errors;
  DeviceHandle device;
  SceneHandle scene;  // released before the device (reverse declaration order)
  // Mesh of each geometry id, then one more entry, kNoHit: indexed by min(geomID,
  // geometries()), a miss reads kNoHit (the fan's copies look up 16 lanes without a branch).
  std::vector<std::uint32_t> geom_to_mesh;
  std::uint32_t geometries() const { return static_cast<std::uint32_t>(geom_to_mesh.size() - 1); }
  Aabb bounds;
  float scale = 0.0f;
  float epsilon = 0.0f;
  std::size_t triangles = 0;
  // Per filtered geometry, what its filter functions read (Embree holds raw pointers).
  std::vector<std::unique_ptr<SurfaceFilter>> filters;

  void intersectPackets(std::span<const Ray> rays, std::span<Hit> hits, RTCIntersectContext& ctx) const;
  void intersectStream(std::span<const Ray> rays, std::span<Hit> hits, RTCIntersectContext& ctx) const;
  void occludedPackets(std::span<const Ray> rays, std::span<std::uint8_t> out,
                       RTCIntersectContext& ctx) const;
  void occludedStream(std::span<const Ray> rays, std::span<std::uint8_t> out,
                      RTCIntersectContext& ctx) const;
};

Accel::Accel(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Accel::Accel(Accel&&) noexcept = default;
Accel& Accel::operator=(Accel&&) noexcept = default;
Accel::~Accel() = default;

Expected<Accel> Accel::build(const scene::Scene& scene, const AccelOptions& options) {
  // Validate before touching Embree: an out-of-range index would make Embree read out of
  // bounds, and non-finite vertices would be silently dropped by its builder.
  Aabb bounds;
  std::size_t triangles = 0;
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    if (options.static_only && !mesh.is_static) continue;
    if (mesh.indices.size() % 3 != 0)
      return invalidInput("mesh {} '{}': {} indices is not a multiple of 3", m, mesh.name,
                          mesh.indices.size());
    const std::size_t vertex_count = mesh.positions.size();
    for (std::size_t k = 0; k < mesh.indices.size(); ++k) {
      const std::uint32_t index = mesh.indices[k];
      if (index >= vertex_count)
        return invalidInput("mesh {} '{}': index {} (triangle {}) is {}, but there are {} positions", m,
                            mesh.name, k, k / 3, index, vertex_count);
      const glm::vec3& p = mesh.positions[index];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        return invalidInput("mesh {} '{}': position {} is not finite ({}, {}, {})", m, mesh.name, index,
                            p.x, p.y, p.z);
      bounds.grow(p);
    }
    triangles += mesh.triangleCount();
  }
  if (triangles == 0)
    return invalidInput("nothing to trace: the scene has no {}triangles ({} meshes)",
                        options.static_only ? "static " : "", scene.meshes.size());
  const float scale = bounds.diagonal();
  if (!(scale > 0.0f) || !std::isfinite(scale))
    return invalidInput("the {} triangles to trace have zero or non-finite extent ({})", triangles,
                        scale);

  auto impl = std::make_unique<Impl>();
  impl->device.reset(rtcNewDevice(nullptr));
  if (!impl->device)
    return internalError("Embree: rtcNewDevice failed ({})", rtcErrorName(rtcGetDeviceError(nullptr)));
  RTCDevice device = impl->device.get();
  rtcSetDeviceErrorFunction(device, &ErrorSink::callback, &impl->errors);
  // Double-sided hits are part of our contract; a build of Embree with backface culling
  // compiled in would silently lose half the hits.
  if (rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED) != 0)
    return unsupported("this Embree was built with backface culling; lightlink needs double-sided hits");

  const RTCBuildQuality quality = options.quality == AccelOptions::Quality::kHigh
                                      ? RTC_BUILD_QUALITY_HIGH
                                      : RTC_BUILD_QUALITY_MEDIUM;
  impl->scene.reset(rtcNewScene(device));
  if (!impl->scene) return impl->errors.failure("rtcNewScene");
  RTCScene rtc_scene = impl->scene.get();
  rtcSetSceneBuildQuality(rtc_scene, quality);
  // See AccelOptions::robust: watertight hits, so closed rooms do not leak.
  rtcSetSceneFlags(rtc_scene, options.robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);

  std::vector<std::shared_ptr<const AlphaPlane>> alpha_planes;  // one copy per texture
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    if (options.static_only && !mesh.is_static) continue;
    const std::size_t tri_count = mesh.triangleCount();
    if (tri_count == 0) continue;

    GeometryHandle geometry(rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE));
    if (!geometry) return impl->errors.failure("rtcNewGeometry");
    // Copies, not shared buffers: Embree reads vertices with 16-byte loads past the last
    // element, which a std::vector<glm::vec3> does not guarantee to be addressable;
    // rtcSetNewGeometryBuffer pads for that, and the Scene can be freed after build().
    auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(geometry.get(), RTC_BUFFER_TYPE_VERTEX,
                                                                 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                                 mesh.positions.size()));
    auto* indices = static_cast<std::uint32_t*>(
        rtcSetNewGeometryBuffer(geometry.get(), RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(std::uint32_t), tri_count));
    if (!vertices || !indices) return impl->errors.failure("rtcSetNewGeometryBuffer");
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
      vertices[3 * i + 0] = mesh.positions[i].x;
      vertices[3 * i + 1] = mesh.positions[i].y;
      vertices[3 * i + 2] = mesh.positions[i].z;
    }
    std::copy(mesh.indices.begin(), mesh.indices.end(), indices);
    if (auto filter = SurfaceFilter::forMesh(scene, mesh, alpha_planes)) {
      rtcSetGeometryUserData(geometry.get(), filter.get());
      if (filter->cutout) rtcSetGeometryIntersectFilterFunction(geometry.get(), &cutoutFilter);
      rtcSetGeometryOccludedFilterFunction(geometry.get(), &occlusionFilter);
      impl->filters.push_back(std::move(filter));
    }
    rtcSetGeometryBuildQuality(geometry.get(), quality);
    rtcCommitGeometry(geometry.get());
    const unsigned geom_id = rtcAttachGeometry(rtc_scene, geometry.get());
    // The scene now holds its own reference; `geometry` drops ours at scope end.
    if (geom_id == RTC_INVALID_GEOMETRY_ID) return impl->errors.failure("rtcAttachGeometry");
    LL_CHECK_EQ(static_cast<std::size_t>(geom_id), impl->geom_to_mesh.size());
    impl->geom_to_mesh.push_back(static_cast<std::uint32_t>(m));
  }
  rtcCommitScene(rtc_scene);
  if (Status status = impl->errors.first(); !status.isOk()) return status;
  impl->geom_to_mesh.push_back(kNoHit);

  impl->bounds = bounds;
  impl->scale = scale;
  impl->epsilon = 1e-5f * scale;
  impl->triangles = triangles;
  return Accel(std::move(impl));
}

// ---- single rays -----------------------------------------------------------------------

Hit Accel::intersect(const Ray& ray) const {
  RTCIntersectContext context = makeContext(Coherence::kIncoherent);
  RTCRayHit rh;
  fillRay(rh.ray, ray);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene.get(), &context, &rh);
  Hit hit;
  fillHit(hit, rh.hit.geomID, rh.hit.primID, rh.hit.u, rh.hit.v, rh.ray.tfar, rh.hit.Ng_x, rh.hit.Ng_y,
          rh.hit.Ng_z, impl_->geom_to_mesh);
  return hit;
}

bool Accel::occluded(const Ray& ray) const {
  RTCIntersectContext context = makeContext(Coherence::kIncoherent);
  RTCRay r;
  fillRay(r, ray);
  rtcOccluded1(impl_->scene.get(), &context, &r);
  // Embree marks an occluded ray by setting tfar to -inf.
  return r.tfar < 0.0f && std::isinf(r.tfar);
}

// ---- batches ---------------------------------------------------------------------------

void Accel::Impl::intersectPackets(std::span<const Ray> rays, std::span<Hit> hits,
                                   RTCIntersectContext& ctx) const {
  alignas(64) RTCRayHit16 rh;
  alignas(64) std::array<int, 16> valid;
  for (std::size_t base = 0; base < rays.size(); base += 16) {
    const std::size_t count = std::min<std::size_t>(16, rays.size() - base);
    fillRay16(rh.ray, valid, rays.data() + base, count);
    for (std::size_t j = 0; j < 16; ++j) {
      rh.hit.geomID[j] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][j] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcIntersect16(valid.data(), scene.get(), &ctx, &rh);
    for (std::size_t j = 0; j < count; ++j)
      fillHit(hits[base + j], rh.hit.geomID[j], rh.hit.primID[j], rh.hit.u[j], rh.hit.v[j],
              rh.ray.tfar[j], rh.hit.Ng_x[j], rh.hit.Ng_y[j], rh.hit.Ng_z[j], geom_to_mesh);
  }
}

// The fan's packet copies are LL_ISA_CLONES (core/common/isa.h); they move bits only.

namespace {

// Eight lanes per GCC vector: on 64-byte vectors GCC 12's AVX2 clone turned the compare
// into scalar code.
typedef std::int32_t Ints8 __attribute__((vector_size(32)));

// A packet in and out of Embree's record as vector moves: the directions in, and every hit
// field out with the lanes that missed zeroed by a mask: cheaper than copying lane by lane
// with a select per field (precompute_bench's "trace" phase on CornellBox-Original).
LL_ISA_INLINE void fanPacketInImpl(RTCRayHit16& rh, const float* dx, const float* dy, const float* dz, float tfar) {
  std::memcpy(rh.ray.dir_x, dx, sizeof rh.ray.dir_x);
  std::memcpy(rh.ray.dir_y, dy, sizeof rh.ray.dir_y);
  std::memcpy(rh.ray.dir_z, dz, sizeof rh.ray.dir_z);
  for (std::size_t j = 0; j < 16; ++j) {
    rh.ray.tfar[j] = tfar;
    rh.hit.geomID[j] = RTC_INVALID_GEOMETRY_ID;
  }
}
LL_ISA_CLONES(void, fanPacketIn, (RTCRayHit16& rh, const float* dx, const float* dy, const float* dz, float tfar), (rh, dx, dy, dz, tfar), fanPacketInImpl)

LL_ISA_INLINE void fanPacketOutImpl(const RTCRayHit16& rh, const std::uint32_t* geom_to_mesh, std::uint32_t geometries,
                                  std::size_t base, const HitArrays& out) {
  const Ints8 invalid = Ints8{} + static_cast<std::int32_t>(RTC_INVALID_GEOMETRY_ID);
  for (std::size_t half = 0; half < 16; half += 8) {
    Ints8 geom;
    std::memcpy(&geom, rh.hit.geomID + half, sizeof geom);
    const Ints8 hit = geom != invalid;  // -1 where the lane hit
    auto masked = [&](const void* src, void* dst) {
      Ints8 v;
      std::memcpy(&v, src, sizeof v);
      v &= hit;
      std::memcpy(dst, &v, sizeof v);
    };
    masked(rh.hit.primID + half, out.triangle + base + half);
    masked(rh.hit.u + half, out.u + base + half);
    masked(rh.hit.v + half, out.v + base + half);
    masked(rh.hit.Ng_x + half, out.ng_x + base + half);
    masked(rh.hit.Ng_y + half, out.ng_y + base + half);
    masked(rh.hit.Ng_z + half, out.ng_z + base + half);
  }
  std::memcpy(out.t + base, rh.ray.tfar, sizeof rh.ray.tfar);
  for (std::size_t j = 0; j < 16; ++j)
    out.mesh[base + j] = geom_to_mesh[std::min<std::uint32_t>(rh.hit.geomID[j], geometries)];
}
LL_ISA_CLONES(void, fanPacketOut, (const RTCRayHit16& rh, const std::uint32_t* geom_to_mesh, std::uint32_t geometries, std::size_t base, const HitArrays& out), (rh, geom_to_mesh, geometries, base, out), fanPacketOutImpl)

}  // namespace

void Accel::intersectFan(const RayFan& fan, const HitArrays& out) const {
  RTCIntersectContext ctx = makeContext(Coherence::kCoherent);
  alignas(64) RTCRayHit16 rh;
  alignas(64) std::array<int, 16> valid;
  // What every packet shares is written once. Embree writes only tfar and the hit fields,
  // and of those instID only for instances (there are none).
  for (std::size_t j = 0; j < 16; ++j) {
    valid[j] = -1;
    rh.ray.org_x[j] = fan.origin.x;
    rh.ray.org_y[j] = fan.origin.y;
    rh.ray.org_z[j] = fan.origin.z;
    rh.ray.tnear[j] = fan.tnear;
    rh.ray.time[j] = 0.0f;
    rh.ray.mask[j] = 0xFFFFFFFFu;
    rh.ray.id[j] = static_cast<unsigned>(j);
    rh.ray.flags[j] = 0;
    rh.hit.instID[0][j] = RTC_INVALID_GEOMETRY_ID;
  }
  const std::uint32_t* geom_to_mesh = impl_->geom_to_mesh.data();
  const std::uint32_t geometries = impl_->geometries();
  const float tfar = fan.tfar;
  RTCScene scene = impl_->scene.get();
  const std::size_t whole = fan.count / 16 * 16;
  for (std::size_t base = 0; base < whole; base += 16) {
    fanPacketIn(rh, fan.dir_x + base, fan.dir_y + base, fan.dir_z + base, tfar);
    rtcIntersect16(valid.data(), scene, &ctx, &rh);
    fanPacketOut(rh, geom_to_mesh, geometries, base, out);
  }
  if (whole == fan.count) return;
  // The last, partial packet through the same copies: its directions padded with harmless
  // rays that Embree skips (valid = 0, as in intersect()), its hits out into a whole packet's
  // arrays here, of which the first `count` are kept.
  const std::size_t count = fan.count - whole;
  alignas(64) float dx[16] = {}, dy[16] = {}, dz[16];
  std::fill(std::begin(dz), std::end(dz), 1.0f);
  std::copy_n(fan.dir_x + whole, count, dx);
  std::copy_n(fan.dir_y + whole, count, dy);
  std::copy_n(fan.dir_z + whole, count, dz);
  for (std::size_t j = 0; j < 16; ++j) valid[j] = j < count ? -1 : 0;
  fanPacketIn(rh, dx, dy, dz, tfar);
  rtcIntersect16(valid.data(), scene, &ctx, &rh);
  alignas(64) std::uint32_t mesh[16], triangle[16];
  alignas(64) float u[16], v[16], t[16], nx[16], ny[16], nz[16];
  fanPacketOut(rh, geom_to_mesh, geometries, 0, HitArrays{mesh, triangle, u, v, t, nx, ny, nz});
  std::copy_n(mesh, count, out.mesh + whole);
  std::copy_n(triangle, count, out.triangle + whole);
  std::copy_n(u, count, out.u + whole);
  std::copy_n(v, count, out.v + whole);
  std::copy_n(t, count, out.t + whole);
  std::copy_n(nx, count, out.ng_x + whole);
  std::copy_n(ny, count, out.ng_y + whole);
  std::copy_n(nz, count, out.ng_z + whole);
}

void Accel::Impl::intersectStream(std::span<const Ray> rays, std::span<Hit> hits,
                                  RTCIntersectContext& ctx) const {
  std::array<RTCRayHit, kStreamGroup> rh;
  for (std::size_t base = 0; base < rays.size(); base += kStreamGroup) {
    const std::size_t count = std::min(kStreamGroup, rays.size() - base);
    for (std::size_t j = 0; j < count; ++j) {
      fillRay(rh[j].ray, rays[base + j]);
      rh[j].hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh[j].hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcIntersect1M(scene.get(), &ctx, rh.data(), static_cast<unsigned>(count), sizeof(RTCRayHit));
    for (std::size_t j = 0; j < count; ++j) {
      const RTCRayHit& r = rh[j];
      fillHit(hits[base + j], r.hit.geomID, r.hit.primID, r.hit.u, r.hit.v, r.ray.tfar, r.hit.Ng_x,
              r.hit.Ng_y, r.hit.Ng_z, geom_to_mesh);
    }
  }
}

void Accel::Impl::occludedPackets(std::span<const Ray> rays, std::span<std::uint8_t> out,
                                  RTCIntersectContext& ctx) const {
  alignas(64) RTCRay16 r;
  alignas(64) std::array<int, 16> valid;
  for (std::size_t base = 0; base < rays.size(); base += 16) {
    const std::size_t count = std::min<std::size_t>(16, rays.size() - base);
    fillRay16(r, valid, rays.data() + base, count);
    rtcOccluded16(valid.data(), scene.get(), &ctx, &r);
    for (std::size_t j = 0; j < count; ++j)
      out[base + j] = (r.tfar[j] < 0.0f && std::isinf(r.tfar[j])) ? 1 : 0;
  }
}

void Accel::Impl::occludedStream(std::span<const Ray> rays, std::span<std::uint8_t> out,
                                 RTCIntersectContext& ctx) const {
  std::array<RTCRay, kStreamGroup> r;
  for (std::size_t base = 0; base < rays.size(); base += kStreamGroup) {
    const std::size_t count = std::min(kStreamGroup, rays.size() - base);
    for (std::size_t j = 0; j < count; ++j) fillRay(r[j], rays[base + j]);
    rtcOccluded1M(scene.get(), &ctx, r.data(), static_cast<unsigned>(count), sizeof(RTCRay));
    for (std::size_t j = 0; j < count; ++j)
      out[base + j] = (r[j].tfar < 0.0f && std::isinf(r[j].tfar)) ? 1 : 0;
  }
}

void Accel::intersect(std::span<const Ray> rays, std::span<Hit> hits, Coherence coherence) const {
  LL_CHECK_EQ(rays.size(), hits.size());
  RTCIntersectContext context = makeContext(coherence);
  if (coherence == Coherence::kCoherent)
    impl_->intersectPackets(rays, hits, context);
  else
    impl_->intersectStream(rays, hits, context);
}

void Accel::occluded(std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                     Coherence coherence) const {
  LL_CHECK_EQ(rays.size(), occluded.size());
  RTCIntersectContext context = makeContext(coherence);
  if (coherence == Coherence::kCoherent)
    impl_->occludedPackets(rays, occluded, context);
  else
    impl_->occludedStream(rays, occluded, context);
}

// ---- scale and offsets -----------------------------------------------------------------

float Accel::sceneScale() const { return impl_->scale; }
float Accel::rayEpsilon() const { return impl_->epsilon; }
std::size_t Accel::triangleCount() const { return impl_->triangles; }
const Aabb& Accel::bounds() const { return impl_->bounds; }
Status Accel::deviceStatus() const { return impl_->errors.first(); }

glm::vec3 Accel::offsetOrigin(const glm::vec3& p, const glm::vec3& n_geom, const glm::vec3& dir) const {
  const float largest = std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)});
  const float distance = impl_->epsilon + kOffsetUlps * FLT_EPSILON * largest;
  const float n_len2 = glm::dot(n_geom, n_geom);
  if (!(n_len2 > 0.0f)) {
    // No usable normal (degenerate triangle): step along the ray itself instead.
    const float d_len2 = glm::dot(dir, dir);
    return d_len2 > 0.0f ? p + dir * (distance / std::sqrt(d_len2)) : p;
  }
  const float side = glm::dot(n_geom, dir) >= 0.0f ? 1.0f : -1.0f;
  return p + n_geom * (side * distance / std::sqrt(n_len2));
}

}  // namespace lightlink::rt
