// CpuPasses: the CPU backend's relight passes (RelightPasses, passes.h) — shadow rays
// through Embree for punctual lights, the pull and the bounce gather over flat arrays, cache
// lighting with the scalar or AVX2 + F16C link kernels (cache_lighting.h), all parallel
// over fixed chunks with fixed-order sums so results are identical for any thread count.
// It also keeps each light's contribution to the surfels and caches, which lets it relight
// a change of one light incrementally: only the surfels that light reaches, their tree
// paths, and the caches linked to the nodes that changed.
#pragma once

#include <memory>

#include "core/relight/passes.h"
#include "core/relight/scene_tables.h"

namespace lightlink::relight {

std::unique_ptr<RelightPasses> makeCpuPasses(const SceneTables& tables);

}  // namespace lightlink::relight
