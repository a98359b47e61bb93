// The GLSL sources of shaders/, embedded into the binary at build time (embed.cmake), so a
// deployed `lightlink` or daemon needs no shader files next to it. Names are the file names
// (naming scheme in shaders/README.md); gpu compiles them with GL at start-up.
#pragma once

#include <optional>
#include <span>
#include <string_view>

namespace lightlink::shaders {

struct EmbeddedShader {
  std::string_view name;    // e.g. "cache_light.comp"
  std::string_view source;  // the file's text
};

std::span<const EmbeddedShader> all();
// The source of `name`, or nullopt when no such shader was embedded.
std::optional<std::string_view> find(std::string_view name);

}  // namespace lightlink::shaders
