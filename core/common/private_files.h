// Private files and directories: what lightlink writes into its caches (artifacts, inline
// scene uploads, sessions.json) may be scene data or secrets, so files are created 0600 and
// directories 0700 whatever the umask, and a cache file is read only when it is a regular
// file (a FIFO or device planted under a cache name must never block a reader).
#pragma once

#include <string>

#include "core/common/status.h"

namespace lightlink {

inline constexpr unsigned kPrivateFileMode = 0600;
inline constexpr unsigned kPrivateDirMode = 0700;

// Creates `dir` and its missing parents with mode 0700 (set explicitly, not through the
// umask). Existing directories keep their mode. An existing non-directory is an error.
Status createPrivateDirectories(const std::string& dir);

// Opens `path` for reading without ever blocking on it: O_NONBLOCK while opening (a FIFO
// without a writer would hang a plain open), then the file must be a regular file.
// Returns the descriptor (blocking mode restored), or kNotFound when missing and
// kInvalidInput naming the kind of file when it is not regular.
Expected<int> openRegularFileForReading(const std::string& path, const char* what);

}  // namespace lightlink
