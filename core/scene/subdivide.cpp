#include "core/scene/subdivide.h"

#include <unordered_map>

namespace lightlink::scene {
namespace {

void subdivideOnce(MeshInstance& m) {
  const std::size_t tris = m.triangleCount();
  std::unordered_map<std::uint64_t, std::uint32_t> midpoint;
  midpoint.reserve(tris * 2);
  const bool has_n = !m.normals.empty(), has_uv0 = !m.uv0.empty(), has_uv1 = !m.uv1.empty();
  auto mid = [&](std::uint32_t a, std::uint32_t b) {
    const std::uint64_t key = (std::uint64_t(std::min(a, b)) << 32) | std::max(a, b);
    auto [it, inserted] = midpoint.try_emplace(key, static_cast<std::uint32_t>(m.positions.size()));
    if (inserted) {
      m.positions.push_back(0.5f * (m.positions[a] + m.positions[b]));
      if (has_n) {
        const glm::vec3 n = m.normals[a] + m.normals[b];
        const float len = glm::length(n);
        m.normals.push_back(len > 0.0f ? n / len : m.normals[a]);
      }
      if (has_uv0) m.uv0.push_back(0.5f * (m.uv0[a] + m.uv0[b]));
      if (has_uv1) m.uv1.push_back(0.5f * (m.uv1[a] + m.uv1[b]));
    }
    return it->second;
  };
  std::vector<std::uint32_t> out;
  out.reserve(tris * 12);
  for (std::size_t t = 0; t < tris; ++t) {
    const std::uint32_t a = m.indices[3 * t], b = m.indices[3 * t + 1], c = m.indices[3 * t + 2];
    const std::uint32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
    // Same winding as the parent in all four children.
    out.insert(out.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
  }
  m.indices = std::move(out);
}

}  // namespace

void subdivide(Scene& scene, int levels) {
  for (int l = 0; l < levels; ++l)
    for (auto& m : scene.meshes) subdivideOnce(m);
}

}  // namespace lightlink::scene
