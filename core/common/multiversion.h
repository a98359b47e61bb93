// LL_MULTIVERSION: a function compiled three times on x86-64 with GCC, for x86-64-v4
// (AVX-512), for AVX2 and for the baseline (SSE2), with the loader picking one at start-up
// (function multi-versioning, target_clones). The project builds for the baseline, so this is
// how its hot loops written on GCC vectors (vector_size) get 256- or 512-bit instructions on
// CPUs that have them. Elsewhere (Clang, other CPUs) it expands to nothing and the baseline
// code runs. (On AVX-512 CPUs the x86-64-v4 version makes link generation's ray directions
// markedly cheaper: precompute_bench's "rays" phase.)
//
// Rule for its users: all versions must give the same bits. x86-64-v4 implies FMA, which GCC
// would fuse a * b + c into, so contraction is off in all of them (optimize attribute); a
// function may only use operations that round the same in every lane width (adds,
// multiplies, divides, selects, moves), never a reassociated reduction. Artifacts depend on
// this (links: ray directions, SH sums, octahedral codes; rt: hits).
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define LL_MULTIVERSION __attribute__((target_clones("arch=x86-64-v4", "avx2", "default"), optimize("fp-contract=off")))
#else
#define LL_MULTIVERSION
#endif
