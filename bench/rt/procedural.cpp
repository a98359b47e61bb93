#include "bench/rt/procedural.h"

#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/common/check.h"

namespace lightlink::bench {
namespace {

using glm::vec3;

// Appends the quad corner, corner+e0, corner+e0+e1, corner+e1 (front face along cross(e0, e1)).
void addQuad(scene::MeshInstance& mesh, vec3 corner, vec3 e0, vec3 e1) {
  const auto base = static_cast<std::uint32_t>(mesh.positions.size());
  const vec3 n = glm::normalize(glm::cross(e0, e1));
  for (const vec3& p : {corner, corner + e0, corner + e0 + e1, corner + e1}) {
    mesh.positions.push_back(p);
    mesh.normals.push_back(n);
  }
  for (std::uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) mesh.indices.push_back(base + i);
}

// Box [lo, hi] with outward front faces; the floor is optional (buildings stand on ground).
void addBox(scene::MeshInstance& mesh, vec3 lo, vec3 hi, bool floor) {
  const vec3 d = hi - lo;
  const vec3 ex(d.x, 0, 0), ey(0, d.y, 0), ez(0, 0, d.z);
  addQuad(mesh, lo, ez, ey);                      // -x
  addQuad(mesh, vec3(hi.x, lo.y, lo.z), ey, ez);  // +x
  if (floor) addQuad(mesh, lo, ex, ez);           // -y
  addQuad(mesh, vec3(lo.x, hi.y, lo.z), ez, ex);  // +y
  addQuad(mesh, lo, ey, ex);                      // -z
  addQuad(mesh, vec3(lo.x, lo.y, hi.z), ex, ey);  // +z
}

}  // namespace

void updateBounds(scene::Scene& scene) {
  scene.bounds = Aabb{};
  for (const scene::MeshInstance& mesh : scene.meshes)
    for (std::uint32_t i : mesh.indices) scene.bounds.grow(mesh.positions[i]);
  scene.scale = scene.bounds.diagonal();
}

scene::Scene makeCity(std::uint32_t seed, int lots) {
  constexpr float kLot = 20.0f;  // metres
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  scene::Scene city;
  city.source_path = "procedural:city";

  scene::MeshInstance ground;
  ground.name = "ground";
  const float extent = kLot * static_cast<float>(lots);
  addQuad(ground, vec3(0.0f), vec3(0, 0, extent), vec3(extent, 0, 0));
  city.meshes.push_back(std::move(ground));

  for (int row = 0; row < lots; ++row) {
    scene::MeshInstance mesh;
    mesh.name = "row" + std::to_string(row);
    for (int col = 0; col < lots; ++col) {
      const float x = kLot * static_cast<float>(col), z = kLot * static_cast<float>(row);
      const float h = 5.0f + 120.0f * std::pow(u01(rng), 3.0f);  // many low, few tall
      const vec3 lo(x + 3.0f + 4.0f * u01(rng), 0.0f, z + 3.0f + 4.0f * u01(rng));
      const vec3 hi(x + 17.0f - 4.0f * u01(rng), h, z + 17.0f - 4.0f * u01(rng));
      addBox(mesh, lo, hi, /*floor=*/false);
      if ((row * lots + col) % 8 == 0) {
        // An overhanging slab: occluders that are not ground-standing boxes.
        const float y = h + 5.0f + 15.0f * u01(rng);
        addBox(mesh, vec3(x + 6.0f, y, z + 6.0f), vec3(x + 20.0f, y + 1.0f, z + 20.0f), /*floor=*/true);
      }
    }
    city.meshes.push_back(std::move(mesh));
  }
  updateBounds(city);
  return city;
}

void subdivide(scene::Scene& scene, int levels) {
  LL_CHECK(levels >= 0 && levels <= 8);
  if (levels == 0) return;
  const std::uint32_t k = 1u << levels;  // segments per edge
  // Vertex (i, j) of the barycentric grid, i + j <= k, numbered row by row.
  auto vertexId = [k](std::uint32_t i, std::uint32_t j) {
    // Rows j = 0..j-1 hold (k+1) + k + ... + (k+2-j) vertices.
    return j * (k + 1) - j * (j - 1) / 2 + i;
  };
  const std::uint32_t per_tri_vertices = (k + 1) * (k + 2) / 2;
  for (scene::MeshInstance& mesh : scene.meshes) {
    const bool has_normals = mesh.normals.size() == mesh.positions.size();
    scene::MeshInstance out;
    const std::size_t tris = mesh.triangleCount();
    out.positions.reserve(tris * per_tri_vertices);
    if (has_normals) out.normals.reserve(tris * per_tri_vertices);
    out.indices.reserve(tris * 3 * k * k);
    for (std::size_t t = 0; t < tris; ++t) {
      const std::uint32_t* idx = &mesh.indices[3 * t];
      const vec3 a = mesh.positions[idx[0]], b = mesh.positions[idx[1]], c = mesh.positions[idx[2]];
      const auto base = static_cast<std::uint32_t>(out.positions.size());
      for (std::uint32_t j = 0; j <= k; ++j)
        for (std::uint32_t i = 0; i + j <= k; ++i) {
          const float fi = static_cast<float>(i) / static_cast<float>(k);
          const float fj = static_cast<float>(j) / static_cast<float>(k);
          out.positions.push_back(a + fi * (b - a) + fj * (c - a));
          if (has_normals) {
            const vec3 na = mesh.normals[idx[0]], nb = mesh.normals[idx[1]], nc = mesh.normals[idx[2]];
            out.normals.push_back(glm::normalize(na + fi * (nb - na) + fj * (nc - na)));
          }
        }
      // Same winding as (a, b, c): "up" triangles (i,j)(i+1,j)(i,j+1) and "down" triangles
      // (i+1,j)(i+1,j+1)(i,j+1).
      for (std::uint32_t j = 0; j < k; ++j)
        for (std::uint32_t i = 0; i + j < k; ++i) {
          for (std::uint32_t v : {vertexId(i, j), vertexId(i + 1, j), vertexId(i, j + 1)})
            out.indices.push_back(base + v);
          if (i + j + 1 < k)
            for (std::uint32_t v : {vertexId(i + 1, j), vertexId(i + 1, j + 1), vertexId(i, j + 1)})
              out.indices.push_back(base + v);
        }
    }
    mesh.positions = std::move(out.positions);
    mesh.normals = std::move(out.normals);
    mesh.indices = std::move(out.indices);
    mesh.uv0.clear();
    mesh.uv1.clear();
  }
}

}  // namespace lightlink::bench
