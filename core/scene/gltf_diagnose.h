// Internal to core/scene: explains a tinygltf load failure in lightlink's terms.
//
// tinygltf stops at the first problem with a message that often omits which object
// failed (e.g. "File size mismatch", or a whole data URI pasted into the text). When it
// fails, the JSON is re-read here to find the cause we can name precisely: a syntax error
// or a number that overflows to infinity (named by its JSON path, "nodes[0].scale[1]"), a
// required extension we do not support, a buffer whose byteLength disagrees with its
// data, or the JSON path of the member a tinygltf schema message complains about.
#pragma once

#include <optional>
#include <string>

#include "core/common/status.h"
#include "core/scene/scene_files.h"

namespace lightlink::scene::gltf {

// A precise Status for the failure of the scene `files` names (whose bytes are `bytes`), or
// nullopt when none of the known causes applies (the caller then reports tinygltf's own message).
// `tinygltf_error` is tinygltf's message; for its schema complaints ("'count' property is
// not a positive integer") the offending member is located and named by JSON path.
std::optional<Status> diagnoseLoadFailure(const SceneFiles& files, const std::string& bytes, bool binary,
                                          const std::string& tinygltf_error);

// tinygltf's message, with data URIs cut short and the length capped for display.
std::string shortenTinygltfMessage(const std::string& message);

}  // namespace lightlink::scene::gltf
