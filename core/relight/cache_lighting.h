// Cache lighting kernels (internal to core/relight): L_cache = sum_links B_node F_node for
// one cache, in both link forms, as a scalar reference and as AVX2 + F16C kernels.
//
// This is the hot loop of a relight (seed 000 sec 4.7): it streams every link's bytes once,
// so it is memory-bound for the projected form and ALU-bound for the runtime form. Node
// radiosity is read as interleaved (R, G, B, 0) float quadruples: a link touches one cache
// line of node data instead of three. The SIMD kernels are compiled
// with __attribute__((target)) in the same translation unit and chosen at run time
// (isaAtLeast(Isa::kAvx2), isa.h), so the library runs on any x86-64 and no build flag
// changes the result of the scalar path. Each kernel sums one cache's links in
// a fixed order, so results do not depend on how caches are split across threads; SIMD and
// scalar sum in different orders and agree to float rounding (tests/relight).
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/links/links.h"

namespace lightlink::relight::detail {

struct NodeRadiance {
  const float* rgbx;  // 4 floats per node: R, G, B, unused (0)
};

// out[ch * nc + i] for ch in {R, G, B}, i < nc = bands^2 (bands = output bands).
// Projected: coefficient stride view.bands^2, output bands <= view.bands.
void lightCacheProjectedScalar(const links::LinksView& view, std::size_t cache, int bands,
                               const NodeRadiance& node, float* out);
void lightCacheRuntimeScalar(const links::LinksView& view, std::size_t cache, int bands,
                             const NodeRadiance& node, float* out);
void lightCacheProjectedAvx2(const links::LinksView& view, std::size_t cache, int bands,
                             const NodeRadiance& node, float* out);
void lightCacheRuntimeAvx2(const links::LinksView& view, std::size_t cache, int bands,
                           const NodeRadiance& node, float* out);

// A plain read of the same link bytes (sums them as integers so the loads cannot be
// optimised away): the benchmark's bandwidth yardstick. Returns the checksum.
std::uint64_t streamLinkBytes(const links::LinksView& view, std::size_t cache_begin, std::size_t cache_end,
                              bool projected);


}  // namespace lightlink::relight::detail
