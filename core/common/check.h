// LL_CHECK: invariants that must hold in release builds too. On failure it prints the
// expression, both operands where given, and the location, then aborts: a failed
// invariant is a bug in lightlink, never a user error (those are Status values).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>

#include <fmt/format.h>

namespace lightlink::detail {
[[noreturn]] inline void checkFailed(const char* file, int line, const std::string& what) {
  std::fprintf(stderr, "%s:%d: CHECK failed: %s\n", file, line, what.c_str());
  std::abort();
}
}  // namespace lightlink::detail

#define LL_CHECK(cond)                                                            \
  do {                                                                            \
    if (!(cond)) ::lightlink::detail::checkFailed(__FILE__, __LINE__, #cond);     \
  } while (0)

#define LL_CHECK_OP(a, op, b)                                                         \
  do {                                                                                \
    const auto& ll_a_ = (a);                                                          \
    const auto& ll_b_ = (b);                                                          \
    if (!(ll_a_ op ll_b_))                                                            \
      ::lightlink::detail::checkFailed(                                               \
          __FILE__, __LINE__, fmt::format("{} {} {} ({} vs {})", #a, #op, #b, ll_a_, ll_b_)); \
  } while (0)

#define LL_CHECK_EQ(a, b) LL_CHECK_OP(a, ==, b)
#define LL_CHECK_LT(a, b) LL_CHECK_OP(a, <, b)
#define LL_CHECK_LE(a, b) LL_CHECK_OP(a, <=, b)
#define LL_CHECK_GT(a, b) LL_CHECK_OP(a, >, b)
#define LL_CHECK_GE(a, b) LL_CHECK_OP(a, >=, b)
