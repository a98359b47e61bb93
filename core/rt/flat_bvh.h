// FlatBvh: a binary BVH over the scene's shadow-casting static triangles, flattened into two
// plain arrays a GPU shader can walk (shaders/common_bvh.glsl), for shadow rays only.
//
// Embree's own BVH is opaque, so the tree is built with Embree's builder API (rtcBuildBVH,
// binned SAH, our node and leaf callbacks) and then written depth first: node 0 is the root,
// an inner node names its two children, a leaf names a run of `triangles`. It holds what
// Accel::occluded() sees: static meshes (as AccelOptions::static_only) that cast shadows;
// alpha cut-outs are not modelled (cutout_meshes counts the meshes that have one, so a caller
// can leave such scenes to Accel). The build runs on one thread: Embree's parallel
// partitioning reorders primitives inside a range, so only a serial build gives the same
// arrays for any thread count.
//
// occluded() is the reference traversal on the host, step for step what the GLSL does:
// watertight ray/triangle test (Woop, Benthin, Wald, JCGT 2013, as Embree's robust mode),
// double-sided, hits with t in [tnear, tfar] in units of |dir| (Accel's ray contract).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/status.h"
#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::rt {

// Set in BvhNode::b for a leaf; its low bits are the triangle count.
inline constexpr std::uint32_t kBvhLeaf = 0x80000000u;

// 32 bytes, laid out as std430 `vec4 lower_a; vec4 upper_b;` (a, b as floatBitsToUint).
// Inner node: a, b = left and right child indices. Leaf: a = first triangle, b = kBvhLeaf | count.
struct BvhNode {
  glm::vec3 lower{0.0f};
  std::uint32_t a = 0;
  glm::vec3 upper{0.0f};
  std::uint32_t b = 0;
};
static_assert(sizeof(BvhNode) == 32);

// A triangle's vertices in world space (metres); w is 0 (std430 vec4 x 3).
struct BvhTriangle {
  glm::vec4 v0{0.0f}, v1{0.0f}, v2{0.0f};
};
static_assert(sizeof(BvhTriangle) == 48);

struct FlatBvh {
  std::vector<BvhNode> nodes;          // [0] is the root
  std::vector<BvhTriangle> triangles;  // in leaf order
  std::size_t cutout_meshes = 0;       // traced meshes with an alpha cut-out (not modelled)
  int depth = 0;                       // levels below the root (a traversal stack needs depth + 1)

  // Fails with kInvalidInput on an index outside its mesh's positions or a non-finite
  // position (naming the mesh), or when no triangle casts a shadow; kInternal when Embree
  // reports an error.
  static Expected<FlatBvh> build(const scene::Scene& scene);

  // Anything on the ray within [tnear, tfar]? Same walk and test as shaders/common_bvh.glsl.
  bool occluded(const Ray& ray) const;
};

// The deepest tree occluded() and the shader walk (their stack holds kBvhMaxDepth + 1 nodes).
inline constexpr int kBvhMaxDepth = 48;

}  // namespace lightlink::rt
