#include "core/scene/scene_files.h"
#include "core/scene/scene_files_unread.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>
#include <linux/openat2.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <deque>
#include <vector>

#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

namespace lightlink::scene {
namespace fs = std::filesystem;
namespace {

// URIs come from the scene; a message shows a bounded prefix of one.
std::string shortUri(std::string_view uri) {
  constexpr std::size_t kKeep = 120;
  return uri.size() <= kKeep ? std::string(uri) : std::string(uri.substr(0, kKeep)) + "...";
}

unsigned char fromHex(unsigned char c) {
  if (c >= '0' && c <= '9') return static_cast<unsigned char>(c - '0');
  if (c >= 'a' && c <= 'f') return static_cast<unsigned char>(c - 'a' + 10);
  if (c >= 'A' && c <= 'F') return static_cast<unsigned char>(c - 'A' + 10);
  return 0;
}

// The canonical form of an absolute path tinygltf asks for, if the access rules let it be
// read: relative paths are tinygltf's fallback to the working directory, always refused.
bool acceptedPath(const SceneFiles& files, const std::string& path, fs::path* canonical) {
  fs::path p(path);
  if (!p.is_absolute()) return false;
  // tinygltf joins an absolute URI to the base as "<folder>//<uri>"; where reading outside is
  // allowed, that URI means itself (as resolveUri has it). Confined, it stays a refused path.
  const std::string joined_absolute = files.folder().string() + "//";
  if (files.access().allow_outside_folder && path.rfind(joined_absolute, 0) == 0)
    p = fs::path(path.substr(joined_absolute.size() - 1));
  Expected<fs::path> resolved = resolvePath(p);
  if (!resolved) return false;
  *canonical = std::move(resolved).value();
  return files.access().allow_outside_folder || files.insideFolder(*canonical);
}

bool fileExists(const std::string& path, void* user) {
  fs::path canonical;
  if (!acceptedPath(*static_cast<const SceneFiles*>(user), path, &canonical)) return false;
  std::error_code ec;
  return fs::is_regular_file(canonical, ec);
}

std::string expandFilePath(const std::string& path, void*) { return path; }  // no ~ or $VAR expansion

bool readWholeFile(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
  fs::path canonical;
  if (!acceptedPath(*static_cast<const SceneFiles*>(user), path, &canonical)) {
    if (err) *err += "refused: outside the scene's folder\n";
    return false;
  }
  const auto& files = *static_cast<const SceneFiles*>(user);
  Expected<std::string> bytes = files.access().allow_outside_folder
                                    ? readRegularFile(canonical, "file")
                                    : readRegularFileBeneath(files.folder(), canonical, "file");
  if (!bytes) {
    if (err) *err += bytes.status().message() + "\n";
    return false;
  }
  out->assign(bytes->begin(), bytes->end());
  return true;
}

bool writeWholeFile(std::string* err, const std::string&, const std::vector<unsigned char>&, void*) {
  if (err) *err += "scene loading never writes files\n";
  return false;
}

}  // namespace

Expected<fs::path> resolvePath(const fs::path& path) {
  constexpr int kMaxLinks = 40;  // as the kernel's ELOOP limit
  std::error_code ec;
  const fs::path absolute = fs::absolute(path, ec);
  if (ec) return ioError("{}: cannot make the path absolute: {}", path.string(), ec.message());
  const fs::path relative = absolute.relative_path();
  std::deque<fs::path> rest(relative.begin(), relative.end());
  fs::path done = absolute.root_path();
  int links = 0;
  while (!rest.empty()) {
    const fs::path part = rest.front();
    rest.pop_front();
    if (part.empty() || part == ".") continue;
    if (part == "..") {
      done = done.parent_path();
      continue;
    }
    const fs::path next = done / part;
    const fs::file_status st = fs::symlink_status(next, ec);
    if (ec || !fs::is_symlink(st)) {  // a directory, a file, or nothing: taken as named
      done = next;
      continue;
    }
    if (++links > kMaxLinks) return ioError("{}: too many levels of symbolic links", path.string());
    const fs::path target = fs::read_symlink(next, ec);
    if (ec) return ioError("{}: cannot read the link {}: {}", path.string(), next.string(), ec.message());
    const fs::path target_rest = target.relative_path();
    rest.insert(rest.begin(), target_rest.begin(), target_rest.end());
    if (target.is_absolute()) done = target.root_path();
  }
  return done;
}

namespace {

// Reads the regular file open on `fd` (and closes it); anything else is refused.
Expected<std::string> readOpenedRegularFile(int fd, std::string_view what) {
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return invalidInput("{}: is not a regular file", what);
  }
  std::string bytes;
  bytes.reserve(static_cast<std::size_t>(st.st_size));
  char buffer[1 << 16];
  for (;;) {
    const ssize_t got = ::read(fd, buffer, sizeof(buffer));
    if (got == 0) break;
    if (got < 0) {
      if (errno == EINTR) continue;
      const int e = errno;
      ::close(fd);
      return ioError("{}: read failed: {}", what, std::strerror(e));
    }
    bytes.append(buffer, static_cast<std::size_t>(got));
  }
  ::close(fd);
  return bytes;
}

Status openFailed(int e, std::string_view what) {
  if (e == ENOENT || e == ENOTDIR) return notFound("{}: file not found", what);
  return ioError("{}: cannot open: {}", what, std::strerror(e));
}

}  // namespace

