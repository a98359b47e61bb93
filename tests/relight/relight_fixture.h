// Small scenes built in code plus their precomputation, for the relight and output tests.
#pragma once

#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "core/precompute/precompute.h"
#include "core/relight/relight.h"
#include "core/rt/accel.h"
#include "tests/common/scene_builders.h"

namespace lightlink::relight::testing {

using lightlink::testing::addBox;
using lightlink::testing::addMaterial;
using lightlink::testing::addQuad;

inline void finish(scene::Scene& s) {
  s.source_path = "test-scene";
  lightlink::testing::finishScene(s);
}

// Scene + accel + precomputation, in the order precompute builds them.
struct Baked {
  scene::Scene scene;
  std::optional<rt::Accel> accel;
  precompute::Precomputation p;

  static std::unique_ptr<Baked> make(scene::Scene s, precompute::PrecomputeOptions o) {
    auto b = std::make_unique<Baked>();
    finish(s);
    b->scene = std::move(s);
    auto p = precompute::run(b->scene, o);
    EXPECT_TRUE(p) << p.status().toString();
    if (!p) return nullptr;
    b->p = std::move(p).value();
    auto a = rt::Accel::build(b->scene);
    EXPECT_TRUE(a) << a.status().toString();
    b->accel.emplace(std::move(a).value());
    return b;
  }

  Relighter relighter() const {
    auto r = Relighter::create(scene, *accel, p);
    EXPECT_TRUE(r) << r.status().toString();
    return std::move(r).value();
  }
};

inline precompute::PrecomputeOptions smallOptions() {
  precompute::PrecomputeOptions o;
  o.surfels = 2048;
  o.links = 64;
  o.rays = 256;
  o.lightmap_resolution = 32;
  o.validity_rays = 16;
  o.builder = hierarchy::Builder::kKdMedian;
  return o;
}

}  // namespace lightlink::relight::testing
