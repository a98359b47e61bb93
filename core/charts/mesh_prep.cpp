#include "core/charts/mesh_prep.h"

#include <array>
#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>

#include "core/common/check.h"

namespace lightlink::charts {
namespace {

// Only connectivity is asked of OpenMesh; positions are kept in our own double array.
struct ConnectivityTraits : OpenMesh::DefaultTraits {
  using Point = OpenMesh::Vec3d;
};
using TriMesh = OpenMesh::TriMesh_ArrayKernelT<ConnectivityTraits>;

struct CellKey {
  std::int64_t x, y, z;
  bool operator==(const CellKey&) const = default;
};
struct CellHash {
  std::size_t operator()(const CellKey& k) const {
    // Large odd multipliers spread neighbouring cells over the buckets.
    return static_cast<std::size_t>(k.x * 73856093LL ^ k.y * 19349663LL ^ k.z * 83492791LL);
  }
};

// Welds positions that lie within `tol` of an earlier representative. Cells are `tol`
// wide, so a match can only be in the 27 cells around the point; first come, first
// served in vertex order, which keeps the result deterministic.
std::vector<std::uint32_t> weld(const std::vector<glm::vec3>& in, double tol,
                                std::vector<glm::dvec3>& reps) {
  std::vector<std::uint32_t> remap(in.size());
  std::unordered_map<CellKey, std::uint32_t, CellHash> head;
  head.reserve(in.size() * 2);
  std::vector<std::int64_t> chain;  // next representative in the same cell, -1 = end
  const double inv = 1.0 / tol;
  const double tol2 = tol * tol;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const glm::dvec3 p(in[i]);
    const CellKey c{static_cast<std::int64_t>(std::floor(p.x * inv)),
                    static_cast<std::int64_t>(std::floor(p.y * inv)),
                    static_cast<std::int64_t>(std::floor(p.z * inv))};
    std::int64_t found = -1;
    for (int dz = -1; dz <= 1 && found < 0; ++dz)
      for (int dy = -1; dy <= 1 && found < 0; ++dy)
        for (int dx = -1; dx <= 1 && found < 0; ++dx) {
          auto it = head.find({c.x + dx, c.y + dy, c.z + dz});
          if (it == head.end()) continue;
          for (std::int64_t r = it->second; r >= 0; r = chain[static_cast<std::size_t>(r)]) {
            const glm::dvec3 d = reps[static_cast<std::size_t>(r)] - p;
            if (glm::dot(d, d) <= tol2) {
              found = r;
              break;
            }
          }
        }
    if (found < 0) {
      found = static_cast<std::int64_t>(reps.size());
      reps.push_back(p);
      auto [it, inserted] = head.try_emplace(c, static_cast<std::uint32_t>(found));
      chain.push_back(inserted ? -1 : static_cast<std::int64_t>(it->second));
      it->second = static_cast<std::uint32_t>(found);
    }
    remap[i] = static_cast<std::uint32_t>(found);
  }
  return remap;
}

}  // namespace

