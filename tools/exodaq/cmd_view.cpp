// `exodaq view`: a live view of the arm in a web browser. Subscribes to the
// rig's joint states, palm poses and status, computes every model frame's
// origin from the published angles at display rate, and serves a page (built
// into this binary) plus a Server-Sent Event stream on 127.0.0.1:8077. One
// thread and one poll(): LCM traffic and browsers never wait for each other;
// the 1 kHz stream never reaches the browser. docs/operations.md "Live view".
#include <poll.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "command.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/flag_names.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/settings/calibration_file.hpp"
#include "exodaq/settings/model_file.hpp"
#include "exodaq/settings/service_config.hpp"
#include "view_assets.hpp"
#include "view_http.hpp"
#include "view_scene.hpp"

namespace exodaq::tools {
namespace {

volatile std::sig_atomic_t g_stop = 0;
extern "C" void on_view_stop_signal(int) {
  g_stop = 1;
}

struct ViewOptions {
  std::string config;
  std::string model;
  std::string url;     // empty: the config's (or the default)
  std::string prefix;  // with prefix_given: overrides the config's
  bool prefix_given = false;
  std::string bind = "127.0.0.1";
  int port = 8077;
  double rate_hz = 30.0;
  double trail_s = 5.0;
  double duration_s = 0.0;
};

// The service config used when none is given: the source tree's sim.yaml in a
// build tree, else the installed service's own.
std::string default_config_path() {
#ifdef EXODAQ_VIEW_SOURCE_CONFIG
  struct stat st {};
  if (::stat(EXODAQ_VIEW_SOURCE_CONFIG, &st) == 0) return EXODAQ_VIEW_SOURCE_CONFIG;
#endif
  return "/etc/exodaq/exodaqd.yaml";
}

void fill_joints(view::ViewModel& m, const kinematics::Chain& chain) {
  for (const auto& j : chain.joints()) {
    m.joint_names.push_back(j.name);
    m.joint_limits.push_back({j.limits.lower, j.limits.upper});
  }
}

// The model (and LCM settings) from a service config or a model file. Throws
// exodaq::ConfigError / std::exception with the reason.
view::ViewModel load_view_model(const ViewOptions& o, view::SceneOptions& scene) {
  view::ViewModel m;
  if (!o.model.empty()) {
    settings::KinematicModel km = settings::load_model_file(o.model);
    m.name = km.name;
    m.model_file = km.file.empty() ? o.model : km.file;
    m.chain = km.chain;
    m.elbow_frame = km.rig.elbow_frame;
    fill_joints(m, km.chain);
    scene.url = messages::kDefaultUrl;
    return m;
  }
  const std::string path = o.config.empty() ? default_config_path() : o.config;
  settings::ServiceConfig cfg = settings::load_service_config(path);
  m.name = cfg.model.name;
  m.model_file = cfg.model_path;
  m.config_file = path;
  m.rig = cfg.rig;
  // The chain the daemon evaluates: the model with the calibration applied.
  m.chain = settings::apply_calibration(cfg.model.chain, cfg.calibration);
  m.calibrated = true;
  m.elbow_frame = cfg.model.rig.elbow_frame;
  fill_joints(m, cfg.model.chain);
  scene.url = cfg.lcm.url;
  scene.prefix = cfg.lcm.prefix;
  scene.sync_required = cfg.clock.require_sync != settings::RequireSync::kIgnore;
  return m;
}

void register_pages(view::HttpServer& server, view::ViewScene& scene) {
  for (const view::WebAsset& a : view::web_assets()) {
    auto page = [a] {
      return view::HttpResponse{200, std::string(a.content_type), std::string(a.body)};
    };
    server.add_handler(std::string(a.path), page);
    if (a.path == "/index.html") server.add_handler("/", page);
  }
  server.add_event_stream(
      "/events", [&scene] { return view::sse_event("hello", scene.hello(mono_now_ns())); });
  // For scripts and curl: the same state a new page starts from.
  server.add_handler("/state.json", [&scene] {
    return view::HttpResponse{200, "application/json", scene.hello(mono_now_ns()) + "\n"};
  });
}

int serve(const ViewOptions& o, view::ViewScene& scene, const view::SceneOptions& so) {
  messages::Subscriber subscriber(so.url);
  const int64_t t0 = mono_now_ns();
  subscriber.subscribe(messages::channel_name(so.prefix, messages::Kind::kJointState),
                       messages::Kind::kJointState, [&](const messages::Received& r) {
                         scene.on_joint_state(std::get<joint_state_t>(r.msg), mono_now_ns());
                       });
  subscriber.subscribe(messages::channel_name(so.prefix, messages::Kind::kPalmPose),
                       messages::Kind::kPalmPose, [&](const messages::Received& r) {
                         scene.on_palm_pose(std::get<palm_pose_t>(r.msg), mono_now_ns());
                       });
  subscriber.subscribe(messages::channel_name(so.prefix, messages::Kind::kStatus),
                       messages::Kind::kStatus, [&](const messages::Received& r) {
                         scene.on_status(std::get<status_t>(r.msg), mono_now_ns());
                       });
  subscriber.subscribe(messages::channel_name(so.prefix, messages::Kind::kSourceStatus),
                       messages::Kind::kSourceStatus, [&](const messages::Received& r) {
                         scene.on_source_status(std::get<source_status_t>(r.msg));
                       });

  view::HttpOptions ho;
  ho.bind = o.bind;
  ho.port = o.port;
  view::HttpServer server(ho);
  register_pages(server, scene);
  std::printf("exodaq view: serving %s (LCM %s, prefix '%s'; Ctrl-C stops)\n", server.url().c_str(),
              so.url.c_str(), so.prefix.c_str());
  std::fflush(stdout);

  struct sigaction sa {};
  sa.sa_handler = on_view_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  const int64_t period_ns = static_cast<int64_t>(1e9 / o.rate_hz);
  const int64_t end_ns = o.duration_s > 0 ? t0 + static_cast<int64_t>(o.duration_s * 1e9) : 0;
  int64_t next_tick = t0;
  std::vector<pollfd> fds;
  while (!g_stop) {
    int64_t now = mono_now_ns();
    if (end_ns && now >= end_ns) break;
    fds.clear();
    fds.push_back(pollfd{subscriber.fileno(), POLLIN, 0});
    server.add_pollfds(fds);
    const int64_t wait_ns = std::max<int64_t>(0, next_tick - now);
    const int r = poll(fds.data(), fds.size(), static_cast<int>((wait_ns + 999'999) / 1'000'000));
    if (r < 0 && errno != EINTR) {
      std::fprintf(stderr, "exodaq view: poll failed: %s\n", std::strerror(errno));
      return kExitFailure;
    }
    if (r > 0 && (fds[0].revents & POLLIN)) {
      // Drain what LCM has, bounded so browsers are served in between.
      for (int k = 0; k < 4096 && subscriber.handle(0) > 0; ++k) {
      }
    }
    now = mono_now_ns();
    server.service(fds, now);  // also when idle: its timeouts run here
    if (now >= next_tick) {
      for (const auto& e : scene.tick(now)) server.publish(e.name, e.json, e.skippable, now);
      next_tick += period_ns;
      if (next_tick <= now) next_tick = now + period_ns;  // fell behind: no burst of ticks
    }
  }
  const view::HttpStats st = server.stats();
  std::printf(
      "exodaq view: stopped: %lld connections, %lld requests (%lld bad), %lld closed to make room, "
      "%lld idle closed, %lld stalled closed, %lld events skipped\n",
      static_cast<long long>(st.accepted), static_cast<long long>(st.requests),
      static_cast<long long>(st.bad_requests), static_cast<long long>(st.evicted),
      static_cast<long long>(st.idle_closed), static_cast<long long>(st.stalled_closed),
      static_cast<long long>(st.skipped_events));
  return kExitOk;
}

int run_view(const ViewOptions& o) {
  view::SceneOptions so;
  so.display_hz = o.rate_hz;
  so.trail_s = o.trail_s;
  std::unique_ptr<view::ViewScene> scene;
  try {
    view::ViewModel model = load_view_model(o, so);
    if (!o.url.empty()) so.url = o.url;
    if (o.prefix_given) so.prefix = o.prefix;
    scene = std::make_unique<view::ViewScene>(std::move(model), so);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "exodaq view: %s\n", e.what());
    return kExitUsage;
  }
  try {
    return serve(o, *scene, so);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "exodaq view: %s\n", e.what());
    return kExitFailure;
  }
}

std::function<int()> setup_view(CLI::App& app) {
  auto o = std::make_shared<ViewOptions>();
  auto* config = app.add_option("--config,-c", o->config,
                                "the daemon's service config: model, calibration, LCM URL and "
                                "prefix (default: " +
                                    default_config_path() + ")");
  auto* model =
      app.add_option("--model", o->model, "a model file instead (nominal chain, default URL)");
  config->excludes(model);
  model->excludes(config);
  app.add_option("--url,-u", o->url, "LCM URL (default: the config's)");
  add_prefix_option(app, o->prefix, "default: the config's")->each([o](const std::string&) {
    o->prefix_given = true;
  });
  app.add_option("--bind", o->bind, "address to listen on (numeric IPv4 or IPv6)")
      ->capture_default_str();
  app.add_option("--port", o->port, "TCP port (0: any free port, printed)")
      ->capture_default_str()
      ->check(CLI::Range(0, 65535));
  app.add_option("--rate", o->rate_hz, "display rate, Hz (the page gets at most this many frames)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 60.0));
  app.add_option("--trail", o->trail_s, "palm trail length, s")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 60.0));
  app.add_option("--duration,-d", o->duration_s, "stop after S seconds (0: until Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  return [o] { return run_view(*o); };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(view, "view",
                        "serve a live view of the arm to a web browser (127.0.0.1:8077): posture, "
                        "palm trail, joint flags, service state, clock health",
                        ::exodaq::tools::setup_view);
