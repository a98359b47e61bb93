// Static files for the gateway: a URL path resolved inside one root folder (never outside
// it, symbolic links included), and a file streamed with its content type.
#pragma once

#include <filesystem>
#include <string>

#include "core/common/status.h"

namespace httplib {
struct Response;
}

namespace lightlink::gateway {

// `rel` (a decoded URL path below the root) as a file inside `root` (canonical). Refused:
// `..`, hidden names (a leading '.'), and anything whose real path leaves the root.
Expected<std::filesystem::path> resolveInside(const std::filesystem::path& root, const std::string& rel);

// The file as the response (200), or a 404 JSON error naming it.
void serveFile(const std::filesystem::path& path, httplib::Response& res);

// The Content-Type for a file name (the types the viewer and bakes use; else octet-stream).
const char* contentTypeOf(const std::filesystem::path& path);

}  // namespace lightlink::gateway
