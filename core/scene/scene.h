// Scene: the in-memory form of a glTF after ingest and validation.
//
// Everything downstream (charts, surfels, links, relight, the reference) reads this and
// only this. Geometry is flattened: one `MeshInstance` per (node, primitive) pair with
// positions and normals already in world space, so instancing is expanded and no module
// needs the node graph. Units are the ones in docs/units.md: lengths in metres (glTF's
// unit), point/spot intensity in candela, directional illuminance in lux, emission as
// radiance (glTF emissiveFactor * KHR_materials_emissive_strength) so an emitter of
// radiance L gives irradiance pi*L at a point it fully surrounds.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/common/aabb.h"
#include "core/lights/light.h"
#include "core/lights/scenarios.h"

namespace lightlink::scene {

// A decoded texture, RGB(A)8 as stored; colour textures are sRGB-encoded and converted to
// linear at sample time (glTF: baseColor and emissive are sRGB).
struct Texture {
  std::string name;
  int width = 0;
  int height = 0;
  // width*height*channels bytes, row 0 = top (glTF v = 0): RGBA8, or RGB8 (channels = 3)
  // where nothing reads the alpha (an opaque material's base colour, an emissive texture).
  std::vector<std::uint8_t> rgba8;
  int channels = 4;
  // Sampler state from glTF (wrap modes as GL enums; 10497 = REPEAT).
  int wrap_s = 10497;
  int wrap_t = 10497;
  bool nearest = false;  // magFilter NEAREST

  // Bilinear, wrap-aware sample at glTF UV, decoded from sRGB to linear RGB (alpha linear;
  // 1 for an RGB8 texture).
  glm::vec4 sampleSrgb(glm::vec2 uv) const;
};

struct TextureRef {
  int texture = -1;  // index into Scene::textures, -1 if none
  int texcoord = 0;  // which TEXCOORD_n set the texture uses
  bool valid() const { return texture >= 0; }
};

struct Material {
  std::string name;
  glm::vec4 base_color_factor{1.0f};  // linear RGBA
  TextureRef base_color_texture;
  glm::vec3 emissive_factor{0.0f};    // linear RGB
  float emissive_strength = 1.0f;     // KHR_materials_emissive_strength
  TextureRef emissive_texture;
  float metallic = 1.0f;              // glTF defaults
  float roughness = 1.0f;
  bool double_sided = false;
  // glTF alphaMode. kMask: the surface is cut out (no ray hits it) where base-colour alpha
  // (factor * texture) < alpha_cutoff. kBlend: traced as a mask at 0.5 (opaque where the
  // opacity is at least one half), docs/scene-format.md "Alpha".
  enum class AlphaMode { kOpaque, kMask, kBlend };
  AlphaMode alpha_mode = AlphaMode::kOpaque;
  float alpha_cutoff = 0.5f;  // glTF alphaCutoff (MASK only)
  // extras {"lightlink": {"cast_shadows": false}}: shadow rays pass through the surface;
  // a node's own flag overrides it (MeshInstance::cast_shadows).
  bool cast_shadows = true;
  // extras.lightlink.contribute_gi: false = reflects no bounce light onto other surfaces.
  bool contribute_gi = true;
  // extras.lightlink.receive_gi, when set (ReceiveGi), else -1: where the mesh's indirect
  // light comes from. A node's own value wins.
  int receive_gi = -1;

  bool hasCutout() const { return alpha_mode != AlphaMode::kOpaque; }
  // The alpha below which the surface is cut out.
  float cutoutThreshold() const { return alpha_mode == AlphaMode::kMask ? alpha_cutoff : 0.5f; }

