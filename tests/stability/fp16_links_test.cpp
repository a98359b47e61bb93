// fp16 link coefficients vs the float projection they were rounded from (DESIGN.md sec 4:
// coefficients are SH of V/pi, bounded |c| <= ~4, so they fit fp16 at any scene scale).
//
// The float projection is recomputed here from the public pieces link generation is made of:
// the same rays (LinkRays), the same owner lookup (SurfelLocator), the same cut (the stored
// link nodes), and sh::evalBasis. Bounds used:
//   per coefficient: |h - f| <= 2^-11 |f| + 2^-25 (round to nearest half: half an ulp,
//                    relative 2^-11 for normals, absolute 2^-25 in the subnormal range),
//                    plus 1e-6 for the different float summation order;
//   per cache:       irradiance (uniform sender radiosity 1, at the cache normal) within
//                    1e-3 relative of the float links' value.
// Run on a millimetre-scale room, where folding 1/A into the coefficients (seed 000) would
// overflow fp16 by orders of magnitude: the coefficients must not depend on the scale.
#include <algorithm>
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "core/links/surfel_locator.h"
#include "tests/stability/stability_fixture.h"

namespace lightlink::stability {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

TEST(StabilityFp16, HalfLinkCoefficientsMatchTheFloatProjection) {
  const float s = 1e-3f;  // a 3 mm x 2 mm x 3 mm room with a 0.6 mm block
  scene::Scene sc;
  addBox(sc, glm::vec3(0.0f), s * glm::vec3(3, 2, 3), /*inward=*/true);
  addBox(sc, s * glm::vec3(1.2f, 0.0f, 1.2f), s * glm::vec3(1.8f, 0.6f, 1.8f), /*inward=*/false);
  auto o = tinyOptions();
  o.rays = 256;
  o.links = 48;
  auto baked = Baked::make(std::move(sc), o);
  ASSERT_TRUE(baked);
  const auto& p = baked->p;
  const auto& links = p.lightmap_links;
  const int bands = links.bands, nc = bands * bands;
  ASSERT_EQ(bands, 3);

  const links::LinkOptions lo{.rays = o.rays, .max_links = o.links, .bands = o.bands, .seed = o.seed};
  const links::LinkRays pattern(lo);
  const links::SurfelLocator locator(p.surfels, baked->scene);
  const std::uint32_t count = pattern.count();
  const float w = 2.0f * kPi / float(count) / kPi;  // hemisphere caches
  std::vector<rt::Ray> rays(count);
  std::vector<rt::Hit> hits(count);
  std::vector<std::uint32_t> owner(count);
  std::vector<float> f(nc);
  double worst_coeff = 0.0, worst_e = 0.0, max_abs = 0.0;
  std::size_t coeffs_checked = 0, caches_checked = 0;
  for (std::size_t c = 0; c < p.lightmap.size(); ++c) {
    pattern.generate(*baked->accel, c, p.lightmap.position[c], p.lightmap.normal[c], rays);
    baked->accel->intersect(rays, hits, rt::Coherence::kCoherent);
    for (std::uint32_t i = 0; i < count; ++i) {
      owner[i] = links::kNoSurfel;
      const rt::Hit& h = hits[i];
      if (!h.hit()) continue;
      const bool back = h.backFacing(rays[i].dir);
      if (back && !baked->scene.materialOf(baked->scene.meshes[h.mesh]).double_sided) continue;
      owner[i] = locator.ownerOfHit(locator.sideMesh(h.mesh, back), h.triangle, h.u, h.v, rays[i].origin + h.t * rays[i].dir,
                                    back ? -h.ng : h.ng);
    }
    std::vector<float> sh_f(nc, 0.0f), sh_h(nc, 0.0f);
    for (std::uint32_t k = links.offsets[c]; k < links.offsets[c + 1]; ++k) {
      const std::uint32_t node = links.node[k];
      std::fill(f.begin(), f.end(), 0.0f);
      float basis[sh::kMaxCoeffs];
      for (std::uint32_t i = 0; i < count; ++i) {
        if (owner[i] == links::kNoSurfel || owner[i] < p.tree.begin[node] || owner[i] >= p.tree.end[node]) continue;
        sh::evalBasis(bands, rays[i].dir, basis);
        for (int q = 0; q < nc; ++q) f[q] += w * basis[q];
      }
      for (int q = 0; q < nc; ++q) {
        const float h = fromHalf(links.coeffs[std::size_t(k) * nc + q]);
        const double bound = std::ldexp(std::abs(f[q]), -11) + std::ldexp(1.0, -25) + 1e-6;
        const double err = std::abs(double(h) - f[q]);
        worst_coeff = std::max(worst_coeff, err / bound);
        max_abs = std::max(max_abs, double(std::abs(h)));
        ASSERT_LE(err, bound) << "cache " << c << " link " << k << " coefficient " << q << ": half " << h
                              << " float " << f[q];
        sh_f[q] += f[q];
        sh_h[q] += h;
        ++coeffs_checked;
      }
    }
    // Uniform sender radiosity 1: incident radiance = sum of the links' SH.
    const glm::vec3 n = p.lightmap.normal[c];
    const float ef = sh::irradiance(bands, sh_f.data(), n), eh = sh::irradiance(bands, sh_h.data(), n);
    if (ef > 0.01f) {
      worst_e = std::max(worst_e, double(std::abs(eh - ef) / ef));
      EXPECT_NEAR(eh, ef, 1e-3f * ef) << "cache " << c;
      ++caches_checked;
    }
  }
  EXPECT_GT(caches_checked, 100u);
  // Bounded visibilities, independent of the 1e-6 m^2 surfel areas: fp16 is far from overflow.
  EXPECT_LE(max_abs, 4.0);
  std::printf("fp16 links: %zu coefficients, worst error %.2f of the bound; %zu caches, worst irradiance rel. "
              "error %.2e; largest |c| %.3f\n",
              coeffs_checked, worst_coeff, caches_checked, worst_e, max_abs);
}

}  // namespace
}  // namespace lightlink::stability
