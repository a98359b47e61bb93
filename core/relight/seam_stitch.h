// SeamStitch: texels on the two sides of a lightmap UV seam made to agree (what Godot's
// lightmapper and Bakery call "fix seams"), as a least-squares problem over the texels the
// seam touches.
//
// A seam is a mesh edge whose two triangles have different lightmap UVs along it: the same
// surface points are stored twice, in two charts, and bilinear lookups on the two sides
// read different texels, so a smooth surface shows a line. For every seam edge shared by
// two triangles of one static mesh that meet smoothly (normals within kSmoothSeamCos; a
// crease such as a box's edge is a real change of lighting and is left alone), samples
// along the edge (two per texel of its length) each ask that the bilinear lookups on side A
// and side B be equal. The stitched texels x minimise
//     w * sum_samples (lookup_A(x) - lookup_B(x))^2 + sum_texels (x - x0)^2
// (x0 the relit values, w = kSeamWeight): a sparse symmetric positive definite system
// whose matrix depends only on the atlas, so it is factored once (Eigen's SimplicialLDLT)
// and each relight solves it for every channel (SH coefficients, direct RGB). Deterministic:
// the system is built in mesh / edge order and solved serially.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "core/scene/scene.h"

namespace lightlink::relight {

// Two triangles meet smoothly when their geometric normals' dot product is at least this
// (30 degrees): a tessellated cylinder's facets are stitched, a box's edges are not.
inline constexpr float kSmoothSeamCos = 0.866f;
// Weight of seam agreement against staying at the relit value.
inline constexpr double kSeamWeight = 100.0;

struct SeamStats {
  std::size_t edges = 0;    // seam edges stitched
  std::size_t samples = 0;  // agreement constraints along them
  std::size_t texels = 0;   // texels the stitch may change
  // Mean |lookup_A - lookup_B| over the samples of the measured channel divided by the mean
  // of the looked-up values: the seam jump, before and after the stitch.
  double jump_before = 0.0, jump_after = 0.0;
};

class SeamStitch {
 public:
  // The seams of the scene's static lightmapped meshes on a width x height atlas (texel
  // (x, y) covers [x, x+1) x [y, y+1) of uv1 * (width, height)). Empty when there is none.
  static SeamStitch build(const scene::Scene& scene, int width, int height);

  SeamStitch();
  SeamStitch(SeamStitch&&) noexcept;
  SeamStitch& operator=(SeamStitch&&) noexcept;
  ~SeamStitch();

  bool empty() const { return texel_.empty(); }
  std::size_t edges() const { return edges_; }

  // Stitches `data` (stride floats per texel, row-major texels of the atlas) in place, every
  // channel. `stats` (optional) gets the jump of channel `measure` before and after.
  void apply(float* data, std::size_t stride, SeamStats* stats = nullptr, std::size_t measure = 0) const;

 private:
  struct Solver;
  std::size_t edges_ = 0;
  std::vector<std::uint32_t> texel_;       // variable -> texel index
  std::vector<std::uint32_t> row_begin_;   // constraint rows (CSR) over variables
  std::vector<std::uint32_t> col_;
  std::vector<float> weight_;              // side A taps positive, side B negative
  std::unique_ptr<Solver> solver_;
};

}  // namespace lightlink::relight
