// Surface rules: the lighting flags of glTF `extras.lightlink` (cast_shadows, contribute_gi,
// receive_gi), set from a bake config instead of the scene file. OBJ and FBX levels have no
// extras, and a studio's level file is often not the baker's to edit; the rules select
// mesh instances by name or material name (glob patterns) and override what the file says.
// They are a bake option (`--surfaces FILE`, core/bake), so they reach the artifact's cache
// key through PrecomputeOptions::canonical(). docs/scene-format.md "Surface rules".
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "core/common/status.h"
#include "core/scene/scene.h"

namespace lightlink::scene {

struct SurfaceRule {
  std::string mesh;      // glob (* and ?) on MeshInstance::name, or on its part before "/<primitive>"; "" = any
  std::string material;  // glob on the material's name; "" = any
  int cast_shadows = -1;   // -1 unset, 0 false, 1 true
  int contribute_gi = -1;  // -1 unset, 0 false, 1 true
  int receive_gi = -1;     // -1 unset, else ReceiveGi
};

struct SurfaceRules {
  std::vector<SurfaceRule> rules;  // in file order: a later rule wins where two set one flag
  bool empty() const { return rules.empty(); }
  // Normalised JSON text (version, rules, keys in a fixed order): the cache key's part.
  std::string canonical() const;
};

// Parses {"version": 1, "surfaces": [{"mesh": "...", "material": "...", "cast_shadows": b,
// "contribute_gi": b, "receive_gi": "lightmap"|"volume"|"off"}, ...]}. Unknown keys, a rule
// with no selector or no flag, other versions and wrong types are invalid input naming
// `origin` (a file name, or "option 'surfaces'"), the rule index and the key.
Expected<SurfaceRules> parseSurfaceRules(std::string_view json, std::string_view origin);

// True when `pattern` (* any run, ? one character) matches all of `text`.
bool globMatch(std::string_view pattern, std::string_view text);

// Sets the flags of every mesh instance a rule selects (over what the scene file said);
// receive_gi volume/off also makes the mesh probe-lit, lightmap makes it lightmapped. A rule
// that selects nothing adds a warning to scene.warnings. Returns how many mesh instances
// each rule selected.
std::vector<std::size_t> applySurfaceRules(Scene& scene, const SurfaceRules& rules);

}  // namespace lightlink::scene
