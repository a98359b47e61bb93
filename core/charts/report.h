// UnwrapReport: what the lightmap-UV stage did and how good the result is, as JSON for
// tools and as text for people. Distortion figures are over generated charts only
// (existing uv1 is checked, not measured), area-weighted for the means; see
// core/charts/flatten.h for their definitions.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

namespace lightlink::charts {

struct UnwrapReport {
  bool generated = false;           // false: every static mesh kept its TEXCOORD_1
  int meshes = 0;                   // static meshes in the atlas
  std::size_t triangles = 0;        // static triangles in the atlas
  int charts = 0;
  std::size_t planar_charts = 0, lscm_charts = 0, chart_splits = 0;
  double utilisation = 0.0;         // texels touched by charts / all pages' texels, in [0, 1]
  double max_area_stretch = 1.0, mean_area_stretch = 1.0;          // 1 = none
  double max_angle_distortion = 1.0, mean_angle_distortion = 1.0;  // 1 = conformal
  std::size_t texels_per_chart_min = 0, texels_per_chart_median = 0, texels_per_chart_max = 0;
  std::size_t overlaps = 0;         // chart-overlap texels + triangle-overlap texel centres
  std::size_t gutter_violations = 0;
  std::size_t flipped = 0;          // triangles with non-positive (or minority-sign) uv area
  std::size_t out_of_range = 0;     // uv1 coordinates outside [0, 1] (existing uv1)
  int resolution = 0;               // page width = height, texels
  int pages = 1;                    // pages stacked along v
  std::size_t probe_lit_meshes = 0; // static meshes lit from the volume, not the lightmap
  std::vector<std::string> probe_lit;  // their names
  int gutter_texels = 0;
  float texel_size_m = 0.0f;        // metres of surface per texel (generated: exact per chart
                                    // on average; kept: the layout's overall mean)
  double seconds = 0.0;             // wall time of unwrap()
  std::size_t degenerate_removed = 0, nonmanifold_split = 0;
  std::vector<std::string> warnings;

  nlohmann::json toJson() const;
  std::string toText() const;
};

}  // namespace lightlink::charts
