#include "view/view_server.h"

#include <civetweb.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "base/json.h"

#ifndef FELT_VIEW_WWW_DIR
#error "FELT_VIEW_WWW_DIR must name the page's directory (CMakeLists.txt)"
#endif

namespace felt {

// One WebSocket client: its one-frame slot and its sender thread.
struct ViewClient {
  mg_connection* conn = nullptr;
  std::mutex mu;  // the slot and the flags; view and sender threads only (never a loop's)
  std::condition_variable wake;
  std::vector<uint8_t> slot;   // the newest frame offered, not yet taken
  bool has_frame = false;      // `slot` holds a frame
  bool closing = false;        // the connection is closing: the sender ends
  size_t in_flight_bytes = 0;  // the frame the sender is writing now
  std::thread sender;
};

// One file the page needs, served at `url`.
struct ViewRoute {
  const char* url;
  std::string path;
  const char* mime;
};

struct ViewServer::Impl {
  std::vector<ViewRoute> routes;
  Server* server = nullptr;
  ViewOptions options;
  std::string static_json;
  mg_context* ctx = nullptr;
  uint16_t port = 0;
  std::thread view_thread;
  std::atomic<bool> stop{false};
  std::atomic<bool> new_client{false};  // send a frame even if the tap has nothing new

  std::mutex clients_mu;  // the list; view thread, civetweb workers and stats() only
  std::vector<ViewClient*> clients;

  std::atomic<uint64_t> frames_built{0};
  std::atomic<uint64_t> frames_sent{0};
  std::atomic<uint64_t> frames_dropped{0};
  std::atomic<uint64_t> bytes_sent{0};
  std::atomic<uint64_t> clients_total{0};
  std::atomic<uint64_t> clients_given_up{0};
  std::atomic<uint64_t> max_queued_bytes{0};

