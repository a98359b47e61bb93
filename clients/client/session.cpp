// Session files: JSON {target, scene_id, scene_token, light_ids, opened}.
#include "clients/client/session.h"

#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <google/protobuf/util/json_util.h>
#include <nlohmann/json.hpp>

namespace lightlink::client {

std::string sceneOpenedJson(const v1::SceneOpened& opened, bool pretty) {
  google::protobuf::util::JsonPrintOptions o;
  o.add_whitespace = pretty;
  o.preserve_proto_field_names = true;
  o.always_print_primitive_fields = true;
  std::string out;
  (void)google::protobuf::util::MessageToJsonString(opened, &out, o);
  return out;
}

Status saveSession(const std::string& path, const Session& session) {
  nlohmann::ordered_json j;
  j["target"] = session.target;
  j["scene_id"] = session.scene.id;
  j["scene_token"] = session.scene.token;
  if (session.scene.ids_known) j["light_ids"] = session.scene.light_ids;
  j["opened"] = nlohmann::json::parse(sceneOpenedJson(session.scene.info, false));
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return ioError("{}: cannot write session file", tmp);
    out << j.dump(2) << "\n";
    if (!out) return ioError("{}: write failed", tmp);
  }
  ::chmod(tmp.c_str(), 0600);
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) return ioError("{}: cannot rename session file: {}", path, ec.message());
  return {};
}

Expected<Session> loadSession(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return notFound("{}: cannot open session file (write one with `lightlink open --session`)", path);
  std::ostringstream ss;
  ss << in.rdbuf();
  nlohmann::json j = nlohmann::json::parse(ss.str(), nullptr, false);
  if (j.is_discarded() || !j.is_object()) return invalidInput("{}: not a JSON session file", path);
  Session s;
  for (auto [key, dst] : {std::pair{"target", &s.target}, std::pair{"scene_id", &s.scene.id},
                          std::pair{"scene_token", &s.scene.token}}) {
    if (!j.contains(key) || !j[key].is_string() || j[key].get<std::string>().empty())
      return invalidInput("{}: {}: missing or not a string", path, key);
    *dst = j[key].get<std::string>();
  }
  if (j.contains("light_ids")) {
    if (!j["light_ids"].is_array()) return invalidInput("{}: light_ids: not an array", path);
    for (const auto& id : j["light_ids"]) {
      if (!id.is_string()) return invalidInput("{}: light_ids: {} is not a string", path, id.dump());
      s.scene.light_ids.insert(id.get<std::string>());
    }
    s.scene.ids_known = true;
  }
  if (j.contains("opened")) {
    google::protobuf::util::JsonParseOptions o;
    o.ignore_unknown_fields = true;
    if (!google::protobuf::util::JsonStringToMessage(j["opened"].dump(), &s.scene.info, o).ok())
      return invalidInput("{}: opened: not a SceneOpened message", path);
  }
  s.scene.info.set_scene_id(s.scene.id);
  return s;
}

}  // namespace lightlink::client

namespace lightlink::client {

Expected<std::string> bearerTokenFrom(const std::string& token_file) {
  if (token_file.empty()) {
    const char* env = std::getenv("LIGHTLINK_TOKEN");
    return std::string(env != nullptr ? env : "");
  }
  std::ifstream in(token_file, std::ios::binary);
  if (!in) return notFound("--token-file {}: cannot read", token_file);
  std::string line;
  std::getline(in, line);
  const auto first = line.find_first_not_of(" \t\r\n");
  const auto last = line.find_last_not_of(" \t\r\n");
  if (first == std::string::npos) return invalidInput("--token-file {}: the first line is empty", token_file);
  return line.substr(first, last - first + 1);
}

std::string tokenInArgvMessage(const std::string& flag) {
  return flag + ": a token on the command line is visible to every user of this machine (ps); give it with "
                "--token-file FILE or the environment variable LIGHTLINK_TOKEN";
}

}  // namespace lightlink::client
