#include "core/charts/report.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

namespace lightlink::charts {

nlohmann::json UnwrapReport::toJson() const {
  nlohmann::json j;
  j["generated"] = generated;
  j["meshes"] = meshes;
  j["triangles"] = triangles;
  j["charts"] = charts;
  j["planar_charts"] = planar_charts;
  j["lscm_charts"] = lscm_charts;
  j["chart_splits"] = chart_splits;
  j["utilisation"] = utilisation;
  j["max_area_stretch"] = max_area_stretch;
  j["mean_area_stretch"] = mean_area_stretch;
  j["max_angle_distortion"] = max_angle_distortion;
  j["mean_angle_distortion"] = mean_angle_distortion;
  j["texels_per_chart"] = {{"min", texels_per_chart_min},
                           {"median", texels_per_chart_median},
                           {"max", texels_per_chart_max}};
  j["overlaps"] = overlaps;
  j["gutter_violations"] = gutter_violations;
  j["flipped"] = flipped;
  j["out_of_range"] = out_of_range;
  j["resolution"] = resolution;
  j["pages"] = pages;
  j["probe_lit_meshes"] = probe_lit_meshes;
  j["probe_lit"] = probe_lit;
  j["gutter_texels"] = gutter_texels;
  j["texel_size_m"] = texel_size_m;
  j["seconds"] = seconds;
  j["degenerate_removed"] = degenerate_removed;
  j["nonmanifold_split"] = nonmanifold_split;
  j["warnings"] = warnings;
  return j;
}

std::string UnwrapReport::toText() const {
  std::string s;
  s += fmt::format("lightmap uv: {} ({} static meshes, {} triangles)\n",
                   generated ? "generated" : "kept existing TEXCOORD_1", meshes, triangles);
  s += fmt::format("  atlas        {0} page{1} of {2}x{2} texels, {3:.4g} m/texel, gutter {4}\n", pages,
                   pages == 1 ? "" : "s", resolution, texel_size_m, gutter_texels);
  if (probe_lit_meshes > 0)
    s += fmt::format("  probe-lit    {} static meshes too small for the lightmap (lit from the volume)\n",
                     probe_lit_meshes);
  if (generated) {
    s += fmt::format("  charts       {} ({} planar, {} LSCM, {} splits)\n", charts, planar_charts,
                     lscm_charts, chart_splits);
    s += fmt::format("  texels/chart min {} median {} max {}\n", texels_per_chart_min,
                     texels_per_chart_median, texels_per_chart_max);
    s += fmt::format("  area stretch max {:.3f} mean {:.3f}; angle distortion max {:.3f} mean {:.3f}\n",
                     max_area_stretch, mean_area_stretch, max_angle_distortion, mean_angle_distortion);
  }
  s += fmt::format("  utilisation  {:.1f} %\n", 100.0 * utilisation);
  s += fmt::format("  overlaps     {}  gutter violations {}  flipped {}  out of [0,1] {}\n", overlaps,
                   gutter_violations, flipped, out_of_range);
  s += fmt::format("  mesh prep    {} degenerate removed, {} non-manifold split\n", degenerate_removed,
                   nonmanifold_split);
  s += fmt::format("  time         {:.3f} s\n", seconds);
  for (const std::string& w : warnings) s += fmt::format("  warning: {}\n", w);
  return s;
}

}  // namespace lightlink::charts
