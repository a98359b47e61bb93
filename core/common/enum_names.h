// One table per enum: an enum's names live in one constexpr table of (name, value) pairs
// beside the enum, and every parser, canonical string, report and benchmark reads it through
// these lookups, so a value is spelled one way everywhere.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string_view>
#include <utility>

namespace lightlink {

template <typename E, std::size_t N>
using EnumNames = std::array<std::pair<std::string_view, E>, N>;

// The name of `value` in `table` ("?" for a value the table does not list).
template <typename E, std::size_t N>
constexpr std::string_view enumName(const EnumNames<E, N>& table, E value) {
  for (const auto& [name, v] : table)
    if (v == value) return name;
  return "?";
}

// The value named `name` in `table`, if any.
template <typename E, std::size_t N>
constexpr std::optional<E> enumValue(const EnumNames<E, N>& table, std::string_view name) {
  for (const auto& [n, v] : table)
    if (n == name) return v;
  return std::nullopt;
}

}  // namespace lightlink
