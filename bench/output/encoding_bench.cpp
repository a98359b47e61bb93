// encoding_bench: what each lightmap encoding costs and loses on one scene (docs/outputs.md
// "Encodings: figures"). Bakes the scene once (reusing a cached artifact), relights on the
// CPU, then for l0, l1 and l2, in half and in float: writes the lightmap and grid files
// (median write time over --repeats runs), counts their bytes, reads them back as
// `lightlink render` does (viewer::loadBakedLighting) and compares, at every valid lightmap
// texel's centre and cache normal, the irradiance they give (indirect + baked direct) with
// the one of the float L2 files, which hold the result bit-exactly (tests/output). Prints a
// table and, with --json, writes it.
//
//   encoding_bench SCENE [--preset P] [--lights F] [--cache-dir D] [--out DIR] [--repeats N] [--json F]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/common/bench_common.h"
#include "clients/viewer/baked_lighting.h"
#include "core/bake/bake_options.h"
#include "core/output/output.h"
#include "core/precompute/resident.h"
#include "core/relight/relight.h"

namespace fs = std::filesystem;
using namespace lightlink;

namespace {

struct Args {
  std::string scene, preset = "medium", lights, cache_dir = "/tmp/lightlink-encoding-bench/cache",
                     out = "/tmp/lightlink-encoding-bench/out", json;
  int repeats = 3;
};

std::uintmax_t bytesOf(const fs::path& dir, const std::vector<std::string>& files) {
  std::uintmax_t n = 0;
  for (const auto& f : files) n += fs::file_size(dir / f);
  return n;
}

// Irradiance (indirect + direct) at every valid lightmap texel's centre and cache normal.
std::vector<glm::vec3> irradianceAtTexels(const viewer::BakedLighting& b, const caches::LightmapCaches& lm,
                                          const std::vector<std::uint8_t>& texel_valid) {
  std::vector<glm::vec3> out;
  for (std::size_t t = 0; t < lm.cache_of_texel.size(); ++t) {
    const std::int32_t c = lm.cache_of_texel[t];
    if (c < 0 || !texel_valid[t]) continue;
    const glm::vec2 uv((float(t % lm.width) + 0.5f) / float(lm.width), (float(t / lm.width) + 0.5f) / float(lm.height));
    glm::vec3 e(0.0f);
    (void)b.sampleLightmap(uv, lm.normal[c], e);
    out.push_back(e);
  }
  return out;
}

struct Error {
  double rel_rmse = 0.0, p95 = 0.0;
};

// RMS error over RMS reference (all texels, RGB), and the 95th percentile of the per-texel
// error over the texel's largest reference channel, floored at 1 % of the reference RMS.
Error compare(const std::vector<glm::vec3>& got, const std::vector<glm::vec3>& ref) {
  double se = 0.0, sv = 0.0;
  for (std::size_t i = 0; i < ref.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      se += double(got[i][c] - ref[i][c]) * double(got[i][c] - ref[i][c]);
      sv += double(ref[i][c]) * double(ref[i][c]);
    }
  const double rms = std::sqrt(sv / double(3 * std::max<std::size_t>(ref.size(), 1)));
  std::vector<double> rel(ref.size());
  for (std::size_t i = 0; i < ref.size(); ++i) {
    const glm::vec3 d = glm::abs(got[i] - ref[i]);
    const double mag = std::max({double(ref[i].x), double(ref[i].y), double(ref[i].z), 0.01 * rms});
    rel[i] = double(std::max({d.x, d.y, d.z})) / mag;
  }
  std::sort(rel.begin(), rel.end());
  Error e;
  e.rel_rmse = sv > 0.0 ? std::sqrt(se / sv) : 0.0;
  e.p95 = rel.empty() ? 0.0 : rel[std::min(rel.size() - 1, std::size_t(0.95 * double(rel.size())))];
  return e;
}

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string f = argv[i];
    const char* v = i + 1 < argc ? argv[i + 1] : nullptr;
    if (f == "--preset" && v) a.preset = argv[++i];
    else if (f == "--lights" && v) a.lights = argv[++i];
    else if (f == "--cache-dir" && v) a.cache_dir = argv[++i];
    else if (f == "--out" && v) a.out = argv[++i];
    else if (f == "--json" && v) a.json = argv[++i];
    else if (f == "--repeats" && v) a.repeats = std::max(1, std::atoi(argv[++i]));
    else if (a.scene.empty() && f[0] != '-') a.scene = f;
    else {
      std::fprintf(stderr, "usage: %s SCENE [--preset P] [--lights F] [--cache-dir D] [--out DIR] [--repeats N] [--json F]\n",
                   argv[0]);
      return 2;
    }
  }
  if (a.scene.empty()) {
    std::fprintf(stderr, "encoding_bench: no SCENE\n");
    return 2;
  }
  const std::vector<std::pair<std::string, std::string>> settings = {{"preset", a.preset}};
  auto options = bake::buildBakeOptions(settings, a.preset);
  if (bench::failed(options)) return 2;
  precompute::ResidentRequest request;
  request.scene_path = a.scene;
  request.options = options->precompute;
  request.cache_dir = a.cache_dir;
  auto resident = precompute::ResidentScene::open(request);
  if (bench::failed(resident)) return 2;
  const precompute::Precomputation& p = resident->precomputation();
  auto relighter = relight::Relighter::create(resident->scene(), resident->accel(), p, resident->lightmapLinks(),
                                              resident->gridLinks());
  if (bench::failed(relighter)) return 2;
  relight::LightSet lights = a.lights.empty() ? bench::lightsOrSun(resident->scene())
                                              : relight::LightSet::fromSceneLights(resident->scene().lights);
  if (!a.lights.empty()) {
    if (Status s = lights.applyFile(a.lights); !s) {
      std::fprintf(stderr, "%s\n", s.toString().c_str());
      return 2;
    }
  }
  auto result = relighter->relight(lights, options->relight);
  if (bench::failed(result)) return 2;
  const caches::LightmapCaches* direct_texels = p.hasDirectLayer() ? &p.direct_texels : nullptr;

  struct Row {
    std::string encoding, precision;
    std::uintmax_t lightmap_bytes = 0, grid_bytes = 0;
    std::size_t files = 0;
    double write_ms = 0.0;
    Error error;
  };
  std::vector<Row> rows;
  std::vector<glm::vec3> reference;
  // Float L2 first: the reference the others are measured against.
  for (const bool half : {false, true})
    for (const output::Encoding enc : {output::Encoding::kL2, output::Encoding::kL1, output::Encoding::kL0}) {
      Row row;
      row.encoding = std::string(output::encodingName(enc));
      row.precision = half ? "half" : "float";
      const fs::path dir = fs::path(a.out) / (row.encoding + "_" + row.precision);
      fs::remove_all(dir);
      fs::create_directories(dir);
      const output::ExrOptions exr{.half = half, .encoding = enc};
      std::vector<double> ms;
      output::WrittenExrs lm, grid;
      for (int r = 0; r < a.repeats; ++r) {
        const auto t0 = bench::Clock::now();
        auto l = output::writeLightmapExrs(*result, p.lightmap, dir.string(), exr, direct_texels);
        if (bench::failed(l)) return 2;
        lm = std::move(*l);
        if (p.has_grid) {
          auto g = output::writeGridExrs(*result, p.grid, dir.string(), exr);
          if (bench::failed(g)) return 2;
          grid = std::move(*g);
          if (Status s = output::writeGridRaw(*result, p.grid, (dir / "grid.raw").string(), enc); !s) return 2;
        }
        ms.push_back(1e3 * bench::secondsSince(t0));
      }
      row.write_ms = bench::median(ms);
      row.lightmap_bytes = bytesOf(dir, lm.files);
      row.grid_bytes = bytesOf(dir, grid.files);
      row.files = lm.files.size() + grid.files.size();
      auto back = viewer::loadBakedLighting(dir.string());
      if (bench::failed(back)) return 2;
      const std::vector<glm::vec3> e = irradianceAtTexels(*back, p.lightmap, result->texel_valid);
      if (reference.empty()) reference = e;
      row.error = compare(e, reference);
      rows.push_back(row);
    }

  std::printf("scene %s, preset %s: lightmap %dx%d (direct %dx%d), %d bands, grid %s, %zu valid texels compared\n",
              fs::path(a.scene).filename().c_str(), a.preset.c_str(), result->width, result->height,
              result->directIsFiner() ? result->direct_width : result->width,
              result->directIsFiner() ? result->direct_height : result->height, result->bands,
              p.has_grid ? fmt::format("{}x{}x{}", p.grid.dims.x, p.grid.dims.y, p.grid.dims.z).c_str() : "none",
              reference.size());
  std::printf("%-8s %-6s %6s %14s %12s %10s %10s %10s\n", "encoding", "prec", "files", "lightmap bytes", "grid bytes",
              "write ms", "rel RMSE", "p95 rel");
  nlohmann::ordered_json j;
  j["scene"] = a.scene;
  j["preset"] = a.preset;
  j["lightmap"] = {result->width, result->height};
  j["bands"] = result->bands;
  j["texels_compared"] = reference.size();
  for (const Row& r : rows) {
    std::printf("%-8s %-6s %6zu %14ju %12ju %10.1f %10.5f %10.5f\n", r.encoding.c_str(), r.precision.c_str(), r.files,
                r.lightmap_bytes, r.grid_bytes, r.write_ms, r.error.rel_rmse, r.error.p95);
    j["rows"].push_back({{"encoding", r.encoding}, {"precision", r.precision}, {"files", r.files},
                         {"lightmap_bytes", r.lightmap_bytes}, {"grid_bytes", r.grid_bytes}, {"write_ms", r.write_ms},
                         {"rel_rmse", r.error.rel_rmse}, {"p95_rel_error", r.error.p95}});
  }
  if (!a.json.empty()) std::ofstream(a.json) << j.dump(1) << "\n";
  return 0;
}
