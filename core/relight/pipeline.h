// RelightPipeline: the one relight driver for every backend. It validates the request,
// makes the effects plan (DESIGN.md sec 5), runs the passes of a RelightPasses backend
// (passes.h: the CPU's or the GPU's) in order — surfel direct light, pull and cache
// lighting, the bounce loop with its stop rule, direct light per cache, texels — and owns
// what is the same on every backend: the light that depends on emission alone
// (EmissionState, sampled once per emission state), the sky matrix, the finer direct layer,
// the indirect smoothing and seam stitch of the texels, and the memo of the last light set
// that lets an unchanged light set rewrite only the texels and a change of one light be
// relit incrementally on a backend that can.
//
// The tables (scene_tables.h) must outlive the pipeline. Not thread-safe: one relight at a
// time per pipeline.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/common/status.h"
#include "core/relight/direct_layer.h"
#include "core/relight/emission_state.h"
#include "core/relight/indirect_smooth.h"
#include "core/relight/passes.h"
#include "core/relight/relight.h"
#include "core/relight/scene_tables.h"
#include "core/relight/seam_stitch.h"

namespace lightlink::relight {

class RelightPipeline {
 public:
  RelightPipeline(const SceneTables& tables, std::unique_ptr<RelightPasses> passes);
  ~RelightPipeline();

  EffectsPlan plan(const LightSet& lights, const RelightOptions& options) const;
  // Whether relightInto(lights, options) would relight one changed light incrementally.
  bool incrementalFor(const LightSet& lights, const RelightOptions& options) const;
  // Relights into `res`, reusing its arrays' capacity. On error `res` is unspecified.
  Status relightInto(const LightSet& lights, const RelightOptions& options, RelightResult& res);
  // kLightState: the next relight is a full one, but what depends on emission alone is
  // reused while the emissive overrides are unchanged. kEverything: nothing is reused.
  void invalidate(bool everything);
  // The smooth_indirect filter on res.lightmap_sh (texels with their own cache, then the
  // dilated texels re-derived from them).
  void smoothIndirect(RelightResult& res);

 private:
  // What the last relight computed, for the unchanged and incremental shortcuts.
  struct Memo {
    bool valid = false;
    bool bounced = false;
    bool warm = false;                 // started from the relight before it
    std::vector<scene::Light> lights;  // parallel to ids and baked
    std::vector<std::string> ids;
    std::vector<std::uint8_t> baked;
    std::vector<EmissiveOverride> emissive;
    bool emissive_baked = true;
    Sky sky;
    RelightOptions options;
    std::vector<BounceRecord> bounce_log;
    std::string bounce_stop;
  };
  void resetResult(const LightSet& lights, const RelightOptions& o, int bands, RelightResult& res) const;
  // Both shortcuts need the same options and light-set fields but the lights (bounce
  // options aside); sameEntry compares a light with the memo's j-th.
  bool sameSetting(const LightSet& lights, const RelightOptions& o, int bands) const;
  // The last relight's caches can start a warm one with these options.
  bool warmBase(const RelightOptions& o, int bands) const;
  bool sameEntry(const LightEntry& e, std::size_t j) const;
  bool unchanged(const LightSet& lights, const RelightOptions& o, int bands) const;
  std::optional<LightChange> oneChange(const LightSet& lights, const RelightOptions& o, const EffectsPlan& plan,
                                       int bands) const;
  Status fullRelight(const RelightFrame& f, RelightResult& res);
  Status bounceLoop(const RelightFrame& f, RelightResult& res);
  // Incremental relight with bounces: propagateChange rounds until the stop rule.
  Status changeLoop(const RelightFrame& f, RelightResult& res);
  void emitterTexels(const RelightFrame& f, RelightResult& res);
  void gridEmitter(const RelightFrame& f, RelightResult& res);
  void finish(const RelightFrame& f, RelightResult& res);
  void remember(const RelightFrame& f, const RelightResult& res);

  const SceneTables& t_;
  std::unique_ptr<RelightPasses> passes_;
  EmissionState emission_;
  DirectLayer layer_;
  SeamStitch seams_;  // of the lightmap atlas
  // The smooth_indirect filter, built on first use (its weights are ~9 entries per texel).
  std::optional<detail::IndirectSmooth> smooth_;
  std::vector<float> smooth_scratch_;
  std::vector<float> sky_matrix_[3];
  Memo memo_;
  detail::EmitterTraceLog trace_log_;  // the backend's emitter sampling in this relight
};

}  // namespace lightlink::relight
