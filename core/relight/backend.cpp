#include "core/relight/backend.h"

namespace lightlink::relight {
namespace {

class CpuBackend final : public RelightBackend {
 public:
  explicit CpuBackend(Relighter r) : relighter_(std::move(r)) {}
  std::string_view name() const override { return "cpu"; }
  EffectsPlan plan(const LightSet& lights, const RelightOptions& options) const override {
    return relighter_.plan(lights, options);
  }
  Status relightInto(const LightSet& lights, const RelightOptions& options, RelightResult& out) override {
    Status s = relighter_.relightInto(lights, options, out);
    if (s) out.backend = "cpu";
    return s;
  }
  bool incrementalFor(const LightSet& lights, const RelightOptions& options) const override {
    return relighter_.incrementalFor(lights, options);
  }
  void invalidate() override { relighter_.invalidate(); }

 private:
  Relighter relighter_;
};

}  // namespace

Expected<std::unique_ptr<RelightBackend>> makeCpuBackend(const scene::Scene& scene, const rt::Accel& accel,
                                                         const precompute::Precomputation& p,
                                                         links::LinksView lightmap_links,
                                                         links::LinksView grid_links) {
  auto r = Relighter::create(scene, accel, p, lightmap_links, grid_links);
  if (!r) return r.status();
  return std::unique_ptr<RelightBackend>(std::make_unique<CpuBackend>(std::move(r).value()));
}

}  // namespace lightlink::relight
