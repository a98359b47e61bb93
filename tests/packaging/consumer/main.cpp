// The consumer's program: reads a light set with the library's one reader, turns it into an
// UpdateLights request and constructs a client (connecting lazily, so no daemon is needed).
#include <chrono>
#include <cstdio>

#include "clients/client/client.h"
#include "clients/client/light_update.h"
#include "core/lights/light_set.h"

int main() {
  const char* text = R"({"version": 1, "lights": [
      {"id": "lamp", "type": "point", "position": [0, 2, 0], "intensity": 40}],
      "sky": {"radiance": [0.1, 0.2, 0.3]}})";
  auto set = lightlink::lights::LightSetPatch::parse(text);
  if (!set) return std::fprintf(stderr, "%s\n", set.status().toString().c_str()), 1;
  auto update = lightlink::client::LightUpdate::fromLightSetPatch(*set, nullptr);
  if (!update || update->proto().add_size() != 1) return std::fprintf(stderr, "light set not converted\n"), 1;
  auto bad = lightlink::client::LightUpdate::fromLightSetText(R"({"version": 1, "sky": {"radiance": [0, -1, 0]}})", nullptr);
  if (bad) return std::fprintf(stderr, "a negative sky was accepted\n"), 1;

  lightlink::client::ConnectOptions options;
  options.target = "127.0.0.1:1";
  options.connect_timeout = std::chrono::milliseconds(0);  // lazy: nothing listens there
  auto client = lightlink::client::Client::connect(options);
  if (!client) return std::fprintf(stderr, "%s\n", client.status().toString().c_str()), 1;
  std::printf("consumer ok: %s\n", bad.status().message().c_str());
  return 0;
}
