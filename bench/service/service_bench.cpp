// service_bench: what a level designer and a room of game clients feel (DESIGN.md sec 11,
// docs/results.md "Service").
//
//   latency     time from sending UpdateLights to the moment a polling client holds the full
//               lightmap of a version that contains the update, measured at every client for
//               every update, with 1 and with 50 clients; also minus the daemon's relight time
//               of the version received (what queueing, encoding, the wire and polling add). Each client is a thread with its own
//               channel and TCP connection asking GetTextures for the lightmap (half),
//               either polling every --poll-ms (wait 0: the plain poll) or long polling
//               (GetTextures wait_ms > 0: one call outstanding, answered when a new version
//               exists); --wait-ms 0,2000 measures both; --subscribe adds clients that hold
//               a Subscribe stream (tile deltas) instead. Updates are spaced so each one is
//               measured alone (the driver waits until every client has it, then pauses
//               --gap-ms).
//   throughput  updates sent back to back for --burst-s seconds by one client: updates/s
//               acknowledged, and relights/s the daemon computed meanwhile (Stats), the rest
//               coalesced.
//   updates     the cost of an acknowledgement (durable: journaled and synced, docs/service.md):
//               for each count in --update-clients, that many clients, each on its own
//               connection, send updates back to back for --burst-s seconds; updates/s
//               acknowledged and the UpdateLights round trip p50/p99. --no-latency skips the
//               latency scenarios (only throughput and updates).
//   memory      daemon RSS before and after the scene is resident, and the scene's
//               resident_bytes / artifact_bytes (Stats).
//
// Scene: the bundled Cornell box at preset medium, its light moved on a circle below the
// ceiling; or --scene F [--lights FILE --light ID --radius R]: the light set FILE sent after
// the open, and its light ID moved on a circle of radius R (metres) around its position.
// JSON to --json; a summary to stdout.
//
// CPU placement (an isolated many-core machine): --daemon-cpus 0-1 runs the started daemon
// on CPUs 0 and 1 only (sched_setaffinity in the child before exec), --client-cpus 2-15 runs
// this process (the driver, the simulated clients and their gRPC threads) on CPUs 2..15.
// Lists use taskset syntax. Without them both share whatever the machine gives.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <numbers>
#include <set>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "clients/client/client.h"
#include "clients/client/local_daemon.h"

namespace {

using namespace lightlink;
using namespace lightlink::client;
using Clock = std::chrono::steady_clock;

struct Args {
  std::string target;  // empty: start a daemon
  std::string daemon = LIGHTLINK_DAEMON_PATH;
  std::string cache_dir;
  int bounces = -1;  // >= 0: the started daemon's --bounces (its default is 8)
  bool progressive = false;  // the started daemon's --progressive: preview, then converged
  bool subscribe = false;    // also measure clients holding a Subscribe stream (tile deltas)
  int bands = 0;             // SH bands the clients ask for (0 = all): the payload size
  bool shared_memory = false;  // polling clients ask for results through shared memory
  std::vector<std::string> daemon_flags;  // more flags for the started daemon (--daemon-flag, repeated)
  std::string scene = std::string(LIGHTLINK_SOURCE_DIR) + "/clients/demo/cornell_box.gltf";
  std::string preset = "medium";
  std::vector<int> clients = {1, 50};
  std::vector<int> wait_ms = {0, 2000};  // per scenario: 0 = plain poll every poll_ms, > 0 = long poll
  std::vector<int> update_clients = {1, 8};  // concurrent updaters per "updates" scenario
  bool latency = true;                        // run the light-change-to-client scenarios
  std::string daemon_cpus, client_cpus;  // taskset-style CPU lists; empty = no pinning
  int updates = 100;
  double poll_ms = 5.0;  // 200 Hz: a game polling every frame, a little faster than 60 Hz
  double gap_ms = 10.0;
  double burst_s = 3.0;
  float cx = 0.278f, cy = 0.45f, cz = 0.28f, radius = 0.15f;  // light circle (Cornell box, metres)
  std::string lights_file, light_id;  // --lights, --light: a light set sent after the open, the light moved
  std::string json;
};

double ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = p * double(v.size() - 1);
  const std::size_t i = std::size_t(pos);
  const double f = pos - double(i);
  return i + 1 < v.size() ? v[i] * (1.0 - f) + v[i + 1] * f : v[i];
}

