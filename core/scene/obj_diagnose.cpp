#include "core/scene/obj_diagnose.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <vector>

#include <fmt/format.h>

namespace lightlink::scene {
namespace {

std::vector<std::string_view> splitWords(std::string_view line) {
  std::vector<std::string_view> words;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) words.push_back(line.substr(start, i - start));
  }
  return words;
}

template <class F>
void forEachLine(std::string_view text, F&& f) {
  std::size_t number = 0, start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    ++number;
    if (!f(number, text.substr(start, end - start))) return;
    start = end + 1;
  }
}

// One of "v", "vt", "vn" counted over the whole file (OBJ lets a face name later vertices).
struct Counts {
  long long v = 0, vt = 0, vn = 0;
};

std::string objectName(const std::string& object, const std::string& group) {
  if (object.empty() && group.empty()) return "(no object name)";
  if (group.empty() || group == object) return fmt::format("object '{}'", object);
  if (object.empty()) return fmt::format("group '{}'", group);
  return fmt::format("object '{}', group '{}'", object, group);
}

}  // namespace

std::optional<std::string> diagnoseObj(std::string_view text, bool vertices) {
  Counts total;
  forEachLine(text, [&](std::size_t, std::string_view line) {
    const auto w = splitWords(line);
    if (!w.empty()) {
      if (w[0] == "v") ++total.v;
      else if (w[0] == "vt") ++total.vt;
      else if (w[0] == "vn") ++total.vn;
    }
    return true;
  });

  std::optional<std::string> found;
  Counts so_far;
  std::string object, group;
  forEachLine(text, [&](std::size_t number, std::string_view line) {
    const auto w = splitWords(line);
    if (w.empty()) return true;
    if (w[0] == "o") {
      object = w.size() > 1 ? std::string(w[1]) : std::string();
      group.clear();
    } else if (w[0] == "g") {
      group = w.size() > 1 ? std::string(w[1]) : std::string();
    } else if (w[0] == "v" || w[0] == "vt" || w[0] == "vn") {
      long long& count = w[0] == "v" ? so_far.v : w[0] == "vt" ? so_far.vt : so_far.vn;
      ++count;
      for (std::size_t i = 1; vertices && i < w.size() && i <= 3; ++i) {
        const std::string word(w[i]);
        char* end = nullptr;
        const double value = std::strtod(word.c_str(), &end);
        if (end != word.c_str() && !std::isfinite(value)) {
          static const char* const kAxis[] = {"x", "y", "z"};
          found = fmt::format("line {}: {} {} has a non-finite {} ({})", number, w[0], count, kAxis[i - 1], word);
          return false;
        }
      }
    } else if (w[0] == "f" || w[0] == "l" || w[0] == "p") {
      for (std::size_t corner = 1; corner < w.size(); ++corner) {
        std::string_view rest = w[corner];
        static const char* const kKinds[] = {"vertex", "texture coordinate", "normal"};
        const long long totals[] = {total.v, total.vt, total.vn};
        const long long before[] = {so_far.v, so_far.vt, so_far.vn};
        for (int slot = 0; slot < 3 && !rest.empty(); ++slot) {
          const std::size_t slash = rest.find('/');
          const std::string part(rest.substr(0, slash));
          rest = slash == std::string_view::npos ? std::string_view() : rest.substr(slash + 1);
          if (part.empty()) continue;
          char* end = nullptr;
          errno = 0;
          const long long index = std::strtoll(part.c_str(), &end, 10);
          if (end == part.c_str()) continue;  // not a number: assimp's message stands
          const long long resolved = index < 0 ? before[slot] + index + 1 : index;
          if (index == 0 || errno == ERANGE || resolved < 1 || resolved > totals[slot]) {
            found = fmt::format("line {}, {}: {} corner {} names {} {}, but the file has {}", number,
                                objectName(object, group), w[0] == "f" ? "face" : "element", corner, kKinds[slot],
                                index, totals[slot]);
            return false;
          }
        }
      }
    }
    return true;
  });
  return found;
}

}  // namespace lightlink::scene
