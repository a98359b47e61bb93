#include "clients/gateway/static_files.h"

#include <fstream>
#include <memory>

#include <fmt/format.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

namespace lightlink::gateway {
namespace fs = std::filesystem;

Expected<fs::path> resolveInside(const fs::path& root, const std::string& rel) {
  const fs::path p(rel);
  if (p.is_absolute()) return invalidInput("\"{}\" is absolute", rel);
  for (const auto& part : p) {
    const std::string s = part.string();
    if (s == "..") return invalidInput("\"{}\" leaves the served folder", rel);
    if (!s.empty() && s.front() == '.' && s != ".") return invalidInput("\"{}\" names a hidden file", rel);
  }
  std::error_code ec;
  const fs::path real = fs::weakly_canonical(root / p, ec);
  if (ec) return Status(Code::kNotFound, fmt::format("\"{}\": {}", rel, ec.message()));
  // Component-wise prefix: /srv/files2 is not inside /srv/files.
  auto r = root.begin();
  auto q = real.begin();
  for (; r != root.end(); ++r, ++q)
    if (q == real.end() || *q != *r) return invalidInput("\"{}\" leaves the served folder", rel);
  return real;
}

const char* contentTypeOf(const fs::path& path) {
  const std::string ext = path.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json" || ext == ".gltf") return ext == ".gltf" ? "model/gltf+json" : "application/json";
  if (ext == ".glb") return "model/gltf-binary";
  if (ext == ".png") return "image/png";
  if (ext == ".jpg" || ext == ".jpeg") return "image/jpeg";
  if (ext == ".exr") return "image/x-exr";
  if (ext == ".ktx2") return "image/ktx2";
  if (ext == ".wasm") return "application/wasm";
  return "application/octet-stream";
}

void serveFile(const fs::path& path, httplib::Response& res) {
  std::error_code ec;
  const bool regular = fs::is_regular_file(path, ec);
  const auto size = regular ? fs::file_size(path, ec) : 0;
  auto in = std::make_shared<std::ifstream>(path, std::ios::binary);
  if (!regular || ec || !*in) {
    res.status = 404;
    res.set_content(nlohmann::json{{"error", "no file " + path.filename().string()}}.dump(), "application/json");
    return;
  }
  res.set_header("Cache-Control", "no-cache");
  res.set_content_provider(static_cast<std::size_t>(size), contentTypeOf(path),
                           [in](std::size_t offset, std::size_t length, httplib::DataSink& sink) {
                             char buffer[1 << 16];
                             in->seekg(static_cast<std::streamoff>(offset));
                             const auto n = std::min(length, sizeof(buffer));
                             in->read(buffer, static_cast<std::streamsize>(n));
                             const auto got = static_cast<std::size_t>(in->gcount());
                             return got > 0 && sink.write(buffer, got);
                           });
}

}  // namespace lightlink::gateway
