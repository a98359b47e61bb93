// Pinpoints what is wrong in an OBJ file assimp refused or whose data failed validation:
// assimp says "vertex index out of range" without a line or an object, so the text is
// scanned for the first face corner that names no vertex (0, past the end, or a negative
// index reaching before the first vertex) or the first `v` line with a non-finite
// coordinate, and that is described by line, object (`o`/`g` name) and field. The index
// check also runs before assimp: assimp accepts a face naming a texture coordinate or
// normal that does not exist. Only well-formed numbers are judged, so text this light
// parser does not understand is left to assimp.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace lightlink::scene {

// "line 12, object 'Crate': face corner 3 names vertex 9, but the file has 8" or nothing.
// Index problems are always checked; `vertices` adds the non-finite `v` check.
std::optional<std::string> diagnoseObj(std::string_view text, bool vertices = true);

}  // namespace lightlink::scene
