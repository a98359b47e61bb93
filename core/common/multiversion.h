// LL_MULTIVERSION: a function compiled twice on x86-64 with GCC, for AVX2 and for the
// baseline (SSE2), with the loader picking one at start-up (function multi-versioning,
// target_clones). The project builds for the baseline, so this is how its hot loops written
// on GCC vectors (vector_size) get 256-bit instructions on CPUs that have them. Elsewhere
// (Clang, other CPUs) it expands to nothing and the baseline code runs.
//
// Rule for its users: both versions must give the same bits. AVX2 does not imply FMA, so no
// multiply-add is fused; a function may only use operations that round the same in every
// lane width (adds, multiplies, divides, selects, moves), never a reassociated reduction.
// Artifacts depend on this (links: ray directions, SH sums, octahedral codes; rt: hits).
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define LL_MULTIVERSION __attribute__((target_clones("avx2", "default")))
#else
#define LL_MULTIVERSION
#endif
