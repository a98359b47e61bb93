#include "core/scene/gltf_diagnose.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/scene/gltf_structure.h"

namespace lightlink::scene::gltf {
namespace {

struct Document {
  std::string text;               // the JSON (a .glb's JSON chunk)
  nlohmann::json json;            // discarded when the text does not parse
  std::size_t glb_bin_bytes = 0;  // BIN chunk length of a .glb, 0 when absent
};

// Finds where JSON parsing fails as a path of keys and indices ("nodes[0].translation[1]"),
// which names the glTF object even when the problem is a number such as 1e999 that
// overflows to infinity (nlohmann rejects those as out_of_range.406).
class JsonPathFinder : public nlohmann::json_sax<nlohmann::json> {
 public:
  std::string error;

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override {
    frames_.push_back({false, {}, 0});
    return true;
  }
  bool key(string_t& k) override {
    frames_.back().key = k;
    return true;
  }
  bool end_object() override {
    frames_.pop_back();
    return value();
  }
  bool start_array(std::size_t) override {
    frames_.push_back({true, {}, 0});
    return true;
  }
  bool end_array() override {
    frames_.pop_back();
    return value();
  }
  bool parse_error(std::size_t position, const std::string& last_token,
                   const nlohmann::detail::exception& ex) override {
    const std::string where = path();
    if (ex.id == 406) {  // number overflow
      error = fmt::format("{} = {} is not a finite number", where.empty() ? "JSON" : where, last_token);
    } else {
      error = fmt::format("malformed JSON at byte {}{}: {}", position,
                          where.empty() ? "" : " (in " + where + ")", ex.what());
    }
    return false;
  }

 private:
  struct Frame {
    bool is_array;
    std::string key;
    std::size_t index;
  };
  bool value() {
    if (!frames_.empty() && frames_.back().is_array) ++frames_.back().index;
    return true;
  }
  std::string path() const {
    std::string out;
    for (const Frame& f : frames_) {
      if (f.is_array) {
        out += fmt::format("[{}]", f.index);
      } else if (!f.key.empty()) {
        out += (out.empty() ? "" : ".") + f.key;
      }
    }
    return out;
  }
  std::vector<Frame> frames_;
};

std::optional<Document> readDocument(const std::string& bytes, bool binary) {
  Document doc;
  std::string& text = doc.text;
  if (binary) {
    // GLB: 12-byte header, then chunks of (uint32 length, uint32 type, data).
    auto u32 = [&](std::size_t at) {
      std::uint32_t v = 0;
      if (at + 4 <= bytes.size()) std::memcpy(&v, bytes.data() + at, 4);
      return v;
    };
    if (bytes.size() < 20 || std::string_view(bytes.data(), 4) != "glTF") return std::nullopt;
    const std::size_t json_len = u32(12);
    if (20 + json_len > bytes.size()) return std::nullopt;
    text.assign(bytes.data() + 20, json_len);
    const std::size_t bin_at = 20 + ((json_len + 3) & ~std::size_t{3});
    if (bin_at + 8 <= bytes.size() && u32(bin_at + 4) == 0x004E4942u) {  // "BIN\0"
      doc.glb_bin_bytes = std::min<std::size_t>(u32(bin_at), bytes.size() - bin_at - 8);
    }
  } else {
    text.assign(bytes.begin(), bytes.end());
  }
  doc.json = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  return doc;
}

// Decoded size of base64 text (tinygltf accepts only the application/octet-stream form).
std::size_t base64DecodedBytes(const std::string& uri) {
  const std::size_t comma = uri.find(',');
  std::size_t chars = 0, padding = 0;
  for (std::size_t i = comma == std::string::npos ? 0 : comma + 1; i < uri.size(); ++i) {
    const char c = uri[i];
    if (c == '=') {
      ++padding;
    } else if (std::isalnum(static_cast<unsigned char>(c)) || c == '+' || c == '/') {
      ++chars;
    }
  }
  (void)padding;  // the decoded size follows from the data characters alone
  return chars * 3 / 4;
}

// Depth-first walk with the JSON path of each value; `visit` returns true to stop.
template <typename Visit>
bool walk(const nlohmann::json& j, const std::string& where, const Visit& visit) {
  if (visit(j, where)) return true;
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (walk(*it, where.empty() ? it.key() : where + "." + it.key(), visit)) return true;
    }
  } else if (j.is_array()) {
    for (std::size_t i = 0; i < j.size(); ++i) {
      if (walk(j[i], fmt::format("{}[{}]", where, i), visit)) return true;
    }
  }
  return false;
}