nlohmann::ordered_json summary(const std::vector<double>& v) {
  double sum = 0.0;
  for (double x : v) sum += x;
  return {{"count", v.size()},
          {"mean", v.empty() ? 0.0 : sum / double(v.size())},
          {"p50", percentile(v, 0.50)},
          {"p90", percentile(v, 0.90)},
          {"p99", percentile(v, 0.99)},
          {"max", v.empty() ? 0.0 : *std::max_element(v.begin(), v.end())}};
}

[[noreturn]] void die(const Status& s) {
  std::fprintf(stderr, "service_bench: %s\n", s.toString().c_str());
  std::exit(s.code() == Code::kIoError ? 3 : 2);
}

template <typename T>
T must(Expected<T> e) {
  if (!e) die(e.status());
  return std::move(e).value();
}

LightUpdate moveLight(const Args& a, const std::string& id, int step) {
  const float t = 2.0f * std::numbers::pi_v<float> * float(step % 64) / 64.0f;
  LightFields f;
  f.id = id;
  f.position = Vec3{a.cx + a.radius * std::cos(t), a.cy, a.cz + a.radius * std::sin(t)};
  LightUpdate u;
  if (Status s = u.modify(f); !s) die(s);
  return u;
}

// One simulated game client: its own connection, polling GetTextures for the lightmap.
struct Poller {
  std::unique_ptr<Client> client;
  std::atomic<std::uint64_t> latest{0};
  std::atomic<std::uint64_t> latest_converged{0};  // newest version held that is not a preview
  struct Arrival {
    std::uint64_t version;
    Clock::time_point whole;  // when the client held the whole lightmap
    double relight_ms;        // the daemon's relight time of that version
    bool preview;             // progressive daemon: a bounce-free result
  };
  std::vector<Arrival> arrivals;
  std::vector<double> not_modified_ms, fetch_ms;
  std::size_t errors = 0;
  std::size_t shared = 0;  // results whose chunks came through a shared-memory file
  std::string first_error;
};

