#include "core/rt/flat_bvh.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>
#include <mutex>
#include <utility>

#include <embree3/rtcore.h>
#include <tbb/task_arena.h>

namespace lightlink::rt {
namespace {

// The builder's tree, in Embree's thread-local allocator (freed with the RTCBVH).
struct BuildNode {
  bool leaf = false;
};
struct BuildInner : BuildNode {
  BuildNode* child[2] = {nullptr, nullptr};
  RTCBounds bounds[2] = {};
};
struct BuildLeaf : BuildNode {
  std::uint32_t count = 0;
  std::uint32_t ids[2 * RTC_BUILD_MAX_PRIMITIVES_PER_LEAF] = {};  // (mesh, triangle) pairs
};

void* createNode(RTCThreadLocalAllocator alloc, unsigned int child_count, void*) {
  void* mem = rtcThreadLocalAlloc(alloc, sizeof(BuildInner), 16);
  auto* node = new (mem) BuildInner;
  (void)child_count;  // maxBranchingFactor = 2
  return node;
}
void setNodeChildren(void* node, void** children, unsigned int count, void*) {
  auto* n = static_cast<BuildInner*>(node);
  for (unsigned i = 0; i < count && i < 2; ++i) n->child[i] = static_cast<BuildNode*>(children[i]);
}
void setNodeBounds(void* node, const RTCBounds** bounds, unsigned int count, void*) {
  auto* n = static_cast<BuildInner*>(node);
  for (unsigned i = 0; i < count && i < 2; ++i) n->bounds[i] = *bounds[i];
}
void* createLeaf(RTCThreadLocalAllocator alloc, const RTCBuildPrimitive* prims, size_t count, void*) {
  void* mem = rtcThreadLocalAlloc(alloc, sizeof(BuildLeaf), 16);
  auto* leaf = new (mem) BuildLeaf;
  leaf->leaf = true;
  leaf->count = std::uint32_t(std::min<size_t>(count, RTC_BUILD_MAX_PRIMITIVES_PER_LEAF));
  for (std::uint32_t i = 0; i < leaf->count; ++i) leaf->ids[2 * i] = prims[i].geomID, leaf->ids[2 * i + 1] = prims[i].primID;
  return leaf;
}

struct ErrorSink {
  std::mutex mutex;
  Status first;
  static void callback(void* user, RTCError, const char* message) {
    auto* self = static_cast<ErrorSink*>(user);
    std::lock_guard<std::mutex> lock(self->mutex);
    if (self->first.isOk()) self->first = internalError("Embree BVH builder: {}", message ? message : "(no message)");
  }
};

// Writes the subtree at `node` depth first; returns its index.
struct Flattener {
  const scene::Scene& scene;
  FlatBvh& out;
  std::uint32_t visit(const BuildNode* node, const RTCBounds& b, int depth) {
    out.depth = std::max(out.depth, depth);
    const auto index = std::uint32_t(out.nodes.size());
    out.nodes.push_back({glm::vec3(b.lower_x, b.lower_y, b.lower_z), 0, glm::vec3(b.upper_x, b.upper_y, b.upper_z), 0});
    if (node->leaf) {
      const auto* leaf = static_cast<const BuildLeaf*>(node);
      // Sorted, so a leaf's order does not depend on how the builder partitioned its range.
      std::vector<std::pair<std::uint32_t, std::uint32_t>> ids(leaf->count);
      for (std::uint32_t i = 0; i < leaf->count; ++i) ids[i] = {leaf->ids[2 * i], leaf->ids[2 * i + 1]};
      std::sort(ids.begin(), ids.end());
      out.nodes[index].a = std::uint32_t(out.triangles.size());
      out.nodes[index].b = kBvhLeaf | leaf->count;
      for (const auto& [m, tri] : ids) {
        const auto& mesh = scene.meshes[m];
        const std::uint32_t t = tri;  // clang 14 cannot capture a structured binding
        const auto p = [&](int k) { return glm::vec4(mesh.positions[mesh.indices[3 * t + k]], 0.0f); };
        out.triangles.push_back({p(0), p(1), p(2)});
      }
      return index;
    }
    const auto* inner = static_cast<const BuildInner*>(node);
    const std::uint32_t left = visit(inner->child[0], inner->bounds[0], depth + 1);
    const std::uint32_t right = visit(inner->child[1], inner->bounds[1], depth + 1);
    out.nodes[index].a = left, out.nodes[index].b = right;
    return index;
  }
};

// The slab test's far distance is scaled up by 1 + 2 gamma(3) (pbrt-v4, "Robust
// ray-bounds intersection"), so rounding never culls a box the ray truly crosses.
constexpr float kSlabGrow = 1.0f + 2.0f * (3.0f * 0x1p-24f) / (1.0f - 3.0f * 0x1p-24f);

// A direction component that is exactly 0 becomes a tiny one of the same sign, so the
// reciprocal is finite-or-inf and never meets a 0 * inf.
float nonZero(float d) { return std::abs(d) < 1e-30f ? std::copysign(1e-30f, d) : d; }

bool hitsBox(const BvhNode& n, const glm::vec3& org, const glm::vec3& inv_dir, float tnear, float tfar) {
  float t0 = tnear, t1 = tfar;
  for (int k = 0; k < 3; ++k) {
    float a = (n.lower[k] - org[k]) * inv_dir[k], b = (n.upper[k] - org[k]) * inv_dir[k];
    if (a > b) std::swap(a, b);
    b *= kSlabGrow;
    t0 = a > t0 ? a : t0;
    t1 = b < t1 ? b : t1;
    if (t0 > t1) return false;
  }
  return true;
}

// The watertight test's shear constants for one ray.
struct Shear {
  int kx, ky, kz;
  float sx, sy, sz;
};
Shear shearOf(const glm::vec3& d) {
  const glm::vec3 a = glm::abs(d);
  Shear s;
  s.kz = a.x > a.y ? (a.x > a.z ? 0 : 2) : (a.y > a.z ? 1 : 2);
  s.kx = (s.kz + 1) % 3, s.ky = (s.kx + 1) % 3;
  if (d[s.kz] < 0.0f) std::swap(s.kx, s.ky);
  s.sx = d[s.kx] / d[s.kz], s.sy = d[s.ky] / d[s.kz], s.sz = 1.0f / d[s.kz];
  return s;
}

bool hitsTriangle(const BvhTriangle& tri, const glm::vec3& org, const Shear& s, float tnear, float tfar) {
  const glm::vec3 A = glm::vec3(tri.v0) - org, B = glm::vec3(tri.v1) - org, C = glm::vec3(tri.v2) - org;
  const float ax = A[s.kx] - s.sx * A[s.kz], ay = A[s.ky] - s.sy * A[s.kz];
  const float bx = B[s.kx] - s.sx * B[s.kz], by = B[s.ky] - s.sy * B[s.kz];
  const float cx = C[s.kx] - s.sx * C[s.kz], cy = C[s.ky] - s.sy * C[s.kz];
  float u = cx * by - cy * bx, v = ax * cy - ay * cx, w = bx * ay - by * ax;
  if (u == 0.0f || v == 0.0f || w == 0.0f) {  // on an edge: decide in double, as the paper does
    u = float(double(cx) * double(by) - double(cy) * double(bx));
    v = float(double(ax) * double(cy) - double(ay) * double(cx));
    w = float(double(bx) * double(ay) - double(by) * double(ax));
  }
  if ((u < 0.0f || v < 0.0f || w < 0.0f) && (u > 0.0f || v > 0.0f || w > 0.0f)) return false;
  const float det = u + v + w;
  if (det == 0.0f) return false;
  const float t = u * (s.sz * A[s.kz]) + v * (s.sz * B[s.kz]) + w * (s.sz * C[s.kz]);
  return det > 0.0f ? (t >= tnear * det && t <= tfar * det) : (t <= tnear * det && t >= tfar * det);
}

}  // namespace

Expected<FlatBvh> FlatBvh::build(const scene::Scene& scene) {
  FlatBvh out;
  std::vector<RTCBuildPrimitive> prims;
  for (std::uint32_t m = 0; m < scene.meshes.size(); ++m) {
    const auto& mesh = scene.meshes[m];
    if (!mesh.is_static || !mesh.cast_shadows || mesh.triangleCount() == 0) continue;
    const bool cutout = mesh.material >= 0 && std::size_t(mesh.material) < scene.materials.size() &&
                        scene.materials[std::size_t(mesh.material)].hasCutout();
    out.cutout_meshes += cutout;
    for (const glm::vec3& p : mesh.positions)
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        return invalidInput("flat BVH: mesh '{}' has a non-finite position", mesh.name);
    for (std::uint32_t i : mesh.indices)
      if (i >= mesh.positions.size())
        return invalidInput("flat BVH: mesh '{}' indexes vertex {} of {}", mesh.name, i, mesh.positions.size());
    for (std::uint32_t t = 0; t < mesh.triangleCount(); ++t) {
      const glm::vec3 a = mesh.positions[mesh.indices[3 * t]], b = mesh.positions[mesh.indices[3 * t + 1]],
                      c = mesh.positions[mesh.indices[3 * t + 2]];
      const glm::vec3 lo = glm::min(a, glm::min(b, c)), hi = glm::max(a, glm::max(b, c));
      prims.push_back({lo.x, lo.y, lo.z, m, hi.x, hi.y, hi.z, t});
    }
  }
  if (prims.empty()) return invalidInput("flat BVH: no static triangle casts a shadow");

  ErrorSink errors;
  RTCDevice device = rtcNewDevice(nullptr);
  if (!device) return internalError("Embree: rtcNewDevice failed");
  rtcSetDeviceErrorFunction(device, &ErrorSink::callback, &errors);
  RTCBVH bvh = rtcNewBVH(device);
  RTCBuildArguments args = rtcDefaultBuildArguments();
  args.buildQuality = RTC_BUILD_QUALITY_MEDIUM;  // binned SAH; no spatial splits, so prims need no spare capacity
  args.maxBranchingFactor = 2;
  args.maxDepth = kBvhMaxDepth;
  args.maxLeafSize = 4;
  args.bvh = bvh;
  args.primitives = prims.data();
  args.primitiveCount = prims.size();
  args.primitiveArrayCapacity = prims.size();
  args.createNode = createNode;
  args.setNodeChildren = setNodeChildren;
  args.setNodeBounds = setNodeBounds;
  args.createLeaf = createLeaf;
  // One thread: the same arrays at any thread count (see the header).
  void* root = nullptr;
  tbb::task_arena(1).execute([&] { root = rtcBuildBVH(&args); });
  Status status = errors.first;
  if (status.isOk() && !root) status = internalError("Embree: rtcBuildBVH returned no tree");
  if (status.isOk()) {
    RTCBounds all{};
    all.lower_x = all.lower_y = all.lower_z = std::numeric_limits<float>::infinity();
    all.upper_x = all.upper_y = all.upper_z = -std::numeric_limits<float>::infinity();
    for (const auto& p : prims) {
      all.lower_x = std::min(all.lower_x, p.lower_x), all.lower_y = std::min(all.lower_y, p.lower_y);
      all.lower_z = std::min(all.lower_z, p.lower_z), all.upper_x = std::max(all.upper_x, p.upper_x);
      all.upper_y = std::max(all.upper_y, p.upper_y), all.upper_z = std::max(all.upper_z, p.upper_z);
    }
    out.nodes.reserve(prims.size());
    out.triangles.reserve(prims.size());
    Flattener{scene, out}.visit(static_cast<const BuildNode*>(root), all, 0);
    if (out.depth > kBvhMaxDepth)
      status = internalError("flat BVH: depth {} exceeds {}", out.depth, kBvhMaxDepth);
  }
  rtcReleaseBVH(bvh);
  rtcReleaseDevice(device);
  if (!status.isOk()) return status;
  return out;
}

bool FlatBvh::occluded(const Ray& ray) const {
  const glm::vec3 d(nonZero(ray.dir.x), nonZero(ray.dir.y), nonZero(ray.dir.z));
  const glm::vec3 inv = 1.0f / d;
  const Shear s = shearOf(ray.dir);
  std::uint32_t stack[kBvhMaxDepth + 1];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const BvhNode& n = nodes[stack[--top]];
    if (!hitsBox(n, ray.origin, inv, ray.tnear, ray.tfar)) continue;
    if (n.b & kBvhLeaf) {
      for (std::uint32_t i = 0; i < (n.b & ~kBvhLeaf); ++i)
        if (hitsTriangle(triangles[n.a + i], ray.origin, s, ray.tnear, ray.tfar)) return true;
    } else {
      stack[top++] = n.b;
      stack[top++] = n.a;
    }
  }
  return false;
}

}  // namespace lightlink::rt