// The JSON path of what a tinygltf schema message is about, or "" when not recognised.
std::string locateTinygltfComplaint(const nlohmann::json& j, const std::string& message) {
  std::string found;
  const auto firstMatch = [&](const auto& predicate) {
    walk(j, "", [&](const nlohmann::json& v, const std::string& where) {
      if (predicate(v)) found = where;
      return !found.empty();
    });
    return found;
  };
  // "'count' property is not a positive integer." / "'buffer' property is not an integer type."
  const std::size_t quote = message.find("' property is not");
  if (message.rfind('\'', 0) == 0 && quote != std::string::npos) {
    const std::string member = message.substr(1, quote - 1);
    return firstMatch([&](const nlohmann::json& v) {
      if (!v.is_object()) return false;
      const auto it = v.find(member);
      return it != v.end() && !it->is_number_unsigned();
    }).empty() ? "" : found + "." + member;
  }
  const auto accessorWith = [&](const char* member, const nlohmann::json& value) -> std::string {
    const auto accessors = j.find("accessors");
    if (accessors == j.end() || !accessors->is_array()) return "";
    for (std::size_t i = 0; i < accessors->size(); ++i) {
      const nlohmann::json& a = (*accessors)[i];
      if (a.is_object() && a.contains(member) && a[member] == value) {
        return fmt::format("accessors[{}].{}", i, member);
      }
    }
    return "";
  };
  // "Invalid `componentType` in accessor. Got 5127"
  if (std::size_t at = message.find("Invalid `componentType` in accessor. Got "); at != std::string::npos) {
    const char* number = message.c_str() + at + std::strlen("Invalid `componentType` in accessor. Got ");
    return accessorWith("componentType", std::strtoll(number, nullptr, 10));
  }
  // "Unsupported `type` for accessor object. Got \"VEC5\""
  if (std::size_t at = message.find("for accessor object. Got \""); at != std::string::npos) {
    const std::size_t start = at + std::strlen("for accessor object. Got \"");
    return accessorWith("type", message.substr(start, message.find('"', start) - start));
  }
  if (message.find("primitive indices accessor out of bounds") != std::string::npos) {
    const std::size_t count = j.contains("accessors") ? j["accessors"].size() : 0;
    return firstMatch([&](const nlohmann::json& v) {
      if (!v.is_object() || !v.contains("attributes") || !v.contains("indices")) return false;
      const nlohmann::json& idx = v["indices"];
      return !idx.is_number_unsigned() || idx.get<std::size_t>() >= count;
    }).empty() ? "" : found + ".indices";
  }
  return "";
}

std::string bufferName(std::size_t index, const nlohmann::json& b) {
  const auto name = b.find("name");
  if (name != b.end() && name->is_string() && !name->get<std::string>().empty()) {
    return fmt::format("buffer {} '{}'", index, name->get<std::string>());
  }
  return fmt::format("buffer {}", index);
}

}  // namespace

