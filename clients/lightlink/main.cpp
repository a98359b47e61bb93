// lightlink: the command-line front end (inspect; later unwrap, precompute, bake, ...).
#include <CLI/CLI.hpp>

#include "clients/lightlink/commands.h"
#include "clients/lightlink/exit_codes.h"

int main(int argc, char** argv) {
  using namespace lightlink::cli;
  CLI::App app{"lightlink: lightmap and irradiance-volume baking (precomputed illuminance composition)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "lightlink 0.1.0");

  InspectArgs inspect;
  auto* inspect_cmd = app.add_subcommand("inspect", "Load and validate a glTF scene and print a summary");
  inspect_cmd->add_option("scene", inspect.scene_path, "glTF scene (.gltf or .glb)")->required();
  inspect_cmd->add_flag("--json", inspect.json, "Print the summary as JSON");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  }
  if (*inspect_cmd) return runInspect(inspect);
  return kExitUsage;
}
