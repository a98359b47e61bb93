#include "core/common/private_files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

namespace lightlink {
namespace {

const char* fileKind(mode_t mode) {
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISDIR(mode)) return "a directory";
  return "not a regular file";
}

}  // namespace

Status createPrivateDirectories(const std::string& dir) {
  namespace fs = std::filesystem;
  if (dir.empty()) return invalidInput("directory: empty path");
  std::vector<fs::path> missing;
  std::error_code ec;
  for (fs::path p = fs::path(dir).lexically_normal(); !p.empty(); p = p.parent_path()) {
    if (fs::exists(p, ec)) break;
    missing.push_back(p);
    if (p == p.parent_path()) break;
  }
  for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
    if (::mkdir(it->c_str(), kPrivateDirMode) != 0 && errno != EEXIST)
      return ioError("cannot create directory {}: {}", it->string(), std::strerror(errno));
    ::chmod(it->c_str(), kPrivateDirMode);  // the umask may have taken bits away; never adds
  }
  if (!fs::is_directory(dir, ec)) return ioError("{} exists and is not a directory", dir);
  return {};
}

Expected<int> openRegularFileForReading(const std::string& path, const char* what) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
  if (fd < 0) {
    if (errno == ENOENT) return notFound("{} {} does not exist", what, path);
    return ioError("cannot open {} {}: {}", what, path, std::strerror(errno));
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd);
    return ioError("cannot stat {} {}: {}", what, path, why);
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    return invalidInput("{} {} is {}, not a regular file; ignored", what, path, fileKind(st.st_mode));
  }
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  return fd;
}

}  // namespace lightlink
