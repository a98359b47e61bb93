// Writes a glTF back with the lightmap uv as TEXCOORD_1, so an engine samples exactly the
// uv the lightmap was baked with.
//
// The input is re-read with tinygltf and only the primitives of generated static meshes
// change: every vertex attribute (and morph target) is re-gathered through
// MeshLightmap::source_vertex, bytes copied as stored, TEXCOORD_1 (float vec2) is
// set and the index buffer rewritten. A TEXCOORD_1 that was there (and replaced, see the
// mixed-scene policy in unwrap.h) is kept as the first free TEXCOORD_n (n >= 2), and a
// material whose core textures sample set 1 is copied with those references moved to n,
// so the surface looks as before (textures inside material extensions are not remapped).
// A primitive with a TEXCOORD_1 (written or kept) but no TEXCOORD_0 gets it as TEXCOORD_0
// too (the same accessor): glTF requires the sets to start at 0 and run without gaps.
// Everything else (nodes, materials, images, extensions, extras, untouched primitives) is
// written as tinygltf read it. All buffers are merged into one (old bytes kept, new ones
// appended): the .bin next to a .gltf output is named after it, a .glb output embeds it,
// so the input's files are never overwritten. External images are copied next to the
// output when the folders differ.
//
// Instancing: the scene gives every instance of a glTF mesh its own charts, so the first
// static node using a mesh keeps it and every further static node gets its own copy of
// the mesh (each with its own TEXCOORD_1). If a dynamic node uses the mesh too, it keeps
// the original untouched and every static node gets a copy.
#pragma once

#include <string>

#include "core/charts/gltf_lighting.h"
#include "core/charts/unwrap.h"
#include "core/common/status.h"
#include "core/scene/scene.h"
#include "core/scene/scene_files.h"

namespace lightlink::charts {

// `scene` and `atlas` are unwrap()'s output for the scene loaded from `in_path`. The output
// is glTF JSON or binary .glb by the extension of `out_path`, which must differ from
// `in_path`. An OBJ or FBX input (scene::isAssimpScenePath) is written as a fresh glTF
// from `scene` instead (gltf_scene_writer.h). The input and the images it names are read
// under `access` (scene_files.h), as the loader read them; a copied image never lands
// outside the output's folder. `lighting` adds the pointers to the baked lighting
// (gltf_lighting.h) on the static meshes that carry a lightmap uv and are not probe-lit.
Status writeGltfWithLightmapUv(const std::string& in_path, const scene::Scene& scene, const LightmapAtlas& atlas,
                               const std::string& out_path, const scene::FileAccess& access = {},
                               const GltfLighting& lighting = {});

// Whether scene mesh `m` is lit from the lightmap: static, with a lightmap uv, not probe-lit.
bool isLightmapped(const scene::Scene& scene, const LightmapAtlas& atlas, std::size_t m);

}  // namespace lightlink::charts
