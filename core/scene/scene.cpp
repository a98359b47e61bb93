#include "core/scene/scene.h"

#include "core/scene/mesh_ops.h"

namespace lightlink::scene {

std::size_t Scene::triangleCount() const {
  std::size_t n = 0;
  for (const MeshInstance& m : meshes) n += m.triangleCount();
  return n;
}

std::size_t Scene::staticTriangleCount() const {
  std::size_t n = 0;
  for (const MeshInstance& m : meshes) {
    if (m.is_static) n += m.triangleCount();
  }
  return n;
}

const Material& Scene::materialOf(const MeshInstance& mesh) const {
  // glTF 2.0 section 3.9.6: a primitive without a material uses these defaults.
  static const Material kDefault = [] {
    Material m;
    m.name = "glTF default";
    return m;
  }();
  if (mesh.material < 0 || static_cast<std::size_t>(mesh.material) >= materials.size()) {
    return kDefault;
  }
  return materials[static_cast<std::size_t>(mesh.material)];
}

std::vector<lights::MaterialEmission> Scene::materialEmissions() const {
  std::vector<lights::MaterialEmission> out;
  out.reserve(materials.size());
  for (const Material& m : materials)
    out.push_back({m.isEmissive() ? m.emissive_factor * m.emissive_strength : glm::vec3(0.0f),
                   m.emissive_texture.valid()});
  return out;
}

double Scene::emissiveArea() const {
  double area_m2 = 0.0;
  for (const MeshInstance& m : meshes) {
    if (!materialOf(m).isEmissive()) continue;
    for (std::size_t t = 0; t + 2 < m.indices.size(); t += 3) {
      area_m2 += triangleArea(m.positions[m.indices[t]], m.positions[m.indices[t + 1]],
                              m.positions[m.indices[t + 2]]);
    }
  }
  return area_m2;
}

}  // namespace lightlink::scene
