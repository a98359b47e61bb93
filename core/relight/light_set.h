// The light set under relight's names. LightSet, its parts and the light-set JSON reader live
// in core/lights (lightlink_lights, which the client library links without Embree or
// OpenMesh); relight code and its callers keep writing relight::LightSet through these
// aliases. New code includes core/lights/light_set.h.
#pragma once

#include "core/lights/light_set.h"

namespace lightlink::relight {

using lights::EmissiveOverride;
using lights::kLightSetSchemaVersion;
using lights::kMaxLightValue;
using lights::LightEntry;
using lights::LightPatch;
using lights::LightSet;
using lights::LightSetPatch;
using lights::sameLight;
using lights::Sky;

}  // namespace lightlink::relight
