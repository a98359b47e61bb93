// Procedural geometry for benchmarks that must run without scene files: a seeded "city"
// of boxes and slabs, and uniform triangle subdivision for scale tests. Both produce a
// scene::Scene exactly like glTF ingest would (world space, y up, metres, static meshes),
// with Scene::bounds and Scene::scale filled in.
#pragma once

#include <cstdint>

#include "core/scene/scene.h"

namespace lightlink::bench {

// A 2 km x 2 km city, y up: a ground quad, `lots` x `lots` buildings (10 triangles each: a
// box without its floor, random footprint in its 20 m lot, heights 5-125 m skewed low) and
// an elevated slab (a 12-triangle box) over every 8th lot. One mesh per row of lots.
// The default 100 x 100 gives 115,002 triangles.
scene::Scene makeCity(std::uint32_t seed, int lots = 100);

// Splits every triangle into 4^levels congruent ones (edges cut into 2^levels segments);
// each input triangle gets its own vertices. Normals are interpolated when present, UVs
// are dropped. Bounds and scale are unchanged.
void subdivide(scene::Scene& scene, int levels);

// Recomputes Scene::bounds and Scene::scale from the positions referenced by triangles.
void updateBounds(scene::Scene& scene);

}  // namespace lightlink::bench
