#include "core/charts/test_meshes.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <string>

namespace lightlink::charts::test_meshes {
namespace {

void quad(std::vector<std::uint32_t>& idx, std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
  idx.insert(idx.end(), {a, b, c, a, c, d});
}

}  // namespace

scene::MeshInstance sphere(float radius, int segments, int rings) {
  scene::MeshInstance m;
  m.name = "sphere";
  const float pi = std::numbers::pi_v<float>;
  for (int r = 0; r <= rings; ++r) {
    const float theta = pi * static_cast<float>(r) / static_cast<float>(rings);
    for (int s = 0; s <= segments; ++s) {
      const float phi = 2.0f * pi * static_cast<float>(s) / static_cast<float>(segments);
      const glm::vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi));
      m.positions.push_back(radius * n);
      m.normals.push_back(n);
      m.uv0.emplace_back(static_cast<float>(s) / segments, static_cast<float>(r) / rings);
    }
  }
  const auto at = [&](int r, int s) { return static_cast<std::uint32_t>(r * (segments + 1) + s); };
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      // Counter-clockwise seen from outside; the pole rows are triangles, not quads.
      if (r != 0) m.indices.insert(m.indices.end(), {at(r, s), at(r + 1, s), at(r, s + 1)});
      if (r != rings - 1) m.indices.insert(m.indices.end(), {at(r, s + 1), at(r + 1, s), at(r + 1, s + 1)});
    }
  }
  return m;
}

scene::MeshInstance torus(float major_radius, float minor_radius, int segments, int sides) {
  scene::MeshInstance m;
  m.name = "torus";
  const float pi = std::numbers::pi_v<float>;
  for (int i = 0; i <= segments; ++i) {
    const float u = 2.0f * pi * static_cast<float>(i) / static_cast<float>(segments);
    const glm::vec3 dir(std::cos(u), 0.0f, -std::sin(u));
    for (int j = 0; j <= sides; ++j) {
      const float v = 2.0f * pi * static_cast<float>(j) / static_cast<float>(sides);
      const glm::vec3 n = std::cos(v) * dir + glm::vec3(0.0f, std::sin(v), 0.0f);
      m.positions.push_back(major_radius * dir + minor_radius * n);
      m.normals.push_back(n);
      m.uv0.emplace_back(static_cast<float>(i) / segments, static_cast<float>(j) / sides);
    }
  }
  const auto at = [&](int i, int j) { return static_cast<std::uint32_t>(i * (sides + 1) + j); };
  for (int i = 0; i < segments; ++i)
    for (int j = 0; j < sides; ++j) quad(m.indices, at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
  return m;
}

scene::MeshInstance cube(float size, int divisions) {
  scene::MeshInstance m;
  m.name = "cube";
  const glm::vec3 normals[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (const glm::vec3& n : normals) {
    // (t, b, n) right-handed so quads wind counter-clockwise seen from outside.
    const glm::vec3 t = std::abs(n.y) > 0.5f ? glm::vec3(1, 0, 0) : glm::normalize(glm::cross(glm::vec3(0, 1, 0), n));
    const glm::vec3 b = glm::cross(n, t);
    const auto base = static_cast<std::uint32_t>(m.positions.size());
    for (int j = 0; j <= divisions; ++j) {
      for (int i = 0; i <= divisions; ++i) {
        const float u = static_cast<float>(i) / divisions - 0.5f, v = static_cast<float>(j) / divisions - 0.5f;
        m.positions.push_back(size * (0.5f * n + u * t + v * b));
        m.normals.push_back(n);
        m.uv0.emplace_back(u + 0.5f, v + 0.5f);
      }
    }
    const auto at = [&](int i, int j) { return base + static_cast<std::uint32_t>(j * (divisions + 1) + i); };
    for (int j = 0; j < divisions; ++j)
      for (int i = 0; i < divisions; ++i) quad(m.indices, at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
  }
  return m;
}

scene::MeshInstance planeWithHoles(float size, int n) {
  scene::MeshInstance m;
  m.name = "plane_with_holes";
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const float u = static_cast<float>(i) / n, v = static_cast<float>(j) / n;
      m.positions.emplace_back(size * (u - 0.5f), 0.0f, -size * (v - 0.5f));
      m.normals.emplace_back(0.0f, 1.0f, 0.0f);
      m.uv0.emplace_back(u, v);
    }
  }
  const auto at = [&](int i, int j) { return static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      if (i % 4 != 1 || j % 4 != 1) quad(m.indices, at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
  return m;
}

scene::MeshInstance subdivided(const scene::MeshInstance& in) {
  scene::MeshInstance m = in;
  m.indices.clear();
  m.indices.reserve(in.indices.size() * 4);
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> midpoints;
  auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
    const auto key = std::minmax(a, b);
    auto [it, inserted] = midpoints.try_emplace(key, static_cast<std::uint32_t>(m.positions.size()));
    if (inserted) {
      m.positions.push_back(0.5f * (m.positions[a] + m.positions[b]));
      if (!m.normals.empty()) {
        const glm::vec3 n = m.normals[a] + m.normals[b];
        m.normals.push_back(glm::length(n) > 0.0f ? glm::normalize(n) : m.normals[a]);
      }
      if (!m.uv0.empty()) m.uv0.push_back(0.5f * (m.uv0[a] + m.uv0[b]));
      if (!m.uv1.empty()) m.uv1.push_back(0.5f * (m.uv1[a] + m.uv1[b]));
    }
    return it->second;
  };
  for (std::size_t t = 0; t < in.triangleCount(); ++t) {
    const std::uint32_t a = in.indices[3 * t], b = in.indices[3 * t + 1], c = in.indices[3 * t + 2];
    const std::uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
    m.indices.insert(m.indices.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
  }
  return m;
}

scene::Scene makeScene(std::vector<scene::MeshInstance> meshes) {
  scene::Scene s;
  s.source_path = "<procedural>";
  for (std::size_t i = 0; i < meshes.size(); ++i) {
    if (meshes[i].name.empty()) meshes[i].name = "mesh" + std::to_string(i);
    for (const glm::vec3& p : meshes[i].positions) s.bounds.grow(p);
    s.stats.triangles_in += meshes[i].triangleCount();
  }
  s.meshes = std::move(meshes);
  s.scale = s.bounds.diagonal() > 0.0f ? s.bounds.diagonal() : 1.0f;
  return s;
}

}  // namespace lightlink::charts::test_meshes
