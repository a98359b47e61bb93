// Bake options: one table, one parser, one validator (core/bake/bake_options.h).
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "core/bake/bake_options.h"
#include "tests/common/testing.h"

namespace lightlink::bake {
namespace {

using Settings = std::vector<std::pair<std::string, std::string>>;

TEST(BakeOptions, UnknownNameIsRejectedListingTheKnownOnes) {
  BakeOptionsBuilder b;
  const Status s = b.set("texel-sise", "0.1");
  ASSERT_FALSE(s);
  EXPECT_EQ(s.code(), Code::kInvalidInput);
  EXPECT_NE(s.message().find("--texel-sise"), std::string::npos) << s.message();
  for (const OptionInfo& o : optionTable())
    EXPECT_NE(s.message().find(std::string(o.name)), std::string::npos) << o.name << ": " << s.message();
}

TEST(BakeOptions, MalformedAndOutOfRangeValuesNameTheOption) {
  const Settings bad = {{"bands", "5"},        {"bands", "two"},          {"bounces", "257"},
                        {"max-atlas", "8"},    {"max-pages", "-1"},       {"texel-size", "0"},
                        {"texel-size", "nan"}, {"texel-size", "0.1m"},    {"grid", "maybe"},
                        {"grid-spacing", "-2"}, {"link-form", "linear"},  {"uv", "reuse"},
                        {"surfels", "63"},     {"links", "4097"},         {"rays", "8"},
                        {"hierarchy", "bvh"},  {"preset", "ultra"},       {"resolution", "0"},
                        {"texel-budget", "-3"},  {"surfaces", "rules.json"},
                        {"surfaces", R"({"version": 3, "surfaces": []})"}};
  for (const auto& [name, value] : bad) {
    BakeOptionsBuilder b;
    const Status s = b.set(name, value);
    ASSERT_FALSE(s) << name << " " << value;
    EXPECT_NE(s.message().find("--" + name), std::string::npos) << name << ": " << s.message();
    EXPECT_TRUE(b.settings().empty());
  }
  // A prefix other than "--" (OpenScene's "options.") and a label (an older field name).
  BakeOptionsBuilder daemon("medium", {}, "options.");
  EXPECT_NE(daemon.set("bands", "9").message().find("options.bands"), std::string::npos);
  EXPECT_NE(daemon.set("grid-spacing", "nan", "grid_spacing").message().find("grid_spacing"), std::string::npos);
}

TEST(BakeOptions, PresetAppliesFirstThenTheSettingsInAnyOrder) {
  auto a = buildBakeOptions(Settings{{"bands", "2"}, {"preset", "draft"}, {"texel-size", "0.05"}});
  auto b = buildBakeOptions(Settings{{"preset", "draft"}, {"texel-size", "0.05"}, {"bands", "2"}});
  ASSERT_TRUE(a) << a.status().message();
  ASSERT_TRUE(b) << b.status().message();
  auto draft = precompute::preset("draft");
  ASSERT_TRUE(draft);
  EXPECT_EQ(a->preset, "draft");
  EXPECT_EQ(a->precompute.surfels, draft->surfels);  // from the preset
  EXPECT_EQ(a->precompute.bands, 2);                 // given after the preset was applied
  ASSERT_TRUE(a->precompute.texel_size_m);
  EXPECT_FLOAT_EQ(*a->precompute.texel_size_m, 0.05f);
  EXPECT_EQ(a->precompute.canonical(), b->precompute.canonical());
  // No setting: the default preset; its canonical form is the preset's.
  auto medium = buildBakeOptions(Settings{});
  ASSERT_TRUE(medium);
  EXPECT_EQ(medium->precompute.canonical(), precompute::preset("medium")->canonical());
}

TEST(BakeOptions, EveryOptionReachesTheOptions) {
  auto o = buildBakeOptions(Settings{{"preset", "high"},       {"texel-budget", "5000"}, {"max-atlas", "512"},
                                     {"max-pages", "3"},       {"resolution", "256"},    {"uv", "generate"},
                                     {"bands", "4"},           {"grid-spacing", "0.5"},  {"bounces", "3"},
                                     {"link-form", "runtime"}, {"surfels", "1000"},      {"links", "17"},
                                     {"rays", "99"},           {"hierarchy", "fast"}});
  ASSERT_TRUE(o) << o.status().message();
  EXPECT_EQ(o->precompute.texel_budget, 5000u);
  EXPECT_EQ(o->precompute.max_atlas, 512);
  EXPECT_EQ(o->precompute.max_pages, 3);
  EXPECT_EQ(o->precompute.lightmap_resolution, 256);
  EXPECT_EQ(o->precompute.uv_mode, charts::UvMode::kGenerate);
  EXPECT_EQ(o->precompute.bands, 4);
  EXPECT_FLOAT_EQ(o->precompute.grid_spacing_m, 0.5f);
  EXPECT_EQ(o->precompute.grid, precompute::GridMode::kOn);  // a spacing asks for a grid
  EXPECT_EQ(o->relight.max_bounces, 3);
  EXPECT_EQ(o->relight.link_form, relight::LinkForm::kRuntime);
  EXPECT_EQ(o->precompute.surfels, 1000u);
  EXPECT_EQ(o->precompute.links, 17);
  EXPECT_EQ(o->precompute.rays, 99);
  EXPECT_EQ(o->precompute.builder, hierarchy::Builder::kKdMedian);
  // The uv mode is part of the cache key.
  auto keep = buildBakeOptions(Settings{{"uv", "keep"}});
  ASSERT_TRUE(keep);
  EXPECT_NE(keep->precompute.canonical(), buildBakeOptions(Settings{})->precompute.canonical());
  // An explicit grid wins over the spacing's implied one, whatever the order.
  auto off = buildBakeOptions(Settings{{"grid", "off"}, {"grid-spacing", "0.5"}});
  ASSERT_TRUE(off);
  EXPECT_EQ(off->precompute.grid, precompute::GridMode::kOff);
}

TEST(BakeOptions, RelightDefaultsHoldUntilASettingChangesThem) {
  relight::RelightOptions daemon;
  daemon.max_bounces = 5;
  auto kept = buildBakeOptions(Settings{}, "medium", daemon);
  ASSERT_TRUE(kept);
  EXPECT_EQ(kept->relight.max_bounces, 5);
  auto given = buildBakeOptions(Settings{{"bounces", "0"}}, "medium", daemon);
  ASSERT_TRUE(given);
  EXPECT_EQ(given->relight.max_bounces, 0);
  // No preset: PrecomputeOptions' defaults (what `lightlink precompute` starts from).
  auto raw = buildBakeOptions(Settings{}, "");
  ASSERT_TRUE(raw);
  EXPECT_EQ(raw->precompute.canonical(), precompute::PrecomputeOptions{}.canonical());
}

TEST(BakeOptions, ValidatorChecksTheWhole) {
  BakeOptions o;
  o.relight.max_bounces = 257;
  EXPECT_FALSE(validate(o));
  o.relight.max_bounces = 8;
  EXPECT_TRUE(validate(o));
  o.precompute.bands = 0;
  EXPECT_NE(validate(o).message().find("--bands"), std::string::npos);
}

// docs/cli.md lists every option of the table, so that the docs cannot drift from the code.
TEST(BakeOptions, DocsListEveryOption) {
  std::ifstream in(testing::sourceDir() / "docs/cli.md");
  ASSERT_TRUE(in) << "docs/cli.md not found";
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string doc = ss.str();
  const auto section = doc.find("## Bake options");
  ASSERT_NE(section, std::string::npos) << "docs/cli.md has no \"## Bake options\" section";
  const std::string table = doc.substr(section, doc.find("\n## ", section + 1) - section);
  for (const OptionInfo& o : optionTable()) {
    std::string value;  // a '|' inside a Markdown table cell is written "\|"
    for (char c : o.value) value += c == '|' ? std::string("\\|") : std::string(1, c);
    const std::string row = "| `--" + std::string(o.name) + "` | " + value + " |";
    EXPECT_NE(table.find(row), std::string::npos) << "docs/cli.md \"Bake options\" lacks the row " << row;
  }
}

// Surface rules reach the cache key: the same rules written differently give one key, other
// rules another, and no rules leave the key as it was before the option existed.
TEST(BakeOptions, SurfaceRulesArePartOfTheCanonicalOptions) {
  auto none = buildBakeOptions(Settings{{"preset", "draft"}});
  auto a = buildBakeOptions(Settings{{"surfaces", R"({"version": 1, "surfaces": [{"mesh": "x", "cast_shadows": false}]})"}});
  auto b = buildBakeOptions(Settings{{"surfaces", R"({"surfaces": [{"cast_shadows": false, "mesh": "x"}], "version": 1})"}});
  auto c = buildBakeOptions(Settings{{"surfaces", R"({"version": 1, "surfaces": [{"mesh": "y", "cast_shadows": false}]})"}});
  ASSERT_TRUE(none && a && b && c);
  EXPECT_EQ(none->precompute.canonical().find("surfaces="), std::string::npos);
  EXPECT_EQ(a->precompute.canonical(), b->precompute.canonical());
  EXPECT_NE(a->precompute.canonical(), c->precompute.canonical());
  EXPECT_EQ(a->precompute.surfaces.rules.size(), 1u);
}

}  // namespace
}  // namespace lightlink::bake