Expected<std::string> readRegularFile(const fs::path& path, std::string_view what) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer forever.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) return openFailed(errno, what);
  return readOpenedRegularFile(fd, what);
}

Expected<std::string> readRegularFileBeneath(const fs::path& folder, const fs::path& inside, std::string_view what) {
  // The path was checked, but a link could be swapped into it before the open: the kernel
  // resolves it again, refusing any step out of `folder` (openat2 RESOLVE_BENEATH, Linux 5.6).
  const fs::path rel = inside.lexically_relative(folder);
  if (rel.empty() || *rel.begin() == "..") return invalidInput("{}: escapes the scene's folder", what);
  const int dir = ::open(folder.c_str(), O_PATH | O_DIRECTORY | O_CLOEXEC);
  if (dir < 0) return openFailed(errno, what);
  open_how how{};
  how.flags = O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY;
  how.resolve = RESOLVE_BENEATH | RESOLVE_NO_MAGICLINKS;
  const long fd = ::syscall(SYS_openat2, dir, rel.c_str(), &how, sizeof(how));
  const int e = errno;
  ::close(dir);
  if (fd >= 0) return readOpenedRegularFile(static_cast<int>(fd), what);
  if (e == EXDEV || e == ELOOP) return invalidInput("{}: escapes the scene's folder", what);
  // Kernels before 5.6, or a sandbox that filters the call: the check above stands alone.
  if (e == ENOSYS || e == EPERM || e == E2BIG) return readRegularFile(inside, what);
  return openFailed(e, what);
}

Expected<SceneFiles> SceneFiles::forScene(const std::string& scene_path, const FileAccess& access) {
  std::error_code ec;
  const fs::path absolute = fs::absolute(scene_path, ec);
  if (ec) return ioError("{}: cannot resolve the path: {}", scene_path, ec.message());
  Expected<fs::path> folder = resolvePath(absolute.parent_path());
  if (!folder) return folder.status();
  SceneFiles files;
  files.scene_path_ = scene_path;
  files.folder_ = std::move(folder).value();
  files.access_ = access;
  return files;
}

Expected<std::string> SceneFiles::readScene() const { return readRegularFile(scene_path_, scene_path_); }

bool SceneFiles::insideFolder(const fs::path& p) const {
  const fs::path rel = p.lexically_relative(folder_);
  return !rel.empty() && *rel.begin() != "..";
}

