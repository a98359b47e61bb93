// Procedural meshes for charting tests and benchmarks, built the way exporters write
// them: vertices split along uv seams and hard edges (so welding has work to do), counter-
// clockwise front faces, world space. makeScene wraps meshes in a Scene with bounds and
// scale set as the glTF loader would.
#pragma once

#include <vector>

#include "core/scene/scene.h"

namespace lightlink::charts::test_meshes {

// Latitude-longitude sphere; the seam column of vertices is duplicated.
scene::MeshInstance sphere(float radius, int segments, int rings);
// Torus around +Y; both seams duplicated.
scene::MeshInstance torus(float major_radius, float minor_radius, int segments, int sides);
// Axis-aligned cube, each face its own vertices (hard edges), `divisions` quads per side.
scene::MeshInstance cube(float size, int divisions);
// Square in the XZ plane (normal +Y) of n x n quads with square holes: every quad whose
// cell (i, j) has i % 4 == 1 and j % 4 == 1 is left out.
scene::MeshInstance planeWithHoles(float size, int n);
// 1-to-4 midpoint subdivision (shared edges get one midpoint), for scaling benchmarks.
scene::MeshInstance subdivided(const scene::MeshInstance& mesh);
// A scene holding `meshes`, bounds and scale computed.
scene::Scene makeScene(std::vector<scene::MeshInstance> meshes);

}  // namespace lightlink::charts::test_meshes