// wait_ms 0: poll, > 0: long poll; subscribe: a Subscribe stream with tile deltas instead.
nlohmann::ordered_json latencyScenario(const Args& a, const ConnectOptions& co, Client& driver, SceneHandle& scene,
                                       const std::string& light, int n_clients, std::uint32_t wait_ms, bool subscribe,
                                       int& step) {
  std::vector<std::unique_ptr<Poller>> pollers;
  for (int i = 0; i < n_clients; ++i) {
    auto p = std::make_unique<Poller>();
    p->client = std::make_unique<Client>(must(Client::connect(co)));
    pollers.push_back(std::move(p));
  }
  ResultSpec spec;
  spec.grid = false;  // the lightmap: what the latency target is about
  spec.bands = a.bands;
  std::atomic<bool> stop{false};
  const auto poll_period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::milli>(a.poll_ms));
  std::vector<std::thread> threads;
  for (auto& pp : pollers) {
    threads.emplace_back([&, p = pp.get()] {
      if (subscribe) {
        // Each result is recorded the moment the stream has it whole; after `stop` the next
        // result (the driver's wake-up update) ends the stream.
        const Status st = p->client->subscribe(
            scene,
            [&](const Textures& t) {
              const auto now = Clock::now();
              p->arrivals.push_back({t.info.version, now, t.info.relight_ms, t.info.preview});
              if (!t.info.preview) p->latest_converged.store(t.info.version, std::memory_order_release);
              p->latest.store(t.info.version, std::memory_order_release);
              return !stop.load(std::memory_order_relaxed);
            },
            spec, /*deltas=*/true);
        if (!st && p->errors++ == 0) p->first_error = st.toString();
        return;
      }
      std::uint64_t last = 0;
      auto next = Clock::now();
      while (!stop.load(std::memory_order_relaxed)) {
        const auto t0 = Clock::now();
        auto r = p->client->getTextures(scene, last, spec, wait_ms);
        const auto t1 = Clock::now();
        if (!r) {
          if (p->errors++ == 0) p->first_error = r.status().toString();
        } else if (r->has_value()) {
          last = (*r)->info.version;
          if ((*r)->info.shared) ++p->shared;
          p->arrivals.push_back({last, t1, (*r)->info.relight_ms, (*r)->info.preview});
          p->fetch_ms.push_back(ms(t1 - t0));
          if (!(*r)->info.preview) p->latest_converged.store(last, std::memory_order_release);
          p->latest.store(last, std::memory_order_release);
        } else {
          p->not_modified_ms.push_back(ms(t1 - t0));
        }
        if (wait_ms > 0) continue;  // long poll: the next call goes out at once
        next += poll_period;
        if (next > t1) std::this_thread::sleep_until(next);
        else next = t1;
      }
    });
  }
  // Let every client see the current version first.
  // Progressive: wait for the converged result too, so each update is measured alone.
  auto allAt = [&](std::uint64_t v, Clock::duration limit) {
    const auto deadline = Clock::now() + limit;
    for (;;) {
      bool all = true;
      for (auto& p : pollers)
        all &= (a.progressive ? p->latest_converged : p->latest).load(std::memory_order_acquire) >= v;
      if (all) return true;
      if (Clock::now() > deadline) return false;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  };
  auto current = must(driver.getTextures(scene, 0, spec));
  if (!current) die(internalError("GetTextures with last_seen 0 answered not modified"));
  if (!allAt(current ? current->info.version : 0, std::chrono::seconds(10))) die(ioError("clients never caught up"));
  const std::size_t result_bytes = current->totalBytes();

  std::vector<std::pair<std::uint64_t, Clock::time_point>> sent;  // version, send time
  std::size_t late = 0;
  for (int k = 0; k < a.updates; ++k) {
    const LightUpdate u = moveLight(a, light, step++);
    const auto t0 = Clock::now();
    auto r = must(driver.updateLights(scene, u));
    sent.emplace_back(r.version, t0);
    if (!allAt(r.version, std::chrono::seconds(5))) ++late;
    std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(a.gap_ms));
  }
  stop = true;
  // Long polls end at their wait; a small update makes them answer at once.
  if (wait_ms > 0 || subscribe) (void)must(driver.updateLights(scene, moveLight(a, light, step++)));
  for (auto& t : threads) t.join();

  std::vector<double> latency, overhead, not_modified, fetch, converged;
  std::size_t missing = 0, errors = 0, shared = 0, fetched = 0;
  std::string first_error;
  for (auto& p : pollers) {
    shared += p->shared;
    fetched += p->fetch_ms.size();
    for (const auto& [v, t_send] : sent) {
      auto it = std::find_if(p->arrivals.begin(), p->arrivals.end(), [&](const auto& x) { return x.version >= v; });
      if (it == p->arrivals.end()) {
        ++missing;
        continue;
      }
      latency.push_back(ms(it->whole - t_send));
      auto c = std::find_if(it, p->arrivals.end(), [&](const auto& x) { return x.version >= v && !x.preview; });
      if (c != p->arrivals.end()) converged.push_back(ms(c->whole - t_send));
      // What the service and the wire add to the relight itself (queueing, encoding,
      // transfer, the poll interval).
      overhead.push_back(ms(it->whole - t_send) - it->relight_ms);
    }
    not_modified.insert(not_modified.end(), p->not_modified_ms.begin(), p->not_modified_ms.end());
    fetch.insert(fetch.end(), p->fetch_ms.begin(), p->fetch_ms.end());
    errors += p->errors;
    if (first_error.empty()) first_error = p->first_error;
  }
  nlohmann::ordered_json j;
  j["clients"] = n_clients;
  j["mode"] = subscribe ? "subscribe" : wait_ms > 0 ? "long poll" : "poll";
  j["wait_ms"] = subscribe ? 0 : wait_ms;
  j["poll_ms"] = wait_ms > 0 || subscribe ? 0.0 : a.poll_ms;
  j["updates"] = a.updates;
  j["result_bytes"] = result_bytes;  // payload bytes of one result, per client
  j["latency_ms"] = summary(latency);
  j["latency_minus_relight_ms"] = summary(overhead);
  // Progressive: to the converged (bounced) result; else the same samples as latency_ms.
  j["latency_converged_ms"] = summary(converged);
  j["missing"] = missing;
  j["late_updates"] = late;
  j["poll_not_modified_ms"] = summary(not_modified);
  j["poll_new_version_ms"] = summary(fetch);
  // Polled results whose chunks came through shared memory (--shared-memory), of all fetched.
  j["shared_memory_results"] = shared;
  j["fetched_results"] = fetched;
  j["errors"] = errors;
  if (!first_error.empty()) j["first_error"] = first_error;
  return j;
}

