#include "bench/rt/throughput.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <random>

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include "core/common/check.h"

namespace lightlink::bench {

const char* queryName(Query query) { return query == Query::kClosestHit ? "closest" : "occluded"; }

const char* rayApiName(RayApi api) {
  switch (api) {
    case RayApi::kSingle: return "single";
    case RayApi::kPacket16: return "packet16";
    case RayApi::kStream: return "stream";
  }
  return "?";
}

PassTiming timePasses(const std::function<void()>& pass, double min_seconds) {
  pass();  // warm-up, untimed
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  PassTiming timing;
  do {
    pass();
    ++timing.passes;
    timing.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  } while (timing.seconds < min_seconds);
  return timing;
}

ThroughputResult measureThroughput(const rt::Accel& accel, std::span<const rt::Ray> rays,
                                   const ThroughputOptions& options) {
  LL_CHECK_GT(options.chunk, std::size_t{0});
  const std::size_t n = rays.size();
  const bool closest = options.query == Query::kClosestHit;
  std::vector<rt::Hit> hits(closest ? n : 0);
  std::vector<std::uint8_t> blocked(closest ? 0 : n);
  const rt::Coherence coherence =
      options.api == RayApi::kPacket16 ? rt::Coherence::kCoherent : rt::Coherence::kIncoherent;

  // One task's work: rays [begin, end) through the chosen API into the result buffers.
  auto trace = [&](std::size_t begin, std::size_t end) {
    const std::span<const rt::Ray> in = rays.subspan(begin, end - begin);
    if (options.api == RayApi::kSingle) {
      if (closest)
        for (std::size_t i = begin; i < end; ++i) hits[i] = accel.intersect(rays[i]);
      else
        for (std::size_t i = begin; i < end; ++i) blocked[i] = accel.occluded(rays[i]) ? 1 : 0;
    } else if (closest) {
      accel.intersect(in, std::span<rt::Hit>(hits).subspan(begin, end - begin), coherence);
    } else {
      accel.occluded(in, std::span<std::uint8_t>(blocked).subspan(begin, end - begin), coherence);
    }
  };

  const int threads = options.threads == 0 ? tbb::info::default_concurrency() : options.threads;
  const std::size_t chunks = (n + options.chunk - 1) / options.chunk;
  tbb::task_arena arena(threads);
  auto pass = [&] {
    if (threads == 1) {
      for (std::size_t c = 0; c < chunks; ++c)
        trace(c * options.chunk, std::min(n, (c + 1) * options.chunk));
      return;
    }
    // One task per chunk (simple_partitioner, grain 1) so chunk boundaries, and hence
    // packet boundaries, are the same as in the single-threaded pass.
    arena.execute([&] {
      tbb::parallel_for(
          tbb::blocked_range<std::size_t>(0, chunks, 1),
          [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t c = r.begin(); c < r.end(); ++c)
              trace(c * options.chunk, std::min(n, (c + 1) * options.chunk));
          },
          tbb::simple_partitioner());
    });
  };

  const PassTiming timing = timePasses(pass, options.min_seconds);
  ThroughputResult result;
  result.rays = n;
  result.threads = threads;
  result.passes = timing.passes;
  result.seconds = timing.seconds;

  if (closest)
    result.hits = static_cast<std::size_t>(
        std::count_if(hits.begin(), hits.end(), [](const rt::Hit& h) { return h.hit(); }));
  else
    result.hits = static_cast<std::size_t>(std::count(blocked.begin(), blocked.end(), std::uint8_t{1}));
  return result;
}

ThroughputResult measureFanThroughput(const rt::Accel& accel, const FanSet& fans, const ThroughputOptions& options) {
  LL_CHECK_GT(fans.per_fan, 0u);
  const std::size_t per_fan = fans.per_fan;
  const std::size_t fan_count = fans.origin.size();
  LL_CHECK_EQ(fans.x.size(), fan_count * per_fan);
  const std::size_t fans_per_task = std::max<std::size_t>(1, options.chunk / per_fan);
  const std::size_t tasks = (fan_count + fans_per_task - 1) / fans_per_task;
  std::atomic<std::size_t> hits{0};
  auto trace = [&](std::size_t task) {
    thread_local std::vector<std::uint32_t> mesh, triangle;
    thread_local std::vector<float> u, v, t, nx, ny, nz;
    for (auto* a : {&mesh, &triangle}) a->resize(per_fan);
    for (auto* a : {&u, &v, &t, &nx, &ny, &nz}) a->resize(per_fan);
    const rt::HitArrays out{mesh.data(), triangle.data(), u.data(), v.data(), t.data(), nx.data(), ny.data(), nz.data()};
    std::size_t task_hits = 0;
    for (std::size_t f = task * fans_per_task; f < std::min(fan_count, (task + 1) * fans_per_task); ++f) {
      rt::RayFan fan;
      fan.origin = fans.origin[f];
      fan.dir_x = fans.x.data() + f * per_fan;
      fan.dir_y = fans.y.data() + f * per_fan;
      fan.dir_z = fans.z.data() + f * per_fan;
      fan.count = per_fan;
      accel.intersectFan(fan, out);
      for (std::size_t i = 0; i < per_fan; ++i) task_hits += mesh[i] != rt::kNoHit ? 1 : 0;
    }
    hits.fetch_add(task_hits, std::memory_order_relaxed);
  };
  const int threads = options.threads == 0 ? tbb::info::default_concurrency() : options.threads;
  tbb::task_arena arena(threads);
  auto pass = [&] {
    hits.store(0);
    if (threads == 1) {
      for (std::size_t k = 0; k < tasks; ++k) trace(k);
      return;
    }
    arena.execute([&] {
      tbb::parallel_for(
          tbb::blocked_range<std::size_t>(0, tasks, 1),
          [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t k = r.begin(); k < r.end(); ++k) trace(k);
          },
          tbb::simple_partitioner());
    });
  };
  const PassTiming timing = timePasses(pass, options.min_seconds);
  ThroughputResult result;
  result.rays = fan_count * per_fan;
  result.threads = threads;
  result.passes = timing.passes;
  result.seconds = timing.seconds;
  result.hits = hits.load();
  return result;
}

