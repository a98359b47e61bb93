#include "service/snapshot.h"

#include <cstring>

#include <grpcpp/impl/codegen/proto_utils.h>

#include "core/common/half.h"
#include "service/result_stream.h"

namespace lightlink::service {
namespace {

// Appends `count` values of `src` as half or float, little-endian (the host order on every
// platform lightlink builds for; x86-64 and aarch64 are little-endian).
void appendValues(std::string& out, const float* src, std::size_t count, bool half, std::size_t& clamped) {
  if (half) {
    const std::size_t at = out.size();
    out.resize(at + count * 2);
    clamped += toHalfSaturating(std::span<const float>(src, count), reinterpret_cast<half_bits*>(out.data() + at));
  } else {
    const std::size_t at = out.size();
    out.resize(at + count * 4);
    std::memcpy(out.data() + at, src, count * 4);
  }
}

// SH block per element: the first `nc` coefficients of each channel of a block with `NC`.
void appendShPrefix(std::string& out, const std::vector<float>& sh, std::size_t elements, int bands, int result_bands,
                    bool half, std::size_t& clamped) {
  const std::size_t nc = static_cast<std::size_t>(bands) * bands;
  const std::size_t NC = static_cast<std::size_t>(result_bands) * result_bands;
  out.reserve(elements * 3 * nc * (half ? 2 : 4));
  if (nc == NC) {
    appendValues(out, sh.data(), elements * 3 * NC, half, clamped);
    return;
  }
  for (std::size_t e = 0; e < elements; ++e)
    for (std::size_t c = 0; c < 3; ++c) appendValues(out, sh.data() + (e * 3 + c) * NC, nc, half, clamped);
}

}  // namespace

SpecKey SpecKey::from(const v1::ResultSpec& spec, int result_bands) {
  SpecKey k;
  k.lightmap = !spec.skip_lightmap();
  k.grid = !spec.skip_grid();
  k.bands = spec.bands() == 0 ? result_bands : spec.bands();
  k.component = spec.component();
  k.precision = spec.precision();
  return k;
}

std::size_t Snapshot::bytes() const {
  return lightmap_sh.size() * sizeof(float) + direct.size() * sizeof(float) + texel_valid.size() +
         grid_sh.size() * sizeof(float);
}

std::shared_ptr<const EncodedResult> Snapshot::encoded(const SpecKey& spec) const {
  std::lock_guard lock(cache_mutex_);
  auto it = cache_.find(spec);
  if (it != cache_.end()) return it->second;
  // Encoding under the lock: readers with the same spec wait for the one encode instead
  // of repeating it; a snapshot has few distinct specs.
  auto e = std::make_shared<const EncodedResult>(encodeSnapshot(*this, spec));
  cache_.emplace(spec, e);
  return e;
}

std::shared_ptr<const WireResult> Snapshot::wire(const SpecKey& spec, std::size_t chunk_bytes, const Snapshot* previous,
                                                 bool delta) const {
  // Built under the lock, as encoded(): a new result wakes every long-polling client and
  // every subscriber at once, and they wait for one build instead of each building the same
  // bytes (with 50 long polls, their 50 builds took 12 % of all cycles in a perf profile of
  // bench/service before the build moved under this lock).
  std::lock_guard lock(wire_mutex_);
  delta = delta && previous != nullptr;
  const WireKey key{spec, chunk_bytes, previous ? previous->sequence : 0, delta};
  if (auto it = wire_cache_.find(key); it != wire_cache_.end()) return it->second;
  const auto e = encoded(spec);
  auto w = std::make_shared<WireResult>();
  const MessageWriter serialize = [&](const v1::ResultMessage& m) {
    grpc::ByteBuffer buffer;
    bool own = false;
    if (!grpc::SerializationTraits<v1::ResultMessage>::Serialize(m, &buffer, &own).ok()) return false;
    w->bytes += buffer.Length();
    w->messages.emplace_back().Swap(&buffer);
    return true;
  };
  const HeaderExtras extras{scene_id, previous ? sequence - previous->sequence - 1 : 0};
  const bool ok = delta ? sendDelta(*this, *e, *previous->encoded(spec), extras, chunk_bytes, serialize)
                        : sendFull(*this, *e, extras, chunk_bytes, serialize);
  if (!ok) return nullptr;
  return wire_cache_.emplace(key, std::move(w)).first->second;
}

EncodedResult encodeSnapshot(const Snapshot& s, const SpecKey& spec) {
  EncodedResult r;
  r.spec = spec;
  const bool half = spec.precision == v1::PRECISION_HALF;
  const std::size_t value_bytes = half ? 2 : 4;
  const std::size_t nc = static_cast<std::size_t>(spec.bands) * spec.bands;
  const std::size_t texels = static_cast<std::size_t>(s.width) * s.height;
  const bool indirect = spec.component != v1::COMPONENT_DIRECT;
  const bool direct = spec.component != v1::COMPONENT_INDIRECT;
  if (spec.lightmap && texels > 0) {
    if (indirect) {
      EncodedPayload p{v1::PAYLOAD_LIGHTMAP_SH, {}, 3 * nc * value_bytes};
      appendShPrefix(p.bytes, s.lightmap_sh, texels, spec.bands, s.bands, half, r.half_clamped);
      r.payloads.push_back(std::move(p));
    }
    if (direct) {
      EncodedPayload p{v1::PAYLOAD_LIGHTMAP_DIRECT, {}, 3 * value_bytes};
      appendValues(p.bytes, s.direct.data(), texels * 3, half, r.half_clamped);
      r.payloads.push_back(std::move(p));
    }
    EncodedPayload v{v1::PAYLOAD_LIGHTMAP_VALID, {}, 1};
    v.bytes.assign(reinterpret_cast<const char*>(s.texel_valid.data()), s.texel_valid.size());
    r.payloads.push_back(std::move(v));
  }
  // The grid holds indirect SH only: it is part of COMPONENT_INDIRECT and BOTH.
  if (spec.grid && s.grid.present && indirect) {
    const std::size_t points = static_cast<std::size_t>(s.grid.dims.x) * s.grid.dims.y * s.grid.dims.z;
    EncodedPayload p{v1::PAYLOAD_GRID_SH, {}, 3 * nc * value_bytes};
    appendShPrefix(p.bytes, s.grid_sh, points, spec.bands, s.bands, half, r.half_clamped);
    r.payloads.push_back(std::move(p));
    EncodedPayload v{v1::PAYLOAD_GRID_VALID, {}, 1};
    if (s.grid_valid) v.bytes.assign(reinterpret_cast<const char*>(s.grid_valid->data()), s.grid_valid->size());
    r.payloads.push_back(std::move(v));
  }
  for (const auto& p : r.payloads) r.total_bytes += p.bytes.size();
  return r;
}

}  // namespace lightlink::service
