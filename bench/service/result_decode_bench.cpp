// result_decode_bench: what a client spends turning one received result into Textures: the
// generated protobuf parser (what gRPC's ClientReader<ResultMessage> runs per message) and the
// ResultAssembler, as Client::relight and getTextures do.
//
// Fixed workload: the demo scene's medium lightmap as service_bench's clients ask for it —
// 256 x 256 texels, 3 bands, half precision, lightmap only (SH + direct + validity, 4.0 MB),
// in the daemon's own wire form (Snapshot::wire, 1 MiB chunks). Each message is handed to
// the decoder as gRPC hands a received message over: a ByteBuffer of 16 KiB slices. Reports
// the median over --repeats of the time per result and the throughput; the decoded
// checksum is printed, so the optimizer cannot drop the work. The figure decided against a
// hand-written decoder that copies chunk data once instead of twice (docs/clients.md).
//
//   result_decode_bench [--repeats N] [--slice-kib K] [--float]   (--float: float32 values, 8 MB)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/support/byte_buffer.h>
#include <grpcpp/support/slice.h>
#include <grpcpp/impl/codegen/proto_utils.h>
#include <nlohmann/json.hpp>

#include "bench/rt/throughput.h"
#include "clients/client/textures.h"
#include "proto/lightlink.pb.h"
#include "service/snapshot.h"

namespace {

using namespace lightlink;
using Clock = std::chrono::steady_clock;

// The demo scene (clients/demo/cornell_box.gltf) at medium: a 256 x 256 lightmap, 3 bands.
void fillMediumDemo(service::Snapshot& s) {
  s.scene_id = "bench";
  s.version = 1;
  s.sequence = 1;
  s.backend = "cpu";
  s.bands = 3;
  s.width = 256;
  s.height = 256;
  const std::size_t texels = 256 * 256;
  s.lightmap_sh.resize(texels * 27);
  for (std::size_t i = 0; i < s.lightmap_sh.size(); ++i) s.lightmap_sh[i] = 0.25f + 0.001f * float(i % 997);
  s.direct.assign(texels * 3, 0.5f);
  s.texel_valid.assign(texels, 1);
}

// `bytes` re-cut into slices of `slice` bytes (gRPC delivers a large message in pieces).
grpc::ByteBuffer resliced(const grpc::ByteBuffer& bytes, std::size_t slice) {
  std::vector<grpc::Slice> in;
  (void)bytes.Dump(&in);
  std::string flat;
  for (const auto& s : in) flat.append(reinterpret_cast<const char*>(s.begin()), s.size());
  std::vector<grpc::Slice> out;
  for (std::size_t at = 0; at < flat.size(); at += slice)
    out.emplace_back(flat.data() + at, std::min(slice, flat.size() - at));
  return grpc::ByteBuffer(out.data(), out.size());
}

std::uint64_t checksum(const client::Textures& t) {
  std::uint64_t sum = 0;
  for (const auto& p : t.payloads)
    for (std::size_t i = 0; i < p.size(); i += 4096) sum += p[i];
  return sum + t.totalBytes();
}

// Generated parser: a ResultMessage per message, as ClientReader<ResultMessage>::Read makes.
client::Textures decodeGenerated(const std::vector<grpc::ByteBuffer>& messages) {
  client::ResultAssembler assembler;
  v1::ResultMessage msg;
  for (const auto& m : messages) {
    grpc::ByteBuffer received(m);  // Deserialize consumes its buffer; this copies references
    if (!grpc::SerializationTraits<v1::ResultMessage>::Deserialize(&received, &msg).ok()) std::abort();
    if (!assembler.add(msg)) std::abort();
  }
  auto t = assembler.take();
  if (!t) std::abort();
  return std::move(t).value();
}

template <typename Decode>
double medianMicroseconds(const std::vector<grpc::ByteBuffer>& messages, int repeats, Decode decode,
                          std::uint64_t* sum) {
  std::vector<double> us;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = Clock::now();
    const client::Textures t = decode(messages);
    us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
    *sum += checksum(t);
  }
  std::nth_element(us.begin(), us.begin() + us.size() / 2, us.end());
  return us[us.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  int repeats = 200;
  std::size_t slice_kib = 16;
  bool as_float = false;
  std::string json_path;
  for (int i = 1; i < argc; i += 2) {
    if (std::strcmp(argv[i], "--float") == 0) {
      as_float = true;
      --i;
    } else if (i + 1 >= argc) {
      std::fprintf(stderr, "%s: missing value\n", argv[i]);
      return 2;
    } else if (std::strcmp(argv[i], "--repeats") == 0) repeats = std::max(1, std::atoi(argv[i + 1]));
    else if (std::strcmp(argv[i], "--slice-kib") == 0) slice_kib = std::max(1, std::atoi(argv[i + 1]));
    else if (std::strcmp(argv[i], "--json") == 0) json_path = argv[i + 1];
    else {
      std::fprintf(stderr, "usage: result_decode_bench [--repeats N] [--slice-kib K] [--float] [--json OUT]\n");
      return 2;
    }
  }
  service::Snapshot snap;
  fillMediumDemo(snap);
  service::SpecKey spec;
  spec.grid = false;
  spec.bands = 3;
  if (as_float) spec.precision = v1::PRECISION_FLOAT;
  const auto wire = snap.wire(spec, 1 << 20);
  if (!wire) return 2;
  std::vector<grpc::ByteBuffer> messages;
  for (const auto& m : wire->messages) messages.push_back(resliced(m, slice_kib << 10));
  const double mb = double(wire->bytes) / 1e6;

  std::uint64_t sum = 0;
  const double generated = medianMicroseconds(messages, repeats, decodeGenerated, &sum);
  std::printf("machine: %s, %u threads\n", bench::cpuModel().c_str(), std::thread::hardware_concurrency());
  std::printf("result: 256x256 texels, 3 bands, %s, lightmap only: %zu messages, %.3f MB, %zu KiB slices\n",
              as_float ? "float" : "half", messages.size(), mb, slice_kib);
  std::printf("%-22s %10s %10s\n", "decoder", "us/result", "GB/s");
  std::printf("%-22s %10.1f %10.2f\n", "generated (protobuf)", generated, mb * 1e3 / generated);
  std::printf("(checksum %llu)\n", static_cast<unsigned long long>(sum));
  if (!json_path.empty()) {
    const nlohmann::ordered_json doc = {
        {"benchmark", "result_decode_bench"},
        {"machine", {{"cpu", bench::cpuModel()}, {"hardware_threads", std::thread::hardware_concurrency()}}},
        {"result", {{"width", 256}, {"height", 256}, {"bands", 3}, {"precision", as_float ? "float" : "half"},
                    {"messages", messages.size()}, {"megabytes", mb}, {"slice_kib", slice_kib}}},
        {"repeats", repeats},
        {"generated_us_per_result", generated}};
    std::ofstream out(json_path);
    out << doc.dump(2) << "\n";
    if (!out) {
      std::fprintf(stderr, "result_decode_bench: cannot write %s\n", json_path.c_str());
      return 1;
    }
  }
  return 0;
}
