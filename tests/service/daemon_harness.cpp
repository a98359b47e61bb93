#include "tests/service/daemon_harness.h"

#include <signal.h>

#include <algorithm>
#include <cstring>
#include <random>

#include "core/common/half.h"
#include "tests/client/process.h"
#include "tests/common/testing.h"

namespace lightlink::testing {

namespace fs = std::filesystem;

DaemonProcess::DaemonProcess(const fs::path& cache_dir, std::vector<std::string> extra) {
  client::LocalDaemon::Options o;
  o.binary = LIGHTLINKD_PATH;
  o.cache_dir = cache_dir;
  o.extra = std::move(extra);
  // Tests open the bundled scenes and scenes they write beside the cache: those are the
  // scene roots unless the test sets its own (or a config file that may).
  const bool own_roots = std::any_of(o.extra.begin(), o.extra.end(),
                                     [](const std::string& a) { return a == "--scene-root" || a == "--config"; });
  if (!own_roots)
    o.extra.insert(o.extra.end(), {"--scene-root", sourceDir().string(), "--scene-root", cache_dir.parent_path().string()});
  // The instant preview takes a scene's first version: the tests written before it count
  // versions from the linked result, so it is off unless a test turns it on (--preview on,
  // preview_daemon_test.cpp) or gives a config file.
  const bool own_preview = std::any_of(o.extra.begin(), o.extra.end(),
                                       [](const std::string& a) { return a == "--preview" || a == "--config"; });
  if (!own_preview) o.extra.insert(o.extra.end(), {"--preview", "off"});
  auto d = client::LocalDaemon::start(o);
  if (!d) {
    error_ = d.status().toString();
    return;
  }
  daemon_ = std::move(d).value();
}

DaemonProcess::~DaemonProcess() {
  // Tests end with a kill, not a drain: a stream a test left open must not delay it.
  if (daemon_) daemon_->signalAndWait(SIGKILL, std::chrono::milliseconds(5000));
}

int DaemonProcess::signalAndWait(int sig, std::chrono::milliseconds limit) {
  return daemon_ ? daemon_->signalAndWait(sig, limit) : -1;
}

std::shared_ptr<grpc::Channel> DaemonProcess::channel(std::chrono::milliseconds connect_wait) const {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(8 << 20);
  args.SetMaxSendMessageSize(128 << 20);
  // A distinct channel per call site: separate connections, i.e. separate gRPC peers.
  args.SetInt("lightlink.test.unique", static_cast<int>(std::random_device{}()));
  auto channel = grpc::CreateCustomChannel(target(), grpc::InsecureChannelCredentials(), args);
  // Not connected in time: the test's own call reports the failure.
  if (connect_wait.count() > 0) (void)channel->WaitForConnected(std::chrono::system_clock::now() + connect_wait);
  return channel;
}

std::unique_ptr<LightlinkRpc> DaemonProcess::rpc(std::chrono::milliseconds connect_wait) const {
  return v1::Lightlink::NewStub(channel(connect_wait));
}

int runDaemonToExit(const std::vector<std::string>& args, std::string* output, std::chrono::milliseconds limit) {
  std::vector<std::string> argv = {LIGHTLINKD_PATH};
  argv.insert(argv.end(), args.begin(), args.end());
  const auto seconds = std::chrono::ceil<std::chrono::seconds>(limit);
  const CommandResult r = runCommand(argv, seconds);
  if (output) *output = r.out + r.err;
  return r.timed_out ? -1 : r.exit_code;
}

std::unique_ptr<grpc::ClientContext> context(int ms, const std::string& bearer) {
  auto c = std::make_unique<grpc::ClientContext>();
  c->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(ms));
  if (!bearer.empty()) c->AddMetadata("authorization", "Bearer " + bearer);
  return c;
}

grpc::Status openScene(LightlinkRpc& rpc, const v1::OpenSceneRequest& request, v1::SceneOpened* opened,
                       std::vector<std::string>* stages, const std::string& bearer, int deadline_ms) {
  auto ctx = context(deadline_ms, bearer);
  auto reader = rpc.OpenScene(ctx.get(), request);
  v1::OpenSceneProgress p;
  bool got = false;
  while (reader->Read(&p)) {
    if (stages && (stages->empty() || stages->back() != p.stage())) stages->push_back(p.stage());
    if (p.has_opened()) {
      if (opened) *opened = p.opened();
      got = true;
    }
  }
  grpc::Status st = reader->Finish();
  if (st.ok() && !got) return {grpc::StatusCode::INTERNAL, "OpenScene ended without `opened`"};
  return st;
}