  void ViewThread();
  void SenderThread(ViewClient* c);
  uint64_t QueuedBytesLocked();  // with clients_mu held
};

namespace {

// A path under `dir`, which must exist (the page cannot work without it).
std::string ViewFileOrThrow(const std::string& dir, const std::string& name,
                            const std::string& hint) {
  const std::string path = (std::filesystem::path(dir) / name).string();
  if (!std::filesystem::is_regular_file(path)) {
    throw std::runtime_error("view: missing " + path + (hint.empty() ? "" : " (" + hint + ")"));
  }
  return path;
}

int ViewHttpHandler(mg_connection* conn, void* cbdata) {
  const auto* impl = static_cast<const ViewServer::Impl*>(cbdata);
  const mg_request_info* info = mg_get_request_info(conn);
  const std::string uri = info->local_uri != nullptr ? info->local_uri : "/";
  for (const ViewRoute& r : impl->routes) {
    if (uri == r.url) {
      mg_send_mime_file(conn, r.path.c_str(), r.mime);
      return 200;
    }
  }
  mg_send_http_error(conn, 404, "%s", "not found");
  return 404;
}

int ViewWsConnect(const mg_connection* /*conn*/, void* cbdata) {
  auto* impl = static_cast<ViewServer::Impl*>(cbdata);
  std::lock_guard<std::mutex> lock(impl->clients_mu);
  // Non-zero refuses the upgrade: every client holds one civetweb worker.
  return impl->clients.size() >= static_cast<size_t>(impl->options.max_clients) ? 1 : 0;
}

void ViewWsReady(mg_connection* conn, void* cbdata) {
  auto* impl = static_cast<ViewServer::Impl*>(cbdata);
  auto* c = new ViewClient;  // owned by the list until ViewWsClose deletes it
  c->conn = conn;
  mg_set_user_connection_data(conn, c);
  {
    std::lock_guard<std::mutex> lock(impl->clients_mu);
    impl->clients.push_back(c);
  }
  impl->clients_total.fetch_add(1);
  c->sender = std::thread([impl, c] { impl->SenderThread(c); });
  impl->new_client.store(true);
}

int ViewWsData(mg_connection* /*conn*/, int bits, char* /*data*/, size_t /*len*/,
               void* /*cbdata*/) {
  // The page sends nothing but control frames; a close frame ends the connection.
  return (bits & 0x0F) == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE ? 0 : 1;
}

void ViewWsClose(const mg_connection* conn, void* cbdata) {
  auto* impl = static_cast<ViewServer::Impl*>(cbdata);
  auto* c = static_cast<ViewClient*>(mg_get_user_connection_data(conn));
  if (c == nullptr) return;
  {
    std::lock_guard<std::mutex> lock(impl->clients_mu);
    impl->clients.erase(std::remove(impl->clients.begin(), impl->clients.end(), c),
                        impl->clients.end());
  }
  {
    std::lock_guard<std::mutex> lock(c->mu);
    c->closing = true;
  }
  c->wake.notify_all();
  c->sender.join();
  delete c;
}

int ViewLogMessage(const mg_connection* /*conn*/, const char* message) {
  spdlog::debug("view: civetweb: {}", message);
  return 1;  // handled: civetweb writes nothing itself
}

void PutU32(uint8_t* p, uint32_t v) { std::memcpy(p, &v, 4); }
void PutF64(uint8_t* p, double v) { std::memcpy(p, &v, 8); }

}  // namespace

size_t ViewFrameBytes(int32_t particles, uint32_t devices) {
  return kViewHeaderBytes +
         4 * (3 * static_cast<size_t>(particles) +
              static_cast<size_t>(devices) * kViewDeviceFloats + kViewStatsFloats);
}

std::string StaticJson(const Server& server) {
  const ClothModel& model = server.model();
  Json tris = Json::array();
  for (const Triangle& t : model.triangles) {
    tris.push_back(t[0]);
    tris.push_back(t[1]);
    tris.push_back(t[2]);
  }
  auto vec = [](const Vec3& v) { return Json::array({v.x(), v.y(), v.z()}); };
  Json obstacles = Json::array();
  for (const ObstacleSpec& o : server.spec().sim.cloth.obstacles) {
    if (const auto* p = std::get_if<PlaneSpec>(&o.shape)) {
      obstacles.push_back(
          {{"type", "plane"}, {"point", vec(p->point_m)}, {"normal", vec(p->normal)}});
    } else if (const auto* s = std::get_if<SphereSpec>(&o.shape)) {
      obstacles.push_back(
          {{"type", "sphere"}, {"center", vec(s->center_m)}, {"radius", s->radius_m}});
    } else if (const auto* b = std::get_if<BoxSpec>(&o.shape)) {
      obstacles.push_back({{"type", "box"}, {"min", vec(b->min_m)}, {"max", vec(b->max_m)}});
    } else if (const auto* c = std::get_if<CapsuleSpec>(&o.shape)) {
      obstacles.push_back(
          {{"type", "capsule"}, {"a", vec(c->a_m)}, {"b", vec(c->b_m)}, {"radius", c->radius_m}});
    }
  }
  Json devices = Json::array();
  for (uint32_t i = 0; i < server.haptic().device_count(); ++i) {
    devices.push_back({{"id", server.haptic().device_spec(i).id},
                       {"radius_m", server.haptic().proxy_model(i).radius_m}});
  }
  Json doc = {{"type", "static"},
              {"version", kViewVersion},
              {"scene", server.spec().scene_name},
              {"width", model.width},
              {"height", model.height},
              {"spacing_m", model.spacing_m},
              {"triangles", std::move(tris)},
              {"obstacles", std::move(obstacles)},
              {"devices", std::move(devices)},
              {"haptic_rate_hz", server.spec().haptic.haptic_rate_hz},
              {"frame_rate_hz", server.spec().sim.integration.frame_rate_hz},
              {"layout",
               {{"magic", kViewMagic},
                {"header_bytes", kViewHeaderBytes},
                {"device_floats", kViewDeviceFloats},
                {"stats_floats", kViewStatsFloats}}}};
  return doc.dump();
}

ViewServer::ViewServer(Server* server, ViewOptions options) : impl_(std::make_unique<Impl>()) {
  if (!(options.rate_hz > 0.0 && options.rate_hz <= 1000.0)) {
    throw std::invalid_argument("view: rate must be in (0, 1000] Hz");
  }
  if (options.max_clients < 1) throw std::invalid_argument("view: max_clients must be >= 1");
  if (options.www_dir.empty()) options.www_dir = FELT_VIEW_WWW_DIR;
  impl_->server = server;
  impl_->options = options;

  // The page's files (checked now, so a missing package is named before anyone connects).
  const std::string three_hint = "install Debian's libjs-three";
  impl_->routes = {
      {"/", ViewFileOrThrow(options.www_dir, "index.html", ""), "text/html; charset=utf-8"},
      {"/index.html", ViewFileOrThrow(options.www_dir, "index.html", ""),
       "text/html; charset=utf-8"},
      {"/view.js", ViewFileOrThrow(options.www_dir, "view.js", ""),
       "text/javascript; charset=utf-8"},
      {"/three.min.js", ViewFileOrThrow(options.three_dir, "three.min.js", three_hint),
       "text/javascript; charset=utf-8"},
      {"/OrbitControls.js",
       ViewFileOrThrow(options.three_dir, "examples/js/controls/OrbitControls.js", three_hint),
       "text/javascript; charset=utf-8"}};

  static std::once_flag init_once;
  std::call_once(init_once, [] { mg_init_library(MG_FEATURES_WEBSOCKET); });
  if (mg_check_feature(MG_FEATURES_WEBSOCKET) == 0) {
    throw std::runtime_error("view: this civetweb was built without WebSocket support");
  }

  server->EnableViewTap();
  impl_->static_json = StaticJson(*server);

  const std::string listen = options.bind + ":" + std::to_string(options.port);
  const std::string threads = std::to_string(options.max_clients + 4);
  const std::string timeout = std::to_string(options.send_timeout_ms);
  const char* mg_options[] = {"listening_ports",
                              listen.c_str(),
                              "num_threads",
                              threads.c_str(),
                              "request_timeout_ms",
                              timeout.c_str(),
                              "websocket_timeout_ms",
                              "10000",
                              "enable_websocket_ping_pong",
                              "yes",
                              nullptr};
  mg_callbacks callbacks{};
  callbacks.log_message = ViewLogMessage;
  mg_init_data init{};
  init.callbacks = &callbacks;
  init.user_data = impl_.get();
  init.configuration_options = mg_options;
  mg_error_data error{};
  char error_text[256] = {0};
  error.text = error_text;
  error.text_buffer_size = sizeof(error_text);
  impl_->ctx = mg_start2(&init, &error);
  if (impl_->ctx == nullptr) {
    throw std::runtime_error("view: cannot listen on " + listen + ": " + error_text);
  }
  mg_server_port ports[4] = {};
  const int n = mg_get_server_ports(impl_->ctx, 4, ports);
  if (n < 1) {
    mg_stop(impl_->ctx);
    throw std::runtime_error("view: civetweb reports no listening port for " + listen);
  }
  impl_->port = static_cast<uint16_t>(ports[0].port);
  mg_set_request_handler(impl_->ctx, "/", ViewHttpHandler, impl_.get());
  mg_set_websocket_handler(impl_->ctx, "/ws", ViewWsConnect, ViewWsReady, ViewWsData, ViewWsClose,
                           impl_.get());
  impl_->view_thread = std::thread([impl = impl_.get()] { impl->ViewThread(); });
}

ViewServer::~ViewServer() {
  impl_->stop.store(true);
  if (impl_->view_thread.joinable()) impl_->view_thread.join();
  // Wake every sender so that none waits for a frame while civetweb closes its connection.
  {
    std::lock_guard<std::mutex> lock(impl_->clients_mu);
    for (ViewClient* c : impl_->clients) {
      std::lock_guard<std::mutex> client_lock(c->mu);
      c->closing = true;
      c->wake.notify_all();
    }
  }
  mg_stop(impl_->ctx);  // closes every connection (ViewWsClose joins and frees each client)
}

uint16_t ViewServer::port() const { return impl_->port; }

std::string ViewServer::url() const {
  std::string host = impl_->options.bind;
  if (host == "0.0.0.0" || host.empty()) {
    char name[256] = {0};
    host = gethostname(name, sizeof(name) - 1) == 0 ? name : "localhost";
  }
  return "http://" + host + ":" + std::to_string(impl_->port) + "/";
}

uint64_t ViewServer::Impl::QueuedBytesLocked() {
  uint64_t queued = 0;
  for (ViewClient* c : clients) {
    std::lock_guard<std::mutex> lock(c->mu);
    queued += (c->has_frame ? c->slot.size() : 0) + c->in_flight_bytes;
  }
  return queued;
}

ViewStats ViewServer::stats() const {
  ViewStats s;
  s.frames_built = impl_->frames_built.load();
  s.frames_sent = impl_->frames_sent.load();
  s.frames_dropped = impl_->frames_dropped.load();
  s.bytes_sent = impl_->bytes_sent.load();
  s.clients_total = impl_->clients_total.load();
  s.clients_given_up = impl_->clients_given_up.load();
  {
    std::lock_guard<std::mutex> lock(impl_->clients_mu);
    s.clients = impl_->clients.size();
    s.queued_bytes = impl_->QueuedBytesLocked();
  }
  s.max_queued_bytes = std::max(impl_->max_queued_bytes.load(), s.queued_bytes);
  return s;
}

void ViewServer::Impl::SenderThread(ViewClient* c) {
  std::vector<uint8_t> sending;
  bool ok = mg_websocket_write(c->conn, MG_WEBSOCKET_OPCODE_TEXT, static_json.data(),
                               static_json.size()) > 0;
  if (ok) bytes_sent.fetch_add(static_json.size());
  std::unique_lock<std::mutex> lock(c->mu);
  while (ok) {
    c->wake.wait(lock, [c] { return c->has_frame || c->closing; });
    if (c->closing) break;
    std::swap(sending, c->slot);  // both keep their capacity: no allocation once warm
    c->has_frame = false;
    c->in_flight_bytes = sending.size();
    lock.unlock();
    // Blocks while the socket is full (until the peer reads or goes, or mg_stop): only this
    // client's sender waits; the view thread keeps replacing the frame in the slot.
    const int written =
        mg_websocket_write(c->conn, MG_WEBSOCKET_OPCODE_BINARY,
                           reinterpret_cast<const char*>(sending.data()), sending.size());
    lock.lock();
    c->in_flight_bytes = 0;
    if (written <= 0) {
      ok = false;
    } else {
      frames_sent.fetch_add(1);
      bytes_sent.fetch_add(sending.size());
    }
  }
  if (!ok && !c->closing) {
    // A write failed or timed out mid-frame: the stream is broken, so send nothing more. The
    // connection ends when the peer goes or the server stops.
    clients_given_up.fetch_add(1);
    c->has_frame = false;
    c->wake.wait(lock, [c] { return c->closing; });
  }
}

void ViewServer::Impl::ViewThread() {
  ViewTap& tap = *server->view_tap();
  const uint32_t devices = server->haptic().device_count();
  const int32_t particles = server->model().num_particles();
  std::vector<uint8_t> frame(ViewFrameBytes(particles, devices), 0);
  std::array<float, kViewStatsFloats> stats{};
  std::unique_ptr<ServerReport> previous = server->Report();
  const auto period = std::chrono::nanoseconds(static_cast<int64_t>(1e9 / options.rate_hz));
  auto next = std::chrono::steady_clock::now();
  auto next_stats = next;
  bool have_cloth = false;
  bool have_devices = false;
  while (!stop.load()) {
    next += period;
    std::this_thread::sleep_until(next);
    const auto now = std::chrono::steady_clock::now();
    if (now > next + period) next = now;  // fell behind: no burst to catch up
    // The tap's read sides: this thread is their only reader.
    const bool new_cloth = tap.cloth.Acquire();
    const bool new_devices = tap.devices.Acquire();
    have_cloth = have_cloth || new_cloth;
    have_devices = have_devices || new_devices;
    // The loops' timing over the last window, ten times a second (Report is lock-free).
    if (now >= next_stats) {
      next_stats = now + std::chrono::milliseconds(100);
      std::unique_ptr<ServerReport> report = server->Report();
      const LoopStatsSnapshot h = report->haptic.Minus(previous->haptic);
      const LoopStatsSnapshot s = report->sim.Minus(previous->sim);
      const double window_s =
          static_cast<double>(report->haptic.taken_ns - previous->haptic.taken_ns) * 1e-9;
      if (h.ticks > 0) {
        stats[0] = static_cast<float>(static_cast<double>(h.lateness.PercentileNs(0.99)) * 1e-3);
        stats[1] = static_cast<float>(static_cast<double>(h.lateness.max_ns) * 1e-3);
      }
      if (s.ticks > 0) {
        stats[2] = static_cast<float>(static_cast<double>(s.compute.PercentileNs(0.5)) * 1e-6);
        stats[3] = static_cast<float>(static_cast<double>(s.compute.max_ns) * 1e-6);
      }
      if (window_s > 0) {
        stats[4] = static_cast<float>(static_cast<double>(h.ticks) / window_s);
        stats[5] = static_cast<float>(static_cast<double>(s.ticks) / window_s);
      }
      previous = std::move(report);
    }
    const bool joined = new_client.exchange(false);
    if (!(new_cloth || new_devices || joined)) continue;
    {
      std::lock_guard<std::mutex> lock(clients_mu);
      if (clients.empty()) continue;
    }
    // Build the frame (docs/view.md, "Binary frames").
    const ViewCloth& cloth = tap.cloth.read_slot();
    const ViewDevices& devs = tap.devices.read_slot();
    uint8_t* p = frame.data();
    PutU32(p, kViewMagic);
    const uint32_t version_and_header = kViewVersion | (kViewHeaderBytes << 16);
    PutU32(p + 4, version_and_header);
    PutU32(p + 8, static_cast<uint32_t>(particles));
    PutU32(p + 12, devices);
    PutU32(p + 16, kViewDeviceFloats);
    PutU32(p + 20, kViewStatsFloats);
    PutF64(p + 24, have_cloth ? cloth.time_s : 0.0);
    PutF64(p + 32, static_cast<double>(have_cloth ? cloth.frame : 0));
    PutF64(p + 40, static_cast<double>(have_devices ? devs.tick : 0));
    std::memcpy(p + kViewHeaderBytes, cloth.xyz_m.data(), cloth.xyz_m.size() * sizeof(float));
    auto* f = reinterpret_cast<float*>(p + kViewHeaderBytes + cloth.xyz_m.size() * sizeof(float));
    for (uint32_t i = 0; i < devices; ++i) {
      const ViewDevice& d = devs.devices[i];
      float* b = f + static_cast<size_t>(i) * kViewDeviceFloats;
      std::fill(b, b + kViewDeviceFloats, 0.0f);
      auto put3 = [](float* out, const Vec3& v) {
        out[0] = static_cast<float>(v.x());
        out[1] = static_cast<float>(v.y());
        out[2] = static_cast<float>(v.z());
      };
      put3(b, d.goal_W_m);
      put3(b + 3, d.proxy_W_m);
      put3(b + 6, d.force_W_N);
      b[9] = static_cast<float>(d.force_W_N.norm());
      b[10] = static_cast<float>(d.num_contacts);
      b[11] = d.fresh ? 1.0f : 0.0f;
      for (int k = 0; k < d.num_contacts && k < kMaxConstraintPlanes; ++k) {
        float* cb = b + 12 + 8 * k;
        put3(cb, d.contacts[static_cast<size_t>(k)].point_W_m);
        put3(cb + 3, d.contacts[static_cast<size_t>(k)].normal_W);
        cb[6] = static_cast<float>(d.contacts[static_cast<size_t>(k)].triangle);
      }
    }
    std::memcpy(f + static_cast<size_t>(devices) * kViewDeviceFloats, stats.data(),
                sizeof(float) * kViewStatsFloats);
    frames_built.fetch_add(1);
    // Offer it to every client: its slot keeps only the newest.
    std::lock_guard<std::mutex> lock(clients_mu);
    for (ViewClient* c : clients) {
      {
        std::lock_guard<std::mutex> client_lock(c->mu);
        if (c->has_frame) frames_dropped.fetch_add(1);
        c->slot.assign(frame.begin(), frame.end());
        c->has_frame = true;
      }
      c->wake.notify_one();
    }
    const uint64_t queued = QueuedBytesLocked();
    uint64_t seen = max_queued_bytes.load();
    while (queued > seen && !max_queued_bytes.compare_exchange_weak(seen, queued)) {
    }
  }
}

}  // namespace felt