  bool isEmissive() const {
    return emissive_strength > 0.0f &&
           (emissive_factor.x > 0.0f || emissive_factor.y > 0.0f || emissive_factor.z > 0.0f);
  }
};

// Where a static mesh's indirect light comes from (extras.lightlink.receive_gi): its lightmap,
// the irradiance volume ("volume", as "lightmap": false), or nowhere ("off": baked like
// "volume", and listed so that the engine shades it without baked indirect light).
enum class ReceiveGi { kLightmap = 0, kVolume = 1, kOff = 2 };

// One triangle primitive placed in the world by one node.
struct MeshInstance {
  std::string name;          // "<mesh name>/<primitive index>" (or node name if the mesh has none)
  int gltf_node = -1;
  int gltf_mesh = -1;
  int gltf_primitive = -1;
  int material = -1;         // index into Scene::materials; -1 = glTF default material
  bool is_static = true;     // node extras {"lightlink": {"static": false}} marks it dynamic
  // Lightmap texel density multiplier (node extras {"lightlink": {"lightmap_scale": s}}):
  // 2 gives the mesh texels half as large as the atlas's texel size.
  float lightmap_scale = 1.0f;
  // Static, but indirect light from the irradiance volume instead of the lightmap: set by
  // node extras {"lightlink": {"lightmap": false}}, or by the unwrap for objects too small
  // for the lightmap (every chart under 2x2 texels). Such a mesh has no uv1.
  bool probe_lit = false;
  // False: shadow rays (direct light) pass through this mesh; other rays still hit it. From
  // node extras {"lightlink": {"cast_shadows": b}} (inherited), else the material's.
  bool cast_shadows = true;
  // False: the mesh reflects no bounce light (its surfels and the reference see albedo 0);
  // it still blocks light and receives it. Node extras over material extras, like cast_shadows.
  bool contribute_gi = true;
  ReceiveGi receive_gi = ReceiveGi::kLightmap;  // kVolume and kOff also set probe_lit
  glm::mat4 world_from_mesh{1.0f};

  // Vertices stay 1:1 with the glTF primitive's accessors (vertex i here is vertex i
  // there), so a writer can add TEXCOORD_1 to the original file; only `indices` is edited.
  std::vector<glm::vec3> positions;  // world space
  std::vector<glm::vec3> normals;    // world space, unit length (generated when absent)
  std::vector<glm::vec2> uv0;        // TEXCOORD_0, empty if absent
  std::vector<glm::vec2> uv1;        // TEXCOORD_1 (lightmap UV), empty if absent
  // 3 per triangle, counter-clockwise seen from the front in world space (mirrored
  // instances already flipped), strips/fans triangulated, degenerate triangles dropped.
  std::vector<std::uint32_t> indices;
  bool normals_generated = false;

  std::size_t triangleCount() const { return indices.size() / 3; }
  bool hasLightmapUv() const { return !uv1.empty(); }
};

// KHR_lights_punctual, in world space (core/lights/light.h: the light-set library owns it).
using Light = lights::Light;

struct SceneStats {
  std::size_t triangles_in = 0;         // as read, before dropping degenerates
  std::size_t degenerate_dropped = 0;   // zero-area or repeated-index triangles removed
  std::size_t vertices = 0;             // over all instances, as read
  std::size_t instances_without_triangles = 0;  // (node, primitive) pairs left empty and removed
  std::size_t normals_generated = 0;    // instances whose normals were generated
  // Images: decoded for lighting (base colour, emissive), each once, and left undecoded
  // because nothing lightlink computes reads them (normal, metallic-roughness, occlusion
  // maps, unused images; core/scene/lighting_images.h).
  std::size_t images_decoded = 0;
  std::size_t images_skipped = 0;
  std::uint64_t image_bytes = 0;        // bytes the decoded images take (RGB8 / RGBA8)
};

struct Scene {
  std::string source_path;
  std::vector<MeshInstance> meshes;
  std::vector<Material> materials;
  std::vector<Texture> textures;
  std::vector<Light> lights;
  std::vector<std::string> warnings;  // non-fatal findings, each naming the object
  SceneStats stats;

  Aabb bounds;        // of all geometry, world space
  float scale = 1.0f; // bounds diagonal in metres; the yardstick for every epsilon

  std::size_t triangleCount() const;
  std::size_t staticTriangleCount() const;
  // The material for a mesh, or the glTF default material for material == -1.
  const Material& materialOf(const MeshInstance& mesh) const;
  // Emissive surface area (m^2) over all meshes whose material emits.
  double emissiveArea() const;
  // Each material's own emission, as lighting-scenario blends need it (core/lights/scenarios.h).
  std::vector<lights::MaterialEmission> materialEmissions() const;
};

}  // namespace lightlink::scene