PreparedMesh prepareMesh(const scene::MeshInstance& mesh, double weld_tolerance_m) {
  PreparedMesh out;
  const std::vector<std::uint32_t> remap = weld(mesh.positions, weld_tolerance_m, out.positions);

  // OpenMesh reports refused faces on its (process-wide) error stream; refusals are
  // expected here and counted in nonmanifold_split instead. Silenced once, before any
  // thread can be adding faces.
  static const bool silenced = [] {
    omerr().disable();
    return true;
  }();
  (void)silenced;
  TriMesh om;
  const std::size_t tri_count = mesh.triangleCount();
  om.reserve(out.positions.size() + 64, tri_count * 3 / 2 + 64, tri_count);
  for (const glm::dvec3& p : out.positions) om.add_vertex(TriMesh::Point(p.x, p.y, p.z));

  out.corners.reserve(tri_count * 3);
  out.source_face.reserve(tri_count);
  out.face_normals.reserve(tri_count);
  out.face_areas.reserve(tri_count);
  for (std::size_t t = 0; t < tri_count; ++t) {
    std::array<std::uint32_t, 3> v{remap[mesh.indices[3 * t]], remap[mesh.indices[3 * t + 1]],
                                   remap[mesh.indices[3 * t + 2]]};
    if (v[0] == v[1] || v[1] == v[2] || v[2] == v[0]) {
      ++out.degenerate_removed;
      continue;
    }
    const glm::dvec3 e1 = out.positions[v[1]] - out.positions[v[0]];
    const glm::dvec3 e2 = out.positions[v[2]] - out.positions[v[0]];
    const glm::dvec3 e3 = out.positions[v[2]] - out.positions[v[1]];
    const glm::dvec3 cr = glm::cross(e1, e2);
    const double twice_area = glm::length(cr);
    const double longest = std::sqrt(std::max({glm::dot(e1, e1), glm::dot(e2, e2), glm::dot(e3, e3)}));
    // Height over the longest edge below the weld tolerance: a needle or a sliver that
    // welding would have flattened had the vertices been a little closer.
    if (!(twice_area > weld_tolerance_m * longest)) {
      ++out.degenerate_removed;
      continue;
    }
    auto fh = om.add_face(TriMesh::VertexHandle(static_cast<int>(v[0])),
                          TriMesh::VertexHandle(static_cast<int>(v[1])),
                          TriMesh::VertexHandle(static_cast<int>(v[2])));
    if (!fh.is_valid()) {
      // Complex edge/vertex or inconsistent orientation: move the face onto copies of as
      // few of its vertices as possible (one, then two, then all three), so it usually
      // stays attached to its neighbours through the edges that were fine. Copies made for
      // a failed trial stay unused (isolated) in both arrays, which keeps ids in step.
      static constexpr int kTrials[7][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0},
                                            {0, 1, 1}, {1, 0, 1}, {1, 1, 1}};
      std::array<std::int64_t, 3> copy{-1, -1, -1};
      std::array<std::uint32_t, 3> trial = v;
      for (const auto& dup : kTrials) {
        for (int k = 0; k < 3; ++k) {
          if (dup[k] && copy[k] < 0) {
            const glm::dvec3 p = out.positions[v[k]];
            copy[k] = static_cast<std::int64_t>(out.positions.size());
            out.positions.push_back(p);
            om.add_vertex(TriMesh::Point(p.x, p.y, p.z));
          }
          trial[k] = dup[k] ? static_cast<std::uint32_t>(copy[k]) : v[k];
        }
        fh = om.add_face(TriMesh::VertexHandle(static_cast<int>(trial[0])),
                         TriMesh::VertexHandle(static_cast<int>(trial[1])),
                         TriMesh::VertexHandle(static_cast<int>(trial[2])));
        if (fh.is_valid()) break;
      }
      v = trial;
      ++out.nonmanifold_split;
    }
    LL_CHECK(fh.is_valid());
    LL_CHECK_EQ(static_cast<std::size_t>(fh.idx()), out.source_face.size());
    out.corners.insert(out.corners.end(), v.begin(), v.end());
    out.source_face.push_back(static_cast<std::uint32_t>(t));
    out.face_normals.push_back(cr / twice_area);
    out.face_areas.push_back(0.5 * twice_area);
  }

  // Face-across-edge table from the halfedge structure: opposite halfedge, its face.
  const std::size_t faces = out.source_face.size();
  out.neighbors.assign(faces * 3, -1);
  for (std::size_t f = 0; f < faces; ++f) {
    for (int k = 0; k < 3; ++k) {
      const TriMesh::VertexHandle a(static_cast<int>(out.corners[3 * f + k]));
      const TriMesh::VertexHandle b(static_cast<int>(out.corners[3 * f + (k + 1) % 3]));
      const TriMesh::HalfedgeHandle heh = om.find_halfedge(a, b);
      LL_CHECK(heh.is_valid());
      const TriMesh::FaceHandle across = om.face_handle(om.opposite_halfedge_handle(heh));
      if (across.is_valid()) out.neighbors[3 * f + k] = across.idx();
    }
  }
  return out;
}

}  // namespace lightlink::charts
