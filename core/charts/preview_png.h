// Chart-layout preview for people: the lightmap atlas as an RGB PNG, each chart filled
// with a colour derived from its id (existing uv1: from the mesh index), the triangle
// wireframe drawn darker on top, empty texels dark grey. Row 0 is v = 0 (glTF's top).
// Atlases above `max_size` are drawn scaled down to it.
#pragma once

#include <string>

#include "core/charts/unwrap.h"
#include "core/common/status.h"
#include "core/scene/scene.h"

namespace lightlink::charts {

Status writeChartPreviewPng(const scene::Scene& scene, const LightmapAtlas& atlas, const std::string& png_path,
                            int max_size = 2048);

}  // namespace lightlink::charts
