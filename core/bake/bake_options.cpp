#include "core/bake/bake_options.h"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

namespace lightlink::bake {
namespace {

// How an option reads its value into the options; `label` names it in messages.
using Apply = Status (*)(BakeOptions&, std::string_view value, const std::string& label);

struct Row {
  OptionInfo info;
  Apply apply;
};

std::string shown(std::string_view v) { return std::string(v.substr(0, 64)); }

Expected<long long> integer(std::string_view v, const std::string& label, long long lo, long long hi) {
  long long x = 0;
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
  if (v.empty() || ec != std::errc() || end != v.data() + v.size())
    return invalidInput("{} '{}' is not an integer", label, shown(v));
  if (x < lo || x > hi) return invalidInput("{} {} is out of range ({}..{})", label, x, lo, hi);
  return x;
}

Expected<float> positiveMetres(std::string_view v, const std::string& label) {
  const std::string s(v);
  char* end = nullptr;
  const float x = s.empty() ? 0.0f : std::strtof(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size()) return invalidInput("{} '{}' is not a number", label, shown(v));
  if (!std::isfinite(x) || !(x > 0.0f))
    return invalidInput("{} {} must be a finite number > 0 (metres)", label, shown(v));
  return x;
}

template <typename T, std::size_t N>
Expected<T> choice(std::string_view v, const std::string& label, const EnumNames<T, N>& c) {
  if (const auto value = enumValue(c, v)) return *value;
  std::string names;
  for (std::size_t i = 0; i < N; ++i) names += fmt::format("{}'{}'", i == 0 ? "" : i + 1 == N ? " or " : ", ", c[i].first);
  return invalidInput("{} '{}' must be {}", label, shown(v), names);
}

// The ranges are the daemon's (they were the stricter): one range for every front end.
constexpr Row kRows[] = {
    {{"preset", "draft|medium|high", "Quality preset, applied before every other option"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto p = choice<int>(v, l, std::array<std::pair<std::string_view, int>, 3>{{{"draft", 0}, {"medium", 1}, {"high", 2}}});
       if (!p) return p.status();
       o.preset = std::string(v);
       return {};
     }},
    {{"texel-size", "metres > 0", "Lightmap texel size (overrides the preset's density rule)"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = positiveMetres(v, l);
       if (!x) return x.status();
       o.precompute.texel_size_m = *x;
       return {};
     }},
    {{"texel-budget", "0..268435456", "Texels the charts cover when no texel size is given (0 = one 128 atlas)"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 0, std::int64_t(1) << 28);
       if (!x) return x.status();
       o.precompute.texel_budget = std::uint64_t(*x);
       return {};
     }},
    {{"max-atlas", "16..16384", "Largest atlas page, texels per side"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 16, charts::kMaxAtlasResolution);
       if (!x) return x.status();
       o.precompute.max_atlas = int(*x);
       return {};
     }},
    {{"max-pages", "0..1024", "Most atlas pages (0 = as many as needed; fewer: the texel size is raised)"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 0, 1024);
       if (!x) return x.status();
       o.precompute.max_pages = int(*x);
       return {};
     }},
    {{"resolution", "1..16384", "Atlas page size in texels, instead of the smallest that fits"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 1, charts::kMaxAtlasResolution);
       if (!x) return x.status();
       o.precompute.lightmap_resolution = int(*x);
       return {};
     }},
    {{"direct-scale", "1..8", "Direct-light texels per lightmap texel along each axis (baked shadows finer than the indirect)"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 1, precompute::kMaxDirectScale);
       if (!x) return x.status();
       o.precompute.direct_scale = int(*x);
       return {};
     }},
    {{"surfaces", "FILE", "Surface rules JSON: cast_shadows / contribute_gi / receive_gi by mesh or material name"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       // The front end hands over the rules' text: the CLI reads the file, the daemon takes
       // the JSON itself (it never opens a path a client names).
       if (v.find('{') == std::string_view::npos)
         return invalidInput("{} '{}' must be the surface rules' JSON text ({{\"version\": 1, \"surfaces\": [...]}})", l,
                             shown(v));
       auto r = scene::parseSurfaceRules(v, l);
       if (!r) return r.status();
       o.precompute.surfaces = std::move(r).value();
       return {};
     }},
    {{"uv", "auto|keep|generate", "An existing TEXCOORD_1: kept unless broken (auto), always kept, or regenerated"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto m = choice<charts::UvMode>(v, l, std::array<std::pair<std::string_view, charts::UvMode>, 3>{
                                                 {{"auto", charts::UvMode::kAuto},
                                                  {"keep", charts::UvMode::kKeep},
                                                  {"generate", charts::UvMode::kGenerate}}});
       if (!m) return m.status();
       o.precompute.uv_mode = *m;
       return {};
     }},
    {{"bands", "1..4", "SH bands of the links"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 1, 4);
       if (!x) return x.status();
       o.precompute.bands = int(*x);
       return {};
     }},
    {{"grid", "auto|on|off", "Grid caches (irradiance volume): auto = when dynamic meshes exist"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       using precompute::GridMode;
       auto m = choice<GridMode>(v, l, std::array<std::pair<std::string_view, GridMode>, 3>{
                                           {{"auto", GridMode::kAuto}, {"on", GridMode::kOn}, {"off", GridMode::kOff}}});
       if (!m) return m.status();
       o.precompute.grid = *m;
       return {};
     }},
    {{"grid-spacing", "metres > 0", "Grid spacing (asks for a grid unless grid is given)"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = positiveMetres(v, l);
       if (!x) return x.status();
       o.precompute.grid_spacing_m = *x;
       return {};
     }},
    {{"bounces", "0..256", "Cap on indirect bounces (default 100); the relight stops earlier once converged"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 0, 256);
       if (!x) return x.status();
       o.relight.max_bounces = int(*x);
       return {};
     }},
    {{"seams", "stitch|off", "Make texels on the two sides of smooth UV seams agree (least squares)"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto m = choice<bool>(v, l, std::array<std::pair<std::string_view, bool>, 2>{{{"stitch", true}, {"off", false}}});
       if (!m) return m.status();
       o.relight.stitch_seams = *m;
       return {};
     }},
    {{"indirect", "raw|smooth", "Indirect SH per texel as linked (raw), or averaged over its 3x3 same-plane neighbours (smooth)"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto m = choice<bool>(v, l, std::array<std::pair<std::string_view, bool>, 2>{{{"raw", false}, {"smooth", true}}});
       if (!m) return m.status();
       o.relight.smooth_indirect = *m;
       return {};
     }},
    {{"link-form", "projected|runtime", "Link form the relight uses"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto m = choice(v, l, relight::kLinkFormNames);
       if (!m) return m.status();
       o.relight.link_form = *m;
       return {};
     }},
    {{"surfels", "64..4000000", "nS: number of surfels"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 64, 4000000);
       if (!x) return x.status();
       o.precompute.surfels = std::uint32_t(*x);
       return {};
     }},
    {{"links", "1..4096", "nL: most links per cache"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 1, 4096);
       if (!x) return x.status();
       o.precompute.links = int(*x);
       return {};
     }},
    {{"rays", "16..65536", "Link rays per cache"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto x = integer(v, l, 16, 65536);
       if (!x) return x.status();
       o.precompute.rays = int(*x);
       return {};
     }},
    {{"hierarchy", "fast|hac", "Tree builder: fast (kd median) or hac (agglomerative)"},
     [](BakeOptions& o, std::string_view v, const std::string& l) -> Status {
       auto m = choice(v, l, hierarchy::kBuilderNames);
       if (!m) return m.status();
       o.precompute.builder = *m;
       return {};
     }},
};