std::string SceneFiles::decodeUri(std::string_view uri) {
  std::string out;
  out.reserve(uri.size());
  for (std::size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '+') {
      out += ' ';
    } else if (uri[i] == '%' && uri.size() > i + 2) {
      out += static_cast<char>(fromHex(static_cast<unsigned char>(uri[i + 1])) << 4 |
                               fromHex(static_cast<unsigned char>(uri[i + 2])));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

Expected<fs::path> SceneFiles::resolveUri(const std::string& uri, std::string_view what) const {
  return resolveDecoded(decodeUri(uri), uri, what);
}

Expected<fs::path> SceneFiles::resolveName(const std::string& name, std::string_view what) const {
  return resolveDecoded(name, name, what);
}

Expected<fs::path> SceneFiles::resolveDecoded(const std::string& name, std::string_view uri,
                                              std::string_view what) const {
  if (name.empty()) return invalidInput("{}: {}: the URI is empty", scene_path_, what);
  if (name.find('\0') != std::string::npos)
    return invalidInput("{}: {} '{}': a file name cannot contain a NUL byte", scene_path_, what, shortUri(uri));
  if (!access_.allow_outside_folder && name.front() == '/') {
    return invalidInput("{}: {} '{}' is an absolute path; a scene may only name files inside its own folder{}",
                        scene_path_, what, shortUri(uri), access_.outside_hint);
  }
  // Joined as tinygltf joins it (folder + '/' + name), so this is the file it would read; an
  // absolute name (allowed here only outside the folder rule) is itself, as acceptedPath has it.
  const fs::path joined = name.front() == '/' ? fs::path(name) : fs::path(folder_.string() + "/" + name);
  Expected<fs::path> resolved = resolvePath(joined);
  if (!resolved) return invalidInput("{}: {} '{}': {}", scene_path_, what, shortUri(uri), resolved.status().message());
  const fs::path& canonical = *resolved;
  if (!access_.allow_outside_folder && !insideFolder(canonical)) {
    const bool lexically_inside = insideFolder(joined.lexically_normal());
    return invalidInput("{}: {} '{}' escapes the scene's folder{}; a scene may only name files inside its own "
                        "folder{}",
                        scene_path_, what, shortUri(uri), lexically_inside ? " through a symbolic link" : "",
                        access_.outside_hint);
  }
  return canonical;
}

Expected<std::string> SceneFiles::readUri(const std::string& uri, std::string_view what) const {
  Expected<fs::path> path = resolveUri(uri, what);
  if (!path) return path.status();
  const std::string named = fmt::format("{}: {} '{}'", scene_path_, what, shortUri(uri));
  return access_.allow_outside_folder ? readRegularFile(*path, named) : readRegularFileBeneath(folder_, *path, named);
}

Expected<std::string> SceneFiles::readName(const std::string& name, std::string_view what) const {
  Expected<fs::path> path = resolveName(name, what);
  if (!path) return path.status();
  const std::string named = fmt::format("{}: {} '{}'", scene_path_, what, shortUri(name));
  return access_.allow_outside_folder ? readRegularFile(*path, named) : readRegularFileBeneath(folder_, *path, named);
}

Status SceneFiles::checkUris(std::string_view json_text) const {
  return checkUris(nlohmann::json::parse(json_text, nullptr, /*allow_exceptions=*/false));
}

Status SceneFiles::checkUris(const nlohmann::json& j) const {
  if (j.is_discarded() || !j.is_object()) return Status::ok();
  for (const char* list : {"buffers", "images"}) {
    const auto it = j.find(list);
    if (it == j.end() || !it->is_array()) continue;
    for (std::size_t i = 0; i < it->size(); ++i) {
      const nlohmann::json& entry = (*it)[i];
      if (!entry.is_object()) continue;
      const auto uri = entry.find("uri");
      if (uri == entry.end() || !uri->is_string()) continue;
      const std::string& text = uri->get_ref<const std::string&>();
      if (text.empty() || text.rfind("data:", 0) == 0) continue;
      const std::string what = fmt::format("{}[{}].uri", list, i);
      Expected<fs::path> resolved = resolveUri(text, what);
      if (!resolved) return resolved.status();
      // A FIFO or device would block or never end; stat() looks without opening it.
      std::error_code ec;
      const fs::file_status st = fs::status(*resolved, ec);
      if (!ec && fs::exists(st) && !fs::is_regular_file(st))
        return invalidInput("{}: {} '{}' is not a regular file", scene_path_, what, shortUri(text));
    }
  }
  return Status::ok();
}

namespace {

bool isUnread(const UnreadFiles& access, const std::string& path) {
  if (access.unread.empty()) return false;
  fs::path canonical;
  if (!acceptedPath(*access.files, path, &canonical)) return false;
  return std::find(access.unread.begin(), access.unread.end(), canonical) != access.unread.end();
}

bool fileExistsSkipping(const std::string& path, void* user) {
  const auto& access = *static_cast<const UnreadFiles*>(user);
  return isUnread(access, path) || fileExists(path, const_cast<SceneFiles*>(access.files));
}

bool readWholeFileSkipping(std::vector<unsigned char>* out, std::string* err, const std::string& path, void* user) {
  const auto& access = *static_cast<const UnreadFiles*>(user);
  if (isUnread(access, path)) {
    out->assign(1, 0);  // tinygltf refuses an empty image; the image loader skips this one
    return true;
  }
  return readWholeFile(out, err, path, const_cast<SceneFiles*>(access.files));
}

}  // namespace

void installSkippingUnread(const UnreadFiles& access, tinygltf::TinyGLTF& loader) {
  tinygltf::FsCallbacks callbacks{};
  callbacks.FileExists = &fileExistsSkipping;
  callbacks.ExpandFilePath = &expandFilePath;
  callbacks.ReadWholeFile = &readWholeFileSkipping;
  callbacks.WriteWholeFile = &writeWholeFile;
  callbacks.user_data = const_cast<UnreadFiles*>(&access);  // the callbacks only read it
  loader.SetFsCallbacks(callbacks);
}

void SceneFiles::install(tinygltf::TinyGLTF& loader) const {
  tinygltf::FsCallbacks callbacks{};
  callbacks.FileExists = &fileExists;
  callbacks.ExpandFilePath = &expandFilePath;
  callbacks.ReadWholeFile = &readWholeFile;
  callbacks.WriteWholeFile = &writeWholeFile;
  callbacks.user_data = const_cast<SceneFiles*>(this);  // the callbacks only read it
  loader.SetFsCallbacks(callbacks);
}

}  // namespace lightlink::scene