std::optional<Status> diagnoseLoadFailure(const SceneFiles& files, const std::string& bytes, bool binary,
                                          const std::string& tinygltf_error) {
  const std::string& path = files.scenePath();
  std::optional<Document> doc = readDocument(bytes, binary);
  if (!doc) return std::nullopt;
  if (doc->json.is_discarded()) {
    JsonPathFinder finder;
    nlohmann::json::sax_parse(doc->text, &finder);
    if (finder.error.empty()) return std::nullopt;
    return invalidInput("{}: {}", path, finder.error);
  }
  const nlohmann::json& j = doc->json;
  if (!j.is_object()) return invalidInput("{}: malformed JSON: the top level is not an object", path);

  // A required extension we lack often breaks tinygltf first (Draco primitives have
  // accessors without bufferViews), so it is the first cause to report.
  const auto required = j.find("extensionsRequired");
  if (required != j.end() && required->is_array()) {
    for (const nlohmann::json& e : *required) {
      if (e.is_string() && !isSupportedExtension(e.get<std::string>())) {
        return Status(Code::kUnsupported,
                      fmt::format("{}: extensionsRequired: required extension {} is not "
                                  "supported by lightlink", path, e.get<std::string>()));
      }
    }
  }

  if (std::string where = locateTinygltfComplaint(j, tinygltf_error); !where.empty()) {
    return invalidInput("{}: {}: {}", path, where, shortenTinygltfMessage(tinygltf_error));
  }

  const auto buffers = j.find("buffers");
  if (buffers == j.end() || !buffers->is_array()) return std::nullopt;
  for (std::size_t i = 0; i < buffers->size(); ++i) {
    const nlohmann::json& b = (*buffers)[i];
    if (!b.is_object()) continue;
    const std::string object = bufferName(i, b);
    const auto length_it = b.find("byteLength");
    if (length_it == b.end() || !length_it->is_number_unsigned()) {
      return invalidInput("{}: {}: byteLength is missing or not a non-negative integer", path, object);
    }
    const auto byte_length = length_it->get<std::size_t>();
    const auto uri_it = b.find("uri");
    const std::string uri = uri_it != b.end() && uri_it->is_string() ? uri_it->get<std::string>() : "";
    std::size_t actual = 0;
    std::string source;
    if (uri.empty()) {
      if (!binary) return invalidInput("{}: {}: has no uri", path, object);
      actual = doc->glb_bin_bytes;
      source = "the GLB BIN chunk";
      if (byte_length > actual) {
        return invalidInput("{}: {}: byteLength {} exceeds the {} bytes of {}", path, object,
                            byte_length, actual, source);
      }
      continue;
    }
    if (uri.rfind("data:", 0) == 0) {
      if (uri.find(";base64,") == std::string::npos) {
        return invalidInput("{}: {}: data URI is not base64", path, object);
      }
      if (uri.rfind("data:application/octet-stream;base64,", 0) != 0 &&
          uri.rfind("data:application/gltf-buffer;base64,", 0) != 0) {
        return invalidInput("{}: {}: data URI has an unsupported media type", path, object);
      }
      actual = base64DecodedBytes(uri);
      source = "its data URI";
    } else {
      // Resolved by the same rules as the loader: sizes of files outside the scene's folder
      // are never looked at, so this message cannot reveal them.
      Expected<std::filesystem::path> file = files.resolveUri(uri, object);
      if (!file) return file.status();
      std::error_code ec;
      if (!std::filesystem::is_regular_file(*file, ec)) {
        return invalidInput("{}: {}: buffer file '{}' does not exist", path, object, uri);
      }
      actual = static_cast<std::size_t>(std::filesystem::file_size(*file, ec));
      source = fmt::format("'{}'", uri);
    }
    if (byte_length > actual) {
      return invalidInput("{}: {}: byteLength {} exceeds the {} bytes of {} (short buffer)", path,
                          object, byte_length, actual, source);
    }
    if (byte_length != actual) {
      return invalidInput("{}: {}: byteLength {} differs from the {} bytes of {} (tinygltf "
                          "requires them equal)", path, object, byte_length, actual, source);
    }
  }
  return std::nullopt;
}

std::string shortenTinygltfMessage(const std::string& message) {
  constexpr std::size_t kMaxChars = 600;
  constexpr std::size_t kUriKeep = 24;
  std::string out;
  out.reserve(std::min(message.size(), kMaxChars + 16));
  for (std::size_t i = 0; i < message.size();) {
    if (message.compare(i, 5, "data:") == 0) {
      std::size_t end = message.find_first_of(" \n'\"", i);
      if (end == std::string::npos) end = message.size();
      out += message.substr(i, std::min(end - i, kUriKeep));
      if (end - i > kUriKeep) out += "...";
      i = end;
    } else {
      out += message[i++];
    }
    if (out.size() > kMaxChars) {
      out += "...";
      break;
    }
  }
  while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
  return out;
}

}  // namespace lightlink::scene::gltf
