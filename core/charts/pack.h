// Packing: places every chart in one square atlas of texels.
//
// Each chart is first rotated so its minimal-area bounding rectangle (rotating calipers on
// the convex hull of its uv) is axis-aligned and wider than tall. At a texel size (metres
// per texel) a chart then has a mask: the texels its triangles touch when rasterised
// conservatively, its box's lower-left corner half a texel inside the first texel. The
// packer is a skyline packer at texel granularity: the atlas keeps one height per texel
// column, a chart is described per column by the lowest and highest texel of its mask,
// so a chart's ragged bottom settles into the ragged top of what lies below instead of
// resting on bounding boxes. Charts go largest first; each tries its four quarter turns at
// every column and takes the lowest resulting top (ties: fewer quarter turns, then left).
// A placed chart raises the heights by its top plus `gutter` over its columns widened by
// `gutter` on both sides, and the outer `gutter` texels of the atlas stay empty, so two
// charts (or a chart and the border) are always more than `gutter` texels apart. The
// strip is packed without a height limit: the height used tells the caller how far the
// texel size is from filling the square, which drives its search in a few packs.
// Paged packing (`page_rows` > 0) stacks square pages of `resolution` texels along y
// instead: a chart goes onto the first page where it fits below the page's top gutter
// (first fit, so small charts fill the gaps of earlier pages), else onto a new page; no
// chart straddles two pages, so each page is a self-contained atlas. Integer arithmetic in
// a fixed order: deterministic.
#pragma once

#include <cstdint>
#include <vector>

#include "core/common/progress.h"
#include "core/charts/flatten.h"

namespace lightlink::charts {

// Rotates the chart's uv (metres) to its minimal-area box, width >= height, min corner at 0.
void alignToMinimalBox(Chart& chart);

struct Placement {
  int x = 0, y = 0;          // atlas texel of the rotated mask's lower-left corner
  int width = 0, height = 0; // mask size in texels before rotation
  int quarter_turns = 0;     // counter-clockwise, 0..3
};

// Packs all charts (aligned, uv in metres) at `texel_m` into a strip `resolution` texels
// wide and as tall as needed. Returns the rows used including the bottom gutter (the
// charts fit a square atlas iff that is <= resolution - gutter), or -1 if some chart is
// wider than the strip in every orientation. A chart larger than the strip is refused
// before its mask is built, so an absurdly small texel size costs nothing. `progress` is
// polled for cancellation only: a cancelled pack returns -1 too.
int packCharts(const std::vector<Chart>& charts, double texel_m, int resolution, int gutter,
               std::vector<Placement>& placements, const Progress* progress = nullptr);

// Paged packing: every chart on one of as many `resolution` x `resolution` pages as needed,
// page p's rows at [p * resolution, (p + 1) * resolution) of the placements' y. Returns the
// page count, or -1 if some chart does not fit an empty page (or on cancellation).
int packChartsPaged(const std::vector<Chart>& charts, double texel_m, int resolution, int gutter,
                    std::vector<Placement>& placements, const Progress* progress = nullptr);

// Texels along the longer side of a chart's mask at `texel_m` (the packer's rounding).
int chartMaskSide(const Chart& chart, double texel_m);

// Moves a chart's uv from metres (aligned box) to atlas texel coordinates per placement.
void applyPlacement(Chart& chart, const Placement& placement, double texel_m);

}  // namespace lightlink::charts