nlohmann::ordered_json throughputScenario(const Args& a, Client& driver, SceneHandle& scene, const std::string& light,
                                          int& step) {
  auto before = must(driver.stats(&scene));
  const auto t0 = Clock::now();
  std::size_t n = 0;
  std::uint64_t last_version = 0;
  while (ms(Clock::now() - t0) < a.burst_s * 1e3) {
    auto r = must(driver.updateLights(scene, moveLight(a, light, step++)));
    last_version = r.version;
    ++n;
  }
  const double send_s = ms(Clock::now() - t0) / 1e3;
  // The relights the burst caused, up to the one that contains the last update.
  ResultSpec nothing;
  nothing.lightmap = nothing.grid = false;
  (void)must(driver.relight(scene, last_version, nothing));
  const double total_s = ms(Clock::now() - t0) / 1e3;
  auto after = must(driver.stats(&scene));
  const auto& b = before.scene(0);
  const auto& e = after.scene(0);
  nlohmann::ordered_json j;
  j["seconds"] = send_s;
  j["updates_acknowledged"] = n;
  j["updates_per_s"] = double(n) / send_s;
  j["relights"] = e.relights() - b.relights();
  j["relights_per_s"] = double(e.relights() - b.relights()) / total_s;
  j["coalesced"] = e.coalesced() - b.coalesced();
  j["mean_relight_ms"] = e.mean_relight_ms();
  j["last_version"] = last_version;
  return j;
}

// `n` clients send updates back to back: what an acknowledgement costs, alone and under a burst.
nlohmann::ordered_json updateScenario(const Args& a, const ConnectOptions& co, SceneHandle& scene,
                                      const std::string& light, int n, int& step) {
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < n; ++i) clients.push_back(std::make_unique<Client>(must(Client::connect(co))));
  std::vector<std::vector<double>> rtt(n);
  std::vector<std::size_t> errors(n, 0);
  std::vector<std::string> first_error(n);
  std::atomic<int> next_step{step};
  const auto t0 = Clock::now();
  const auto until = t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(a.burst_s));
  std::vector<std::thread> threads;
  for (int i = 0; i < n; ++i)
    threads.emplace_back([&, i] {
      while (Clock::now() < until) {
        const LightUpdate u = moveLight(a, light, next_step++);
        const auto s = Clock::now();
        auto r = clients[i]->updateLights(scene, u);
        if (!r) {
          if (errors[i]++ == 0) first_error[i] = r.status().toString();
          continue;
        }
        rtt[i].push_back(ms(Clock::now() - s));
      }
    });
  for (auto& t : threads) t.join();
  const double seconds = ms(Clock::now() - t0) / 1e3;
  step = next_step.load();
  std::vector<double> all;
  std::size_t errs = 0;
  std::string first;
  for (int i = 0; i < n; ++i) {
    all.insert(all.end(), rtt[i].begin(), rtt[i].end());
    errs += errors[i];
    if (first.empty()) first = first_error[i];
  }
  nlohmann::ordered_json j;
  j["clients"] = n;
  j["seconds"] = seconds;
  j["updates_acknowledged"] = all.size();
  j["updates_per_s"] = double(all.size()) / seconds;
  j["round_trip_ms"] = summary(all);
  j["errors"] = errs;
  if (!first.empty()) j["first_error"] = first;
  return j;
}

