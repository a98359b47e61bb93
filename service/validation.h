// Validation and translation of requests: proto messages -> core types, nothing applied
// until everything checked.
//
// Every value that enters the daemon is checked here, once, before it reaches core: NaN,
// Inf, negative or absurd values and counts are rejected with a Status naming the field
// path the way the client wrote it (`add[0].intensity`, `modify[2].id`, `surfels`), which
// the service maps to INVALID_ARGUMENT. Light values reuse relight::LightSet::validate so
// the daemon, `lightlink bake` and light-set files accept exactly the same lights.
#pragma once

#include <cstddef>
#include <string>

#include "core/bake/bake_options.h"
#include "core/common/status.h"
#include "core/precompute/precompute.h"
#include "core/relight/light_set.h"
#include "proto/lightlink.pb.h"

namespace lightlink::service {

// Caps on repeated fields and strings of one request (beyond the 64 MiB message limit).
inline constexpr std::size_t kMaxLightsPerScene = 4096;
inline constexpr std::size_t kMaxChangesPerRequest = 4096;
inline constexpr std::size_t kMaxNameBytes = 1024;
inline constexpr std::size_t kMaxPathBytes = 4096;
inline constexpr std::uint32_t kMaxWaitMs = 60000;
// A scenario's light-set document: 4,096 lights take well under 1 MiB.
inline constexpr std::size_t kMaxLightSetJsonBytes = std::size_t(4) << 20;

// OpenScene parameters -> bake options, through the one builder every front end uses
// (core/bake/bake_options.h): the deprecated typed fields that are set, then `options`.
// `relight_defaults` are the daemon's (--bounces) before any setting.
Expected<bake::BakeOptions> bakeOptionsFrom(const v1::OpenSceneRequest& request,
                                            const relight::RelightOptions& relight_defaults = {});
// The precompute part of bakeOptionsFrom.
Expected<precompute::PrecomputeOptions> precomputeOptionsFrom(const v1::OpenSceneRequest& request);

// Applies an UpdateLights request to `lights` (a copy the caller swaps in on success):
// set/remove/modify/add/emissive/sky/emissive_baked in the documented order, all or
// nothing. `material_count` bounds emissive override indices.
Status applyUpdate(const v1::UpdateLightsRequest& request, std::size_t material_count, relight::LightSet& lights);

// A light of a light set as the proto Light GetLights answers: every field set.
v1::Light toProtoLight(const relight::LightEntry& entry);

// Checks a ResultSpec against a result with `result_bands` bands.
Status validateSpec(const v1::ResultSpec& spec, int result_bands, std::string_view field = "spec");

}  // namespace lightlink::service
