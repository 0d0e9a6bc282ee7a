// `felt view --scene FILE --trace FILE [--port P] [--bind ADDR] [--speed X] [--exit-at-end]`:
// plays a pointer trace through the scene in virtual time, as `felt compare` does
// (compare/lockstep.h: the same schedule of haptic ticks and sim frames on a virtual clock from
// kLockstepEpochNs, one thread, no DDS), paced to the wall clock, and serves the live view of it
// (view/view_server.h, docs/view.md). After the trace it keeps serving the last state until
// SIGINT/SIGTERM (or exits with --exit-at-end).
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "app/command.h"
#include "app/command_util.h"
#include "compare/lockstep.h"
#include "haptic_loop/pointer_source.h"
#include "recordings/trace.h"
#include "scene/scene_file.h"
#include "server/server.h"
#include "server/server_spec.h"
#include "view/view_server.h"

namespace felt::app::cmd_view {
namespace {

struct ViewArgs {
  std::string scene;
  std::string trace;
  uint16_t port = 8080;
  std::string bind = "127.0.0.1";
  double speed = 1.0;
  bool exit_at_end = false;
};

int Play(const ViewArgs& args) {
  ServerSpec spec;
  try {
    spec = CheckWholeScene(LoadSceneDocument(args.scene));
  } catch (const SceneError& e) {
    std::fprintf(stderr, "felt view: %s\n", e.what());
    return 2;
  }
  if (!(args.speed > 0.0)) throw std::invalid_argument("--speed must be > 0");
  const Trace trace = ReadTrace(args.trace);
  const auto devices = static_cast<uint32_t>(spec.devices.size());
  TracePointerSource source(std::vector<std::vector<TraceSample>>(devices, trace.samples));
  CapturingForceSink sink(devices);
  ServerOptions options;
  options.apply_realtime = false;  // no loop threads: this thread drives the server
  options.monitor_log = false;
  Server server(std::move(spec), &source, &sink, options);
  ViewOptions view_options;
  view_options.port = args.port;
  view_options.bind = args.bind;
  ViewServer view(&server, view_options);
  std::printf("felt view: %s on %s, live view at %s\n", args.trace.c_str(), args.scene.c_str(),
              view.url().c_str());
  std::fflush(stdout);
  InstallStopHandlers();

  // The lock-step schedule (compare/lockstep.h), virtual time t = epoch + elapsed.
  const double tick_hz = server.spec().haptic.haptic_rate_hz;
  const double frame_hz = server.spec().sim.integration.frame_rate_hz;
  const double length_s = trace.samples.back().t_s - trace.samples.front().t_s + 0.5;
  server.PublishInitialSnapshot(kLockstepEpochNs);
  const auto wall0 = std::chrono::steady_clock::now();
  int64_t frame = 1;
  for (int64_t tick = 1; !StopRequested().load(); ++tick) {
    const auto tick_ns =
        static_cast<int64_t>(std::llround(static_cast<double>(tick) * 1e9 / tick_hz));
    if (static_cast<double>(tick_ns) * 1e-9 > length_s) break;
    for (;;) {
      const auto frame_ns =
          static_cast<int64_t>(std::llround(static_cast<double>(frame) * 1e9 / frame_hz));
      if (frame_ns > tick_ns) break;
      server.SimFrame(1.0 / frame_hz, kLockstepEpochNs + frame_ns);
      ++frame;
    }
    server.HapticTick(kLockstepEpochNs + tick_ns, 1.0 / tick_hz);
    // Paced to the wall clock (every 4 ticks: a sleep per 1 ms tick costs more than it gains).
    if (tick % 4 == 0) {
      std::this_thread::sleep_until(wall0 + std::chrono::nanoseconds(static_cast<int64_t>(
                                                static_cast<double>(tick_ns) / args.speed)));
    }
  }
  std::printf("felt view: trace played (%.2f s)%s\n", length_s,
              args.exit_at_end ? "" : "; serving its last state until Ctrl-C");
  std::fflush(stdout);
  while (!args.exit_at_end && !StopRequested().load()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return 0;
}

CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<ViewArgs>();
  cmd.add_option("--scene", args->scene, "scene file (TOML)")->required();
  cmd.add_option("--trace", args->trace, "felt-trace to play to every device")->required();
  cmd.add_option("--port", args->port, "TCP port of the view (0: any free port)");
  cmd.add_option("--bind", args->bind, "address to listen on (0.0.0.0 exposes it on the LAN)");
  cmd.add_option("--speed", args->speed, "virtual seconds per wall second (default 1)");
  cmd.add_flag("--exit-at-end", args->exit_at_end, "exit when the trace has played");
  return [args]() -> int { return Play(*args); };
}

const bool kRegistered = RegisterCommand(
    {"", "view", "play a trace through a scene in virtual time and watch it in the browser",
     Setup});

}  // namespace
}  // namespace felt::app::cmd_view