std::vector<int> parseList(const std::string& s) {
  std::vector<int> v;
  std::size_t pos = 0;
  while (pos <= s.size()) {
    const std::size_t comma = s.find(',', pos);
    v.push_back(std::stoi(s.substr(pos, comma == std::string::npos ? std::string::npos : comma - pos)));
    if (comma == std::string::npos) break;
    pos = comma + 1;
  }
  return v;
}

Args parseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto val = [&]() -> std::string {
      if (i + 1 >= argc) die(invalidInput("{}: missing value", k));
      return argv[++i];
    };
    try {
      if (k == "--target") a.target = val();
      else if (k == "--daemon") a.daemon = val();
      else if (k == "--cache-dir") a.cache_dir = val();
      else if (k == "--bounces") a.bounces = std::stoi(val());
      else if (k == "--progressive") a.progressive = true;
      else if (k == "--subscribe") a.subscribe = true;
      else if (k == "--shared-memory") a.shared_memory = true;
      else if (k == "--bands") a.bands = std::stoi(val());
      else if (k == "--daemon-flag") a.daemon_flags.push_back(val());
      else if (k == "--scene") a.scene = val();
      else if (k == "--preset") a.preset = val();
      else if (k == "--lights") a.lights_file = val();
      else if (k == "--light") a.light_id = val();
      else if (k == "--radius") a.radius = std::stof(val());
      else if (k == "--clients") a.clients = parseList(val());
      else if (k == "--wait-ms") a.wait_ms = parseList(val());
      else if (k == "--update-clients") a.update_clients = parseList(val());
      else if (k == "--no-latency") a.latency = false;
      else if (k == "--daemon-cpus") a.daemon_cpus = val();
      else if (k == "--client-cpus") a.client_cpus = val();
      else if (k == "--updates") a.updates = std::stoi(val());
      else if (k == "--poll-ms") a.poll_ms = std::stod(val());
      else if (k == "--gap-ms") a.gap_ms = std::stod(val());
      else if (k == "--burst-s") a.burst_s = std::stod(val());
      else if (k == "--json") a.json = val();
      else if (k == "--help" || k == "-h") {
        std::printf(
            "service_bench [--target host:port | --daemon PATH --cache-dir DIR --bounces N --progressive]\n"
            "              [--scene F] [--preset P] [--lights FILE --light ID] [--radius M]\n"
            "              [--clients 1,50] [--wait-ms 0,2000] [--updates N] [--poll-ms MS] [--gap-ms MS]\n"
            "              [--burst-s S] [--daemon-cpus LIST] [--client-cpus LIST] [--daemon-flag F ...] [--json F]\n"
            "              [--subscribe] [--bands B] [--shared-memory] [--update-clients 1,8] [--no-latency]\n"
            "  --wait-ms    one latency scenario per value and client count: 0 = poll every --poll-ms,\n"
            "               > 0 = long poll (GetTextures wait_ms)\n"
            "  --daemon-cpus, --client-cpus  taskset-style CPU lists (0-1, 2-15, 0,2,4-7): where the started\n"
            "               daemon and this process (driver, clients) may run\n"
            "  --subscribe  also one scenario per client count with Subscribe streams (tile deltas)\n"
            "  --update-clients  one \"updates\" scenario per value: that many clients send updates back to\n"
            "               back for --burst-s (acknowledged updates/s, round trip p50/p99)\n"
            "  --no-latency skip the light-change-to-client latency scenarios\n"
            "  --bands      SH bands the clients fetch (default 0: all): how latency scales with the payload\n"
            "  --shared-memory  polling clients ask for results through shared memory (the daemon is on this\n"
            "               machine: chunks in a file it writes once, docs/service.md)\n"
            "  --daemon-flag  one more flag for the started daemon (repeat: --daemon-flag --log-level\n"
            "               --daemon-flag debug --daemon-flag --log-file --daemon-flag d.log)\n");
        std::exit(0);
      } else die(invalidInput("unknown argument {}", k));
    } catch (const std::exception&) {
      die(invalidInput("{}: not a number", k));
    }
  }
  if (a.updates < 1 || a.poll_ms <= 0.0 || a.gap_ms < 0.0 || a.burst_s <= 0.0)
    die(invalidInput("--updates >= 1, --poll-ms > 0, --gap-ms >= 0, --burst-s > 0"));
  for (int c : a.clients)
    if (c < 1 || c > 1000) die(invalidInput("--clients: {} is out of range (1..1000)", c));
  for (int c : a.update_clients)
    if (c < 1 || c > 1000) die(invalidInput("--update-clients: {} is out of range (1..1000)", c));
  for (int w : a.wait_ms)
    if (w < 0 || w > 60000) die(invalidInput("--wait-ms: {} is out of range (0..60000)", w));
  if (!a.daemon_cpus.empty() && !a.target.empty()) die(invalidInput("--daemon-cpus: only for a daemon it starts (no --target)"));
  return a;
}

}  // namespace