const Row* find(std::string_view name) {
  for (const Row& r : kRows)
    if (r.info.name == name) return &r;
  return nullptr;
}

std::array<OptionInfo, std::size(kRows)> makeTable() {
  std::array<OptionInfo, std::size(kRows)> t{};
  for (std::size_t i = 0; i < std::size(kRows); ++i) t[i] = kRows[i].info;
  return t;
}

}  // namespace

std::span<const OptionInfo> optionTable() {
  static const auto table = makeTable();
  return table;
}

BakeOptionsBuilder::BakeOptionsBuilder(std::string default_preset, relight::RelightOptions relight_defaults,
                                       std::string flag_prefix)
    : default_preset_(std::move(default_preset)),
      relight_defaults_(relight_defaults),
      prefix_(std::move(flag_prefix)) {}

Status BakeOptionsBuilder::set(std::string_view name, std::string_view value, std::string_view label) {
  const Row* row = find(name);
  if (row == nullptr) {
    std::string known;
    for (const Row& r : kRows) known += fmt::format("{}{}", known.empty() ? "" : ", ", r.info.name);
    return invalidInput("{}{}: unknown bake option (known: {})", prefix_, shown(name), known);
  }
  const std::string l = label.empty() ? prefix_ + std::string(name) : std::string(label);
  BakeOptions scratch;  // checks the value now, so that a bad one fails where it was given
  if (Status s = row->apply(scratch, value, l); !s) return s;
  settings_.emplace_back(std::string(name), std::string(value));
  labels_.push_back(l);
  return {};
}

bool BakeOptionsBuilder::has(std::string_view name) const {
  for (const auto& [n, v] : settings_)
    if (n == name) return true;
  return false;
}

Expected<BakeOptions> BakeOptionsBuilder::build() const {
  BakeOptions o;
  o.preset = default_preset_;
  for (const auto& [n, v] : settings_)
    if (n == "preset") o.preset = v;  // the last one given wins, and applies first
  if (!o.preset.empty()) {
    auto p = precompute::preset(o.preset);
    if (!p) return p.status();
    o.precompute = *p;
  }
  o.relight = relight_defaults_;
  for (std::size_t i = 0; i < settings_.size(); ++i) {
    if (settings_[i].first == "preset") continue;
    if (Status s = find(settings_[i].first)->apply(o, settings_[i].second, labels_[i]); !s) return s;
  }
  // Asking for a spacing is asking for a grid, even in a scene without dynamic meshes.
  if (has("grid-spacing") && !has("grid")) o.precompute.grid = precompute::GridMode::kOn;
  if (Status s = validate(o); !s) return s;
  return o;
}

Expected<BakeOptions> buildBakeOptions(std::span<const std::pair<std::string, std::string>> settings,
                                       std::string default_preset, relight::RelightOptions relight_defaults,
                                       std::string flag_prefix) {
  BakeOptionsBuilder b(std::move(default_preset), relight_defaults, std::move(flag_prefix));
  for (const auto& [n, v] : settings)
    if (Status s = b.set(n, v); !s) return s;
  return b.build();
}

Status validate(const BakeOptions& o) {
  if (Status s = o.precompute.validate(); !s) return s;
  if (o.relight.max_bounces < 0 || o.relight.max_bounces > 256)
    return invalidInput("--bounces {} is out of range (0..256)", o.relight.max_bounces);
  if (o.relight.link_form != relight::LinkForm::kProjected && o.relight.link_form != relight::LinkForm::kRuntime)
    return invalidInput("--link-form {} is not projected or runtime", static_cast<int>(o.relight.link_form));
  return {};
}

}  // namespace lightlink::bake