std::vector<rt::Ray> cameraRays(const glm::vec3& eye, const glm::vec3& target, float vfov_deg, int width,
                                int height) {
  LL_CHECK(width > 0 && height > 0 && width % 4 == 0 && height % 4 == 0);
  const glm::vec3 forward = glm::normalize(target - eye);
  glm::vec3 right = glm::cross(forward, glm::vec3(0.0f, 1.0f, 0.0f));
  if (glm::dot(right, right) < 1e-12f) right = glm::vec3(1.0f, 0.0f, 0.0f);  // looking straight up/down
  right = glm::normalize(right);
  const glm::vec3 up = glm::cross(right, forward);
  const float half_h = std::tan(0.5f * vfov_deg * 3.14159265f / 180.0f);
  const float half_w = half_h * static_cast<float>(width) / static_cast<float>(height);

  std::vector<rt::Ray> rays;
  rays.reserve(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  for (int ty = 0; ty < height; ty += 4)
    for (int tx = 0; tx < width; tx += 4)
      for (int y = ty; y < ty + 4; ++y)
        for (int x = tx; x < tx + 4; ++x) {
          const float sx =
              (2.0f * (static_cast<float>(x) + 0.5f) / static_cast<float>(width) - 1.0f) * half_w;
          const float sy =
              (1.0f - 2.0f * (static_cast<float>(y) + 0.5f) / static_cast<float>(height)) * half_h;
          rays.push_back(rt::Ray{eye, 0.0f, glm::normalize(forward + sx * right + sy * up),
                                 std::numeric_limits<float>::infinity()});
        }
  return rays;
}

std::vector<rt::Ray> diffuseRays(const scene::Scene& scene, const rt::Accel& accel, std::size_t count,
                                 std::uint32_t seed) {
  // Area-weighted triangle choice through one flat CDF over all static triangles.
  struct TriangleRef {
    std::uint32_t mesh;
    std::uint32_t triangle;
  };
  std::vector<TriangleRef> triangles;
  std::vector<double> cdf;
  double total = 0.0;
  for (std::size_t m = 0; m < scene.meshes.size(); ++m) {
    const scene::MeshInstance& mesh = scene.meshes[m];
    if (!mesh.is_static) continue;
    for (std::size_t t = 0; t < mesh.triangleCount(); ++t) {
      const glm::vec3 a = mesh.positions[mesh.indices[3 * t]];
      const glm::vec3 b = mesh.positions[mesh.indices[3 * t + 1]];
      const glm::vec3 c = mesh.positions[mesh.indices[3 * t + 2]];
      const double area = 0.5 * static_cast<double>(glm::length(glm::cross(b - a, c - a)));
      if (!(area > 0.0)) continue;
      total += area;
      triangles.push_back({static_cast<std::uint32_t>(m), static_cast<std::uint32_t>(t)});
      cdf.push_back(total);
    }
  }
  LL_CHECK(!triangles.empty());

  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> pick(0.0, total);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::vector<rt::Ray> rays(count);
  for (rt::Ray& ray : rays) {
    const std::size_t k = std::min<std::size_t>(
        static_cast<std::size_t>(std::upper_bound(cdf.begin(), cdf.end(), pick(rng)) - cdf.begin()),
        triangles.size() - 1);
    const scene::MeshInstance& mesh = scene.meshes[triangles[k].mesh];
    const std::uint32_t* idx = &mesh.indices[3 * static_cast<std::size_t>(triangles[k].triangle)];
    const glm::vec3 a = mesh.positions[idx[0]], b = mesh.positions[idx[1]], c = mesh.positions[idx[2]];
    // Uniform point on the triangle (square-root parameterisation).
    const float su = std::sqrt(u01(rng)), sv = u01(rng);
    const glm::vec3 p = (1.0f - su) * a + su * (1.0f - sv) * b + su * sv * c;
    const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
    // Cosine-distributed direction about n (Malley: uniform disk lifted to the hemisphere).
    const glm::vec3 t = glm::normalize(std::abs(n.x) > 0.5f ? glm::cross(n, glm::vec3(0, 1, 0))
                                                            : glm::cross(n, glm::vec3(1, 0, 0)));
    const glm::vec3 bt = glm::cross(n, t);
    const float r = std::sqrt(u01(rng));
    const float phi = 6.28318531f * u01(rng);
    const glm::vec3 d =
        r * std::cos(phi) * t + r * std::sin(phi) * bt + std::sqrt(std::max(0.0f, 1.0f - r * r)) * n;
    ray = rt::Ray{accel.offsetOrigin(p, n, d), 0.0f, d, std::numeric_limits<float>::infinity()};
  }
  return rays;
}

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      const std::size_t colon = line.find(':');
      if (colon != std::string::npos) {
        std::size_t start = line.find_first_not_of(" \t", colon + 1);
        return start == std::string::npos ? "unknown" : line.substr(start);
      }
    }
  }
  return "unknown";
}

}  // namespace lightlink::bench
