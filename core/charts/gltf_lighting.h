// What a baked glTF points at (docs/outputs.md, "The glTF and its lighting"): the plain RGB
// irradiance map (L0, lux) bound to every lightmapped material through the MOZ_lightmap
// vendor extension, and a root LIGHTLINK_lighting extension that describes the SH maps and
// the grid. Both glTF writers take one; `lightlink unwrap` writes none.
//
// An EXR is not a core glTF image type (PNG, JPEG only), so the irradiance texture names its
// image through the LIGHTLINK_texture_exr vendor extension and has no core `source`, as
// KHR_texture_basisu and EXT_texture_webp do for theirs: a loader that does not know the
// extension sees a texture without an image, and the file stays valid glTF.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/common/status.h"

namespace tinygltf {
class Model;
}

namespace lightlink::charts {

struct GltfLighting {
  // Uri (relative to the glTF) of the plain RGB irradiance EXR; empty when none was written,
  // then no material gets MOZ_lightmap.
  std::string irradiance_uri;
  int lightmap_texcoord = 1;  // the set the lightmap was baked with (TEXCOORD_1)
  // Body of the root LIGHTLINK_lighting extension; null: none.
  nlohmann::json description;

  bool empty() const { return irradiance_uri.empty() && description.is_null(); }
};

// Used by the writers: adds `lighting` to `model`, whose lightmapped primitives are the
// (mesh, primitive) pairs listed. A material they share with a primitive that is not
// lightmapped is copied for them, and those with no material get a default one, so
// MOZ_lightmap lands only where the lightmap uv means something. A model that is itself a
// lightmapped glTF keeps one irradiance texture (reused, not added again). Returns the
// image bound (-1: none): a file the bake wrote, which the writer must never copy over.
Expected<int> addGltfLighting(tinygltf::Model& model, const std::vector<std::pair<int, int>>& lightmapped,
                              const GltfLighting& lighting);

}  // namespace lightlink::charts
