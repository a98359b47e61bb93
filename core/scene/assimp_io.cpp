#include "core/scene/assimp_io.h"

#include <algorithm>
#include <cstring>

#include <assimp/MemoryIOWrapper.h>

namespace lightlink::scene {
namespace fs = std::filesystem;

std::string ConfinedIOSystem::normalise(const std::string& name) const {
  std::string out = name;
  std::replace(out.begin(), out.end(), '\\', '/');
  const std::string folder = files_.folder().string() + "/";
  if (out.rfind(folder, 0) == 0) out.erase(0, folder.size());
  while (out.rfind("./", 0) == 0) out.erase(0, 2);
  return out;
}

bool ConfinedIOSystem::Exists(const char* file) const {
  if (file == nullptr) return false;
  const std::string name = normalise(file);
  // Only a read is refused loudly (Open): a probe that finds nothing reads nothing.
  Expected<fs::path> path = files_.resolveName(name, what_);
  if (!path) return false;
  std::error_code ec;
  if (fs::is_regular_file(*path, ec)) return true;
  if (std::find(missing_.begin(), missing_.end(), name) == missing_.end()) missing_.push_back(name);
  return false;
}

Assimp::IOStream* ConfinedIOSystem::Open(const char* file, const char* mode) {
  if (file == nullptr) return nullptr;
  if (mode != nullptr && (std::strchr(mode, 'w') || std::strchr(mode, 'a') || std::strchr(mode, '+'))) {
    if (refused_.empty())
      refused_ = fmt::format("{}: scene loading never writes files ('{}')", files_.scenePath(), file);
    return nullptr;
  }
  const std::string name = normalise(file);
  Expected<std::string> bytes = files_.readName(name, what_);
  if (!bytes) {
    if (bytes.status().code() == Code::kNotFound) {
      if (std::find(missing_.begin(), missing_.end(), name) == missing_.end()) missing_.push_back(name);
    } else if (refused_.empty()) {
      refused_ = bytes.status().message();
    }
    return nullptr;
  }
  auto* buffer = new uint8_t[std::max<std::size_t>(bytes->size(), 1)];
  std::memcpy(buffer, bytes->data(), bytes->size());
  return new Assimp::MemoryIOStream(buffer, bytes->size(), /*own=*/true);
}

void ConfinedIOSystem::Close(Assimp::IOStream* stream) { delete stream; }

}  // namespace lightlink::scene
