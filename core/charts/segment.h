// Charting: splits a PreparedMesh into charts by greedy region growing.
//
// A chart starts at the lowest-numbered unassigned face and grows across its border one
// face at a time, cheapest first, where the cost of adding face f to chart C is
//
//   cost(f, C) = (1 - n_f . N_C)  +  compactness_weight * |c_f - s_C| / sqrt(A_C / pi)
//
// n_f the face normal, N_C the chart's area-weighted mean normal, c_f the face centroid,
// s_C the seed face centroid and A_C the chart area: the first term keeps the chart flat
// (planarity), the second keeps it round (compactness: the distance from the seed in units
// of the radius of a disc with the chart's area, ~1 on the front of a round chart). A face
// is only taken if its normal lies within `normal_cone_deg` of N_C, which bounds how far a
// chart bends and therefore the distortion of flattening it. Edges whose dihedral angle
// exceeds `hard_edge_deg` are never crossed, nor are mesh borders (each MeshInstance has
// one material, so material boundaries are mesh borders and always chart borders).
// Borders are then smoothed: a face with two neighbours in another chart moves there if
// that chart's cone and the hard edges allow it (removes one-face spikes and notches).
// Deterministic: seeds in face order, ties broken by face index.
#pragma once

#include <cstdint>
#include <vector>

#include "core/charts/mesh_prep.h"

namespace lightlink::charts {

struct SegmentOptions {
  double normal_cone_deg = 60.0;      // max angle between a face normal and the chart normal
  double hard_edge_deg = 60.0;        // dihedral angle above which an edge is a chart border
  double compactness_weight = 0.25;   // weight of the compactness term against planarity
};

struct Segmentation {
  std::vector<std::uint32_t> face_chart;  // per face, chart index in [0, chart_count)
  std::uint32_t chart_count = 0;
};

Segmentation segmentCharts(const PreparedMesh& mesh, const SegmentOptions& options);

}  // namespace lightlink::charts
