// Mesh preparation: turns one scene::MeshInstance (an indexed triangle soup whose vertices
// are split wherever normals or texture coordinates differ) into the connected surface the
// charting works on.
//
// Vertices are welded by position (tolerance in metres, relative to the scene scale, so
// UV and normal seams do not cut the surface), the faces are inserted into an OpenMesh
// TriMesh, which is the authority on manifoldness: a face OpenMesh refuses (complex edge or
// complex vertex) is split off onto duplicated vertices instead of being dropped. Faces
// that collapse under welding or whose height is below the weld tolerance are removed and
// counted. The result is flattened into plain arrays (corner vertices, face-across-edge
// neighbours, normals, areas) because every later stage runs hot loops over them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "core/scene/scene.h"

namespace lightlink::charts {

struct PreparedMesh {
  std::vector<glm::dvec3> positions;        // world, metres, per prepared vertex
  std::vector<std::uint32_t> corners;       // 3 prepared vertex ids per face, source winding
  std::vector<std::int32_t> neighbors;      // 3 per face: face across edge (c[k], c[k+1]), -1 = border
  std::vector<std::uint32_t> source_face;   // per face: triangle index in the MeshInstance
  std::vector<glm::dvec3> face_normals;     // unit, from the welded positions
  std::vector<double> face_areas;           // m^2

  std::size_t degenerate_removed = 0;  // faces collapsed by welding or thinner than the tolerance
  std::size_t nonmanifold_split = 0;   // faces moved onto duplicated vertices

  std::size_t faceCount() const { return source_face.size(); }
};

// weld_tolerance_m: vertices closer than this are one vertex; also the minimum triangle
// height below which a face counts as degenerate.
PreparedMesh prepareMesh(const scene::MeshInstance& mesh, double weld_tolerance_m);

}  // namespace lightlink::charts