int main(int argc, char** argv) {
  Args a = parseArgs(argc, argv);
  // Pin this process first, so every thread it creates (clients, gRPC) inherits the set.
  std::vector<int> client_cpus, daemon_cpus;
  if (!a.client_cpus.empty()) {
    client_cpus = must(parseCpuList(a.client_cpus));
    if (Status s = pinCurrentThread(client_cpus); !s) die(s);
  }
  if (!a.daemon_cpus.empty()) daemon_cpus = must(parseCpuList(a.daemon_cpus));
  std::unique_ptr<LocalDaemon> daemon;
  std::string target = a.target;
  if (target.empty()) {
    LocalDaemon::Options d;
    d.binary = a.daemon;
    d.cpus = daemon_cpus;
    d.cache_dir = a.cache_dir;
    // The scene's folder is the daemon's scene root: it opens that scene by path.
    d.extra = {"--no-restore", "--scene-root", std::filesystem::absolute(a.scene).parent_path().string()};
    if (a.bounces >= 0) d.extra.insert(d.extra.end(), {"--bounces", std::to_string(a.bounces)});
    if (a.progressive) d.extra.push_back("--progressive");
    d.extra.insert(d.extra.end(), a.daemon_flags.begin(), a.daemon_flags.end());
    daemon = must(LocalDaemon::start(d));
    target = daemon->target();
  }
  ConnectOptions co;
  co.target = target;
  co.own_connection = true;
  co.call_timeout = std::chrono::seconds(60);
  Client driver = must(Client::connect(co));
  co.shared_memory = a.shared_memory;  // the polling clients' (the driver's own fetches stay on the stream)
  auto stats0 = must(driver.stats());

  OpenOptions oo;
  oo.path = std::filesystem::absolute(a.scene).string();  // the daemon may run in another directory
  oo.preset = a.preset;
  oo.name = "service_bench";
  const auto t_open = Clock::now();
  SceneHandle scene = must(driver.openScene(oo));
  const double open_s = ms(Clock::now() - t_open) / 1e3;
  std::string light = scene.info.light_ids_size() > 0 ? scene.info.light_ids(0) : std::string();
  if (!a.lights_file.empty()) {
    // The level's light set, then its light --light moved on a circle around where it stands.
    std::set<std::string> known(scene.info.light_ids().begin(), scene.info.light_ids().end());
    auto u = must(LightUpdate::fromLightSetFile(a.lights_file, &known));
    const auto r = must(driver.updateLights(scene, u));
    (void)must(driver.relight(scene, r.version));
    std::ifstream in(a.lights_file);
    const auto doc = nlohmann::json::parse(in, nullptr, false);
    bool found = false;
    if (doc.is_object() && doc.contains("lights") && doc["lights"].is_array())
      for (const auto& l : doc["lights"])
        if (l.value("id", "") == a.light_id && l.contains("position") && l["position"].is_array() &&
            l["position"].size() == 3) {
          a.cx = l["position"][0].get<float>(), a.cy = l["position"][1].get<float>();
          a.cz = l["position"][2].get<float>(), found = true;
        }
    if (!found) die(invalidInput("--light {}: no light with that id and a position in {}", a.light_id, a.lights_file));
    light = a.light_id;
  }
  if (light.empty()) die(invalidInput("{}: the scene has no light to move", a.scene));
  // Wait for the initial result so the memory figures include it.
  (void)must(driver.relight(scene, scene.info.version()));
  auto stats1 = must(driver.stats(&scene));
  auto health = must(driver.health());

  nlohmann::ordered_json out;
  out["benchmark"] = "service";
  out["target"] = a.target.empty() ? "local lightlinkd (started by the benchmark)" : a.target;
  out["machine_threads"] = std::thread::hardware_concurrency();
  out["daemon_version"] = health.daemon_version();
  out["scene"] = a.scene;
  out["preset"] = a.preset;
  out["open_seconds"] = open_s;
  out["artifact_reused"] = scene.info.artifact_reused();
  out["backend"] = scene.info.backend();
  out["lightmap"] = {{"width", scene.info.lightmap().width()}, {"height", scene.info.lightmap().height()},
                     {"bands", scene.info.bands()}};
  out["daemon_bounces"] = a.bounces >= 0 ? std::to_string(a.bounces) : std::string("daemon default");
  out["progressive"] = a.progressive;
  out["fetched_bands"] = a.bands;
  out["shared_memory"] = a.shared_memory;
  out["poll_ms"] = a.poll_ms;
  out["gap_ms"] = a.gap_ms;
  out["daemon_cpus"] = a.daemon_cpus.empty() ? "any" : a.daemon_cpus;
  out["client_cpus"] = a.client_cpus.empty() ? "any" : a.client_cpus;
  int step = 0;
  nlohmann::ordered_json scenarios = nlohmann::ordered_json::array();
  for (int w : a.latency ? a.wait_ms : std::vector<int>{})
    for (int c : a.clients) {
      std::fprintf(stderr, "service_bench: %d client(s), %s, %d updates\n", c,
                   w > 0 ? fmt::format("long poll (wait_ms {})", w).c_str() : "poll", a.updates);
      scenarios.push_back(latencyScenario(a, co, driver, scene, light, c, std::uint32_t(w), false, step));
    }
  if (a.subscribe && a.latency)
    for (int c : a.clients) {
      std::fprintf(stderr, "service_bench: %d client(s), subscribe (deltas), %d updates\n", c, a.updates);
      scenarios.push_back(latencyScenario(a, co, driver, scene, light, c, 0, true, step));
    }
  out["latency"] = scenarios;
  std::fprintf(stderr, "service_bench: update burst for %.1f s\n", a.burst_s);
  out["throughput"] = throughputScenario(a, driver, scene, light, step);
  nlohmann::ordered_json updates = nlohmann::ordered_json::array();
  for (int n : a.update_clients) {
    std::fprintf(stderr, "service_bench: %d client(s) sending updates for %.1f s\n", n, a.burst_s);
    updates.push_back(updateScenario(a, co, scene, light, n, step));
  }
  out["updates"] = updates;
  auto stats2 = must(driver.stats(&scene));
  const auto& sc = stats2.scene(0);
  out["memory"] = {{"rss_before_open_bytes", stats0.rss_bytes()},
                   {"rss_after_open_bytes", stats1.rss_bytes()},
                   {"rss_per_scene_bytes", std::int64_t(stats1.rss_bytes()) - std::int64_t(stats0.rss_bytes())},
                   {"rss_end_bytes", stats2.rss_bytes()},
                   {"resident_bytes", sc.resident_bytes()},
                   {"artifact_bytes", sc.artifact_bytes()},
                   // Files the daemon keeps for shared-memory delivery (--shared-memory), at the end.
                   {"shared_memory_files", stats2.shared_memory_files()},
                   {"shared_memory_bytes", stats2.shared_memory_bytes()}};
  out["relight"] = {{"relights", sc.relights()}, {"previews", sc.previews()}, {"coalesced", sc.coalesced()},
                    {"mean_relight_ms", sc.mean_relight_ms()}, {"last_relight_ms", sc.last_relight_ms()}};
  (void)driver.closeScene(scene);

  std::string text = fmt::format("scene        {} ({}x{} texels, {} bands, {} backend, open {:.1f} s{})\n", a.scene,
                                 scene.info.lightmap().width(), scene.info.lightmap().height(), scene.info.bands(),
                                 scene.info.backend(), open_s, scene.info.artifact_reused() ? ", artifact reused" : "");
  for (const auto& s : out["latency"]) {
    text += fmt::format("latency      {:<9} {:>3} client(s): p50 {:6.2f} ms  p99 {:6.2f} ms  max {:6.2f} ms  (minus relight: p50 "
                        "{:.2f} ms, p99 {:.2f} ms; {} samples, {} missing); not-modified poll p50 {:.3f} ms; "
                        "{:.0f} KiB per result{}\n",
                        s["mode"].get<std::string>(), s["clients"].get<int>(), s["latency_ms"]["p50"].get<double>(),
                        s["latency_ms"]["p99"].get<double>(), s["latency_ms"]["max"].get<double>(),
                        s["latency_minus_relight_ms"]["p50"].get<double>(),
                        s["latency_minus_relight_ms"]["p99"].get<double>(),
                        s["latency_ms"]["count"].get<std::size_t>(), s["missing"].get<std::size_t>(),
                        s["poll_not_modified_ms"]["p50"].get<double>(),
                        double(s["result_bytes"].get<std::size_t>()) / 1024.0,
                        a.shared_memory ? fmt::format(", {} of {} fetched through shared memory",
                                                      s["shared_memory_results"].get<std::size_t>(),
                                                      s["fetched_results"].get<std::size_t>())
                                        : std::string());
    if (a.progressive)
      text += fmt::format("             converged (bounced) result: p50 {:6.2f} ms  p99 {:6.2f} ms\n",
                          s["latency_converged_ms"]["p50"].get<double>(), s["latency_converged_ms"]["p99"].get<double>());
  }
  const auto& tp = out["throughput"];
  text += fmt::format("throughput   {:.0f} updates/s acknowledged, {:.1f} relights/s ({} coalesced), mean relight {:.2f} ms\n",
                      tp["updates_per_s"].get<double>(), tp["relights_per_s"].get<double>(),
                      tp["coalesced"].get<std::uint64_t>(), tp["mean_relight_ms"].get<double>());
  for (const auto& u : out["updates"])
    text += fmt::format("updates      {:>3} client(s): {:.0f} updates/s acknowledged, round trip p50 {:.2f} ms  p99 {:.2f} ms"
                        "{}\n",
                        u["clients"].get<int>(), u["updates_per_s"].get<double>(), u["round_trip_ms"]["p50"].get<double>(),
                        u["round_trip_ms"]["p99"].get<double>(),
                        u["errors"].get<std::size_t>() ? fmt::format(" ({} errors)", u["errors"].get<std::size_t>())
                                                       : std::string());
  const auto& m = out["memory"];
  text += fmt::format("memory       resident {:.1f} MiB (artifact {:.1f} MiB), daemon RSS +{:.1f} MiB for the scene\n",
                      double(m["resident_bytes"].get<std::uint64_t>()) / 1048576.0,
                      double(m["artifact_bytes"].get<std::uint64_t>()) / 1048576.0,
                      double(m["rss_per_scene_bytes"].get<std::int64_t>()) / 1048576.0);
  std::fwrite(text.data(), 1, text.size(), stdout);
  if (!a.json.empty()) {
    std::ofstream f(a.json);
    f << out.dump(2) << "\n";
    if (!f) die(ioError("{}: cannot write", a.json));
  }
  if (daemon) daemon->stop();
  return 0;
}