v1::OpenSceneRequest cornellRequest() {
  v1::OpenSceneRequest r;
  r.set_path((sourceDir() / "clients/demo/cornell_box.gltf").string());
  r.set_preset("draft");
  r.set_surfels(2048);
  r.set_links(32);
  r.set_rays(128);
  r.set_grid_spacing(0.1f);
  r.set_backend(v1::BACKEND_CPU);
  return r;
}

bool ResultReader::next(Result& out) {
  v1::ResultMessage m;
  if (!reader_->Read(&m)) return false;
  if (!m.has_header()) {
    error_ = "a result started with a chunk, not a header";
    return false;
  }
  Result r;
  r.header = m.header();
  const bool delta = r.header.delta();
  if (delta) {
    if (!previous_) {
      error_ = "the first result of a stream is a delta";
      return false;
    }
    r.payloads = previous_->payloads;
  }
  std::uint64_t received = 0;
  std::map<int, std::uint64_t> next_offset;
  const int tile_size = r.header.lightmap().tile_size();
  const int width = r.header.lightmap().width(), height = r.header.lightmap().height();
  const int tiles_x = tile_size > 0 ? (width + tile_size - 1) / tile_size : 0;
  while (received < r.header.payload_bytes()) {
    if (!reader_->Read(&m)) {
      error_ = "stream ended inside a result";
      return false;
    }
    if (m.has_header()) {
      error_ = "a header arrived before the previous result's chunks were complete (torn result)";
      return false;
    }
    const v1::Chunk& c = m.chunk();
    received += c.data().size();
    ++r.chunks;
    const bool lightmap = c.payload() == v1::PAYLOAD_LIGHTMAP_SH || c.payload() == v1::PAYLOAD_LIGHTMAP_DIRECT ||
                          c.payload() == v1::PAYLOAD_LIGHTMAP_VALID;
    if (delta && lightmap) {
      std::string& full = r.payloads[c.payload()];
      const std::size_t texel_bytes = full.size() / (static_cast<std::size_t>(width) * height);
      const int tx = static_cast<int>(c.tile()) % tiles_x, ty = static_cast<int>(c.tile()) / tiles_x;
      const int x0 = tx * tile_size, y0 = ty * tile_size;
      const int w = std::min(tile_size, width - x0);
      const std::size_t row_bytes = w * texel_bytes;
      for (std::size_t i = 0; i < c.data().size(); ++i) {
        const std::size_t at = c.offset() + i;
        const std::size_t y = at / row_bytes, xb = at % row_bytes;
        full[((y0 + y) * width + x0) * texel_bytes + xb] = c.data()[i];
      }
      continue;
    }
    std::string& p = r.payloads[c.payload()];
    if (delta) {
      // A whole grid payload replaces the previous one.
      if (c.offset() == 0) p.clear();
    }
    if (c.offset() != p.size()) {
      error_ = "chunk offset " + std::to_string(c.offset()) + " does not continue payload " +
               std::to_string(c.payload()) + " at " + std::to_string(p.size());
      return false;
    }
    p += c.data();
  }
  if (received != r.header.payload_bytes()) {
    error_ = "chunks carried " + std::to_string(received) + " bytes, header said " +
             std::to_string(r.header.payload_bytes());
    return false;
  }
  previous_ = r;
  out = std::move(r);
  return true;
}

grpc::Status readOne(grpc::ClientReader<v1::ResultMessage>* reader, Result& out, std::string* error) {
  ResultReader rr(reader);
  const bool got = rr.next(out);
  v1::ResultMessage extra;
  const bool more = got && reader->Read(&extra);
  grpc::Status st = reader->Finish();
  if (error) {
    *error = rr.error();
    if (more) *error = "more messages after the single result";
    if (st.ok() && !got && error->empty()) *error = "no result";
  }
  return st;
}

std::vector<float> decodeValues(const std::string& bytes, v1::Precision precision) {
  std::vector<float> out;
  if (precision == v1::PRECISION_HALF) {
    out.resize(bytes.size() / 2);
    for (std::size_t i = 0; i < out.size(); ++i) {
      half_bits h;
      std::memcpy(&h, bytes.data() + 2 * i, 2);
      out[i] = fromHalf(h);
    }
  } else {
    out.resize(bytes.size() / 4);
    std::memcpy(out.data(), bytes.data(), out.size() * 4);
  }
  return out;
}

}  // namespace lightlink::testing
