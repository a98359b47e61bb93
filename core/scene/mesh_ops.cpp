#include "core/scene/mesh_ops.h"

namespace lightlink::scene {

void generateVertexNormals(const std::vector<glm::vec3>& positions,
                           const std::vector<std::uint32_t>& indices,
                           std::vector<glm::vec3>& normals) {
  std::vector<glm::dvec3> sum(positions.size(), glm::dvec3(0.0));
  for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
    const glm::dvec3 a(positions[indices[t]]);
    const glm::dvec3 b(positions[indices[t + 1]]);
    const glm::dvec3 c(positions[indices[t + 2]]);
    const glm::dvec3 n = glm::cross(b - a, c - a);  // length = 2 * area: the area weight
    sum[indices[t]] += n;
    sum[indices[t + 1]] += n;
    sum[indices[t + 2]] += n;
  }
  normals.resize(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const double len = glm::length(sum[i]);
    normals[i] = len > 0.0 ? glm::vec3(sum[i] / len) : glm::vec3(0.0f, 0.0f, 1.0f);
  }
}

std::size_t worldNormalsOrGenerated(const glm::dmat3& linear, MeshInstance& mesh) {
  bool need_generated = mesh.normals.empty();
  const glm::dmat3 normal_from_mesh = glm::transpose(glm::inverse(linear));
  for (glm::vec3& n : mesh.normals) {
    const glm::dvec3 w = normal_from_mesh * glm::dvec3(n);
    const double len = glm::length(w);
    if (len > 0.0 && std::isfinite(len)) {
      n = glm::vec3(w / len);
    } else {
      n = glm::vec3(0.0f);  // filled from the generated normal below
      need_generated = true;
    }
  }
  if (!need_generated) return 0;
  std::vector<glm::vec3> generated;
  generateVertexNormals(mesh.positions, mesh.indices, generated);
  if (mesh.normals.empty()) {
    mesh.normals = std::move(generated);
    mesh.normals_generated = true;
    return 0;
  }
  std::size_t replaced = 0;
  for (std::size_t i = 0; i < mesh.normals.size(); ++i) {
    if (mesh.normals[i] == glm::vec3(0.0f)) {
      mesh.normals[i] = generated[i];
      ++replaced;
    }
  }
  return replaced;
}

double triangleArea(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::dvec3 da(a);
  return 0.5 * glm::length(glm::cross(glm::dvec3(b) - da, glm::dvec3(c) - da));
}

std::size_t dropDegenerateTriangles(MeshInstance& mesh, double min_area_m2) {
  std::vector<std::uint32_t>& idx = mesh.indices;
  std::size_t kept = 0;
  for (std::size_t t = 0; t + 2 < idx.size(); t += 3) {
    const std::uint32_t i0 = idx[t], i1 = idx[t + 1], i2 = idx[t + 2];
    if (i0 == i1 || i1 == i2 || i0 == i2) continue;
    if (!(triangleArea(mesh.positions[i0], mesh.positions[i1], mesh.positions[i2]) >= min_area_m2)) {
      continue;
    }
    idx[kept++] = i0;
    idx[kept++] = i1;
    idx[kept++] = i2;
  }
  const std::size_t dropped = (idx.size() - kept) / 3;
  idx.resize(kept);
  return dropped;
}

}  // namespace lightlink::scene
