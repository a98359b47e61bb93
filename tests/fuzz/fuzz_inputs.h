// The entry functions behind the fuzzers (fuzz_gltf, fuzz_artifact) and the replay test.
//
// Each takes arbitrary bytes, hands them to a loader exactly as a file on disk would be
// (the loaders read paths: the bytes go to a private temp file first) and returns the
// loader's verdict. The contract under test, for *any* bytes: the loader accepts them or
// returns a Status whose message says what is wrong; it never crashes, hangs, reads out of
// bounds, throws through the API, or trips ASan/UBSan. libFuzzer calls these through
// LLVMFuzzerTestOneInput; the replay test calls them on every committed corpus and
// regression file in ordinary builds, so a fixed crash stays fixed without clang.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/common/status.h"
#include "core/precompute/precompute.h"
#include "core/relight/light_set.h"
#include "core/scene/scene.h"

namespace lightlink::fuzz {

// glTF ingest with full validation (scene::loadGltf). The bytes are written as "in.gltf";
// the loader tells .glb from JSON by the "glTF" magic, so one target covers both paths.
// Textures are decoded (stb), external URIs resolve next to the temp file.
Status loadGltfBytes(std::span<const std::uint8_t> bytes);

struct ArtifactVerdict {
  Status raw;            // precompute::open of the bytes as given
  bool fixed = false;    // fixChecksums changed the bytes and they were opened again
  Status after_fix;      // precompute::open after fixChecksums (when fixed)
  bool relit = false;    // an artifact opened and a relight of the fuzz scene ran on it
  Status relight;        // Relighter::create + relight on the opened artifact
};

// The artifact loader: artifact::Artifact::open (payloads verified, then header-only with
// per-section verify/bytes), precompute::open, and, for an artifact that opens, a relight of
// fuzzScene() on it: whatever open() accepts must be safe for its consumers. When the raw
// bytes fail a checksum, the fuzzer would never get past it; so the bytes are also opened
// after fixChecksums(), which lets mutations reach the section and metadata parsing.
ArtifactVerdict openArtifactBytes(std::span<const std::uint8_t> bytes);

// Light-set JSON (docs/lightset.md), as `lightlink bake --lights` and `render --lights` read
// it: the bytes as a file through relight::LightSet::load, and merged into the fuzz scene's
// lights with LightSet::apply (the `--lights` path). A set that loads must survive a
// round trip: LightSet::fromJson(set.toJson()) loads the same set; violated, the returned
// status is kInternal (the fuzzer stops on it).
// A merge that applies is then relit on the fuzz scene (what `bake --lights` does next).
struct LightSetVerdict {
  Status load;        // LightSet::load of the bytes as a file
  Status apply;       // fuzzSceneLights().applyFile of the same file, then its emissive materials against the scene
  Status round_trip;  // kInternal when toJson/fromJson disagree or a failed merge changed the set
  bool relit = false;
  Status relight;     // relightFuzzScene(merged set), when apply succeeded
};
LightSetVerdict loadLightSetBytes(std::span<const std::uint8_t> bytes);

// The bake outputs `lightlink render` and the game client read (clients/viewer): the bytes as
// one lightmap EXR of layout 2 (viewer::readLightlinkExr, at most 2^16 texels: larger windows
// cost the fuzzer seconds per input, and the size check itself is covered by the replay
// test; an irradiance map is then loaded as an L0 bake), or as a grid.raw
// (viewer::readGridRaw). What loads is then sampled as `render` samples it: UVs and points
// inside, on the edges, far outside and NaN.
Status readLightmapExrBytes(std::span<const std::uint8_t> bytes);
Status readGridRawBytes(std::span<const std::uint8_t> bytes);

// Rewrites file_bytes (to the real size) and the header, table and section checksums of a
// buffer that starts with an artifact header, as a correct writer would have computed them.
// Leaves bytes it cannot interpret alone. Returns true when anything changed.
bool fixChecksums(std::vector<std::uint8_t>& bytes);

// The tiny scene the seed artifact is computed from (a closed room with an emissive panel
// and a dynamic block, so the artifact has lightmap and grid links), and the options.
scene::Scene fuzzScene();
precompute::PrecomputeOptions fuzzOptions();

// The fuzz scene baked once per process (precompute + accel + Relighter), its light set and
// material count; relightFuzzScene relights it with `lights` (one bounce, one emitter
// sample): what the daemon's update worker and `lightlink bake --lights` do with a light
// set they accepted. Accepted light sets must relight; an error here is a validation gap.
const relight::LightSet& fuzzSceneLights();
std::size_t fuzzSceneMaterialCount();
Status relightFuzzScene(const relight::LightSet& lights);

// Computes the seed artifact of fuzz_artifact and writes it to `path`.
Status writeSeedArtifact(const std::string& path);

// Bakes the fuzz scene (precompute + relight) and writes the seeds of fuzz_lightmap_exr and
// fuzz_grid_raw: `dir`/lightmap_float.exr, lightmap_half.exr and grid.raw.
Status writeSeedBakeOutputs(const std::string& dir);

}  // namespace lightlink::fuzz
