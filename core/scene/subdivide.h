// Midpoint subdivision of every triangle into four, for scale tests and benchmarks (the
// largest shared scene has 58k triangles; two levels give the ~235k-triangle case of the
// precompute target). Edge midpoints are shared between neighbouring triangles so the
// mesh stays connected; every attribute is interpolated linearly (normals renormalised).
// Lighting-wise the scene is unchanged: same surfaces, same materials.
#pragma once

#include "core/scene/scene.h"

namespace lightlink::scene {

// Splits every triangle of every mesh `levels` times (x 4^levels triangles).
void subdivide(Scene& scene, int levels);

}  // namespace lightlink::scene
