// Ray throughput yardstick: the rays and the timing loop behind bench/rt/ray_bench.
//
// DESIGN.md sec. 11 asks link generation to reach >= 70 % of Embree's raw ray throughput
// "on the same rays, same run". This library is that yardstick in reusable form: another
// benchmark builds its own rays (or uses cameraRays / diffuseRays below), calls
// measureThroughput() on them, and compares with its own timing taken in the same process.
//
// Rules that keep the figures honest (STYLE.md, "honest benchmarks"):
//  - fixed seeds; ray generation is not timed;
//  - one untimed warm-up pass (page faults, TBB worker start-up), then whole passes over
//    the rays until min_seconds have elapsed; rays/s = passes * rays / elapsed;
//  - every result is written to a buffer and counted afterwards, so nothing can be elided.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "core/rt/accel.h"
#include "core/scene/scene.h"

namespace lightlink::bench {

enum class Query { kClosestHit, kOcclusion };

// How the rays reach Embree.
enum class RayApi {
  kSingle,    // Accel::intersect(const Ray&) per ray (rtcIntersect1 / rtcOccluded1)
  kPacket16,  // batched, Coherence::kCoherent: rtcIntersect16 packets of neighbouring rays
  kStream,    // batched, Coherence::kIncoherent: rtcIntersect1M streams
};

struct ThroughputOptions {
  Query query = Query::kClosestHit;
  RayApi api = RayApi::kStream;
  int threads = 1;           // 1: the calling thread only; 0: all TBB threads; n: an arena of n
  double min_seconds = 0.5;  // keep repeating whole passes until this much time has passed
  std::size_t chunk = 1024;  // rays per task (a multiple of 16 keeps packets full)
};

struct ThroughputResult {
  std::size_t rays = 0;    // rays in one pass
  std::size_t passes = 0;  // timed passes
  double seconds = 0.0;    // wall time of the timed passes
  std::size_t hits = 0;    // rays that hit / were occluded in the last pass
  int threads = 1;         // threads actually used
  double raysPerSecond() const {
    return seconds > 0.0 ? static_cast<double>(rays * passes) / seconds : 0.0;
  }
};

ThroughputResult measureThroughput(const rt::Accel& accel, std::span<const rt::Ray> rays,
                                   const ThroughputOptions& options);

// Fans of rays (one origin each, directions as arrays): what link generation traces per cache
// through rt::Accel::intersectFan. Fan f's rays are [f * per_fan, (f + 1) * per_fan).
struct FanSet {
  std::vector<glm::vec3> origin;  // per fan
  std::vector<float> x, y, z;     // per ray
  std::uint32_t per_fan = 0;
};

// Closest hits of every fan through Accel::intersectFan (16-ray packets), each fan's hits
// into the task's own arrays, as link generation keeps them (counted after every fan, so
// nothing is elided); tasks of options.chunk rays (whole fans); options.query and .api are
// ignored. The timing rule is measureThroughput's.
ThroughputResult measureFanThroughput(const rt::Accel& accel, const FanSet& fans, const ThroughputOptions& options);

// The timing rule on its own, for a benchmark timing its own work (e.g. link generation
// over the same rays): one untimed call of `pass`, then calls until min_seconds elapsed.
struct PassTiming {
  std::size_t passes = 0;
  double seconds = 0.0;
};
PassTiming timePasses(const std::function<void()>& pass, double min_seconds);

const char* queryName(Query query);
const char* rayApiName(RayApi api);

// Primary rays of a pinhole camera (y up, vertical field of view in degrees), ordered in
// 4x4 pixel tiles so that every aligned group of 16 rays is one tile of neighbouring pixels:
// what a 16-wide packet wants. width and height must be multiples of 4.
std::vector<rt::Ray> cameraRays(const glm::vec3& eye, const glm::vec3& target, float vfov_deg, int width,
                                int height);

// Diffuse-bounce rays: `count` points drawn uniformly by area over the triangles the Accel
// holds (static meshes only), each with a cosine-distributed direction about its triangle's
// front-face normal, origins pushed off the surface with Accel::offsetOrigin. Every ray is an
// independent draw, so neighbours in the array are unrelated (as if shuffled).
std::vector<rt::Ray> diffuseRays(const scene::Scene& scene, const rt::Accel& accel, std::size_t count,
                                 std::uint32_t seed);

// "model name" from /proc/cpuinfo, or "unknown".
std::string cpuModel();

}  // namespace lightlink::bench
