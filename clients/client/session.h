// Session files: a scene handle written by `lightlink open --session FILE` and read by the
// other commands and the example game client, so a shell script opens a scene once and
// then names it by file instead of copying ids and tokens around. The file holds the scene
// token (a capability): keep it where only its owner can read it (written with mode 0600).
// The daemon's bearer token is never written; give it with --token-file or LIGHTLINK_TOKEN
// (never in argv, where every user of the machine sees it in ps).
#pragma once

#include <string>

#include "clients/client/client.h"

namespace lightlink::client {

struct Session {
  std::string target;  // host:port of the daemon
  SceneHandle scene;
};

Status saveSession(const std::string& path, const Session& session);
Expected<Session> loadSession(const std::string& path);

// The daemon bearer token a client command uses: the first line of `token_file` when one is
// given (surrounding whitespace dropped), else $LIGHTLINK_TOKEN, else none ("").
Expected<std::string> bearerTokenFrom(const std::string& token_file);

// The message for a bearer token given in argv (`flag`), which client commands refuse.
std::string tokenInArgvMessage(const std::string& flag);

// SceneOpened as JSON (protobuf's JSON mapping, field names as in the proto).
std::string sceneOpenedJson(const v1::SceneOpened& opened, bool pretty);

}  // namespace lightlink::client
