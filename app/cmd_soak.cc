// `felt soak --minutes M [--scene FILE] [--trace FILE] [--json FILE] [--md FILE] [thresholds]`:
// runs the server (`felt serve`) and a replay (`felt replay`) as two child processes of this
// binary over loopback DDS, then reports the server's loop timing (from serve's --stats-json),
// the end-to-end latency and drops (from replay's --json), the server's resident memory at the
// start and end of the replay (/proc/PID/status VmRSS) and the CPU of both (/proc/PID/stat), as
// JSON and a markdown table. Exits 3 when a threshold is crossed (defaults: issue 7's target).
// SIGINT/SIGTERM stop both children cleanly; children also get SIGTERM should this process die
// (PR_SET_PDEATHSIG), so none is left behind (docs/replay.md).
#include <poll.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "app/command.h"
#include "app/command_util.h"
#include "base/json.h"
#include "base/process.h"
#include "base/report.h"
#include "recordings/trace.h"
#include "rt/clock.h"
#include "rt/histogram_plot.h"
#include "scene/scene_file.h"
#include "server/server_spec.h"

namespace felt::app::cmd_soak {
namespace {

constexpr int kExitThreshold = 3;              // a threshold was crossed
constexpr int kExitInterrupted = 130;          // SIGINT/SIGTERM (128 + SIGINT, the shell's habit)
constexpr int64_t kStopGraceNs = 10000000000;  // SIGINT, then SIGKILL after 10 s
constexpr size_t kTailLines = 40;              // output lines kept per child for error reports

// ---- serve's and replay's JSON files ----

// Reads and parses a JSON file; throws std::runtime_error naming the file.
Json ReadJsonFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot read: " + std::strerror(errno));
  std::stringstream text;
  text << in.rdbuf();
  return ParseJson(text.str(), path);
}

// The value at a dotted path ("haptic.lateness_us.p99"), or null when absent.
const Json* Find(const Json& root, std::string_view path) {
  const Json* v = &root;
  while (!path.empty()) {
    const size_t dot = path.find('.');
    if (!v->is_object()) return nullptr;
    const auto next = v->find(std::string(path.substr(0, dot)));
    if (next == v->end()) return nullptr;
    v = &*next;
    path = dot == std::string_view::npos ? std::string_view() : path.substr(dot + 1);
  }
  return v;
}

// The number at `path`, NaN when absent (or null: a non-finite number).
double Num(const Json& root, std::string_view path) {
  const Json* v = Find(root, path);
  return v != nullptr && v->is_number() ? v->get<double>() : std::nan("");
}

// The boolean at `path`, false when absent.
bool Flag(const Json& root, std::string_view path) {
  const Json* v = Find(root, path);
  return v != nullptr && v->is_boolean() && v->get<bool>();
}

// ---- /proc readings ----

// VmRSS of process `pid` in kB, or -1 when it cannot be read (the process is gone).
int64_t ReadRssKb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::strtoll(line.c_str() + 6, nullptr, 10);
  }
  return -1;
}

// utime + stime of process `pid` in seconds (/proc/PID/stat fields 14 and 15, proc(5)), or -1.
double ReadCpuS(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(in, line)) return -1.0;
  // Fields after the command name, which is in parentheses and may hold spaces.
  const size_t close = line.rfind(')');
  if (close == std::string::npos) return -1.0;
  std::istringstream fields(line.substr(close + 2));
  std::string field;
  unsigned long long utime = 0, stime = 0;
  for (int i = 3; i <= 15 && fields >> field; ++i) {
    if (i == 14) utime = std::strtoull(field.c_str(), nullptr, 10);
    if (i == 15) stime = std::strtoull(field.c_str(), nullptr, 10);
  }
  return static_cast<double>(utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

// ---- Child processes ----

// One child: `felt <args>` with stdout and stderr into a pipe that this process reads. Its
// Process kills and reaps it should it still run when this goes out of scope (an exception path):
// no orphan is ever left behind.
struct Child {
  std::string name;
  Process process;
  int64_t stop_sent_ns = 0;  // when SIGINT was sent (0 = not yet)
  std::string partial;       // the unfinished last line
  std::deque<std::string> tail;
  bool echo = false;

  // Reads what is available, line by line; calls on_line for each complete line.
  template <typename OnLine>
  void Drain(OnLine&& on_line) {
    if (process.output_fd() < 0) return;
    // At the end of the output, an unfinished last line is still a line.
    if (!process.ReadOutput(&partial) && !partial.empty()) partial += '\n';
    size_t newline = 0;
    while ((newline = partial.find('\n')) != std::string::npos) {
      std::string line = partial.substr(0, newline);
      partial.erase(0, newline + 1);
      if (echo) std::printf("[%s] %s\n", name.c_str(), line.c_str());
      on_line(line);
      tail.push_back(std::move(line));
      if (tail.size() > kTailLines) tail.pop_front();
    }
  }

  // Asks the child to stop (SIGINT: serve and replay stop cleanly and write their reports).
  void RequestStop() {
    if (process.running() && stop_sent_ns == 0) {
      process.Signal(SIGINT);
      stop_sent_ns = MonotonicNowNs();
    }
  }
};

// Starts `exe args...` with its output into a pipe; it gets SIGTERM when this process dies.
Child SpawnChild(const std::string& name, const std::string& exe,
                 const std::vector<std::string>& args, bool echo) {
  std::vector<std::string> argv = {exe};
  argv.insert(argv.end(), args.begin(), args.end());
  SpawnOptions options;
  options.output = SpawnOptions::Output::kPipe;
  options.die_with_parent = true;
  Child child;
  child.name = name;
  child.process = Process::Spawn(argv, options);
  child.echo = echo;
  return child;
}

// ---- The soak ----

struct SoakArgs {
  double minutes = 0.0;
  std::string scene = "scenes/curtain.toml";
  std::string trace = "recordings/poke_hold.trace";
  std::string json;
  std::string md;
  std::string plot_dir;
  std::optional<uint32_t> domain;
  std::string security;  // DDS Security directory for both children ("" = off)
  bool no_realtime = false;
  std::optional<uint16_t> view_port;  // --view PORT: the server serves the live view (docs/view.md)
  bool verbose = false;
  bool keep_files = false;
  bool report_only = false;
  double max_dropped = 0;
  double max_rss_growth_kb = 1024;
  double max_lateness_p99_us = 100;
  double max_lateness_p999_us = 500;
  double discovery_timeout_s = 20;
};

// One threshold check.
struct Check {
  std::string name;  // what is checked, with its unit
  double value = 0;  // measured (NaN = unknown: fails)
  double limit = 0;  // the largest value that passes
  bool pass = false;
};

std::string Fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "n/a";
  return fmt::format("{:.{}f}", v, decimals);
}

// What a soak runs, read and checked before anything starts.
struct SoakPlan {
  std::string device_id;    // the scene's first device, which the replay stands in for
  double duration_s = 0.0;  // replay time
  uint32_t domain = 0;      // DDS domain of both children
  std::string dir;          // a private directory for the children's reports
  std::string serve_json;   // the server's --stats-json
  std::string replay_json;  // the replay's --json
  std::string exe;          // this felt binary
};

SoakPlan PlanSoak(const SoakArgs& args) {
  if (!(args.minutes > 0.0 && args.minutes <= 1440.0)) {
    throw std::invalid_argument(
        fmt::format("--minutes must be in (0, 1440], got {}", args.minutes));
  }
  const ServerSpec spec = CheckWholeScene(LoadSceneDocument(args.scene));
  if (spec.devices.empty()) throw std::invalid_argument(args.scene + ": the scene has no device");
  (void)ReadTrace(args.trace);  // a bad trace is refused here, before a child starts
  SoakPlan plan;
  plan.device_id = spec.devices.front().id;
  plan.duration_s = args.minutes * 60.0;
  plan.domain = args.domain.value_or(100 + static_cast<uint32_t>(getpid() % 100));
  std::string dir_template = (std::filesystem::temp_directory_path() / "felt-soak-XXXXXX").string();
  if (mkdtemp(dir_template.data()) == nullptr) {
    throw std::runtime_error("soak: cannot create a temporary directory: " +
                             std::string(std::strerror(errno)));
  }
  plan.dir = dir_template;
  plan.serve_json = plan.dir + "/serve.json";
  plan.replay_json = plan.dir + "/replay.json";
  char exe_buffer[4096];
  const ssize_t exe_length = readlink("/proc/self/exe", exe_buffer, sizeof(exe_buffer) - 1);
  if (exe_length <= 0) throw std::runtime_error("soak: cannot read /proc/self/exe");
  plan.exe.assign(exe_buffer, static_cast<size_t>(exe_length));
  return plan;
}

// `felt serve` and `felt replay` as the plan has them.
std::pair<Child, Child> SpawnChildren(const SoakArgs& args, const SoakPlan& plan) {
  std::vector<std::string> serve_args = {
      "serve",        "--scene",      args.scene, "--domain", std::to_string(plan.domain),
      "--stats-json", plan.serve_json};
  if (args.no_realtime) serve_args.push_back("--no-realtime");
  if (args.view_port) {
    serve_args.push_back("--view");
    serve_args.push_back(std::to_string(*args.view_port));
  }
  std::vector<std::string> replay_args = {"replay",
                                          args.trace,
                                          "--domain",
                                          std::to_string(plan.domain),
                                          "--device",
                                          plan.device_id,
                                          "--duration",
                                          fmt::format("{}", plan.duration_s),
                                          "--json",
                                          plan.replay_json,
                                          "--discovery-timeout",
                                          fmt::format("{}", args.discovery_timeout_s)};
  if (!args.security.empty()) {  // identities "server" and "device-<the scene's first device>"
    for (auto* list : {&serve_args, &replay_args}) {
      list->push_back("--security");
      list->push_back(args.security);
    }
  }
  Child serve = SpawnChild("serve", plan.exe, serve_args, args.verbose);
  Child replay = SpawnChild("replay", plan.exe, replay_args, args.verbose);
  if (args.view_port) {
    std::printf("soak: watch it live at http://127.0.0.1:%u/ (felt serve --view)\n",
                static_cast<unsigned>(*args.view_port));
    std::fflush(stdout);
  }
  return {std::move(serve), std::move(replay)};
}

// What watching the two children saw: the replay's window, the server's memory and CPU over it.
struct SoakWatch {
  int64_t publishing_ns = 0;  // the replay started publishing (0: never)
  int64_t replay_end_ns = 0;  // the replay ended (0: never)
  int64_t rss_start_kb = -1, rss_end_kb = -1, rss_max_kb = -1;
  double serve_cpu_start_s = -1, serve_cpu_end_s = -1, replay_cpu_start_s = -1;
  bool interrupted = false, timed_out = false, serve_died = false;

  // The replay's window in seconds (NaN when it never started or ended).
  double window_s() const {
    return publishing_ns != 0 && replay_end_ns != 0
               ? static_cast<double>(replay_end_ns - publishing_ns) / 1e9
               : std::nan("");
  }
};

// Watches both children until they end: output, the start of publication, the server's RSS once a
// second, the replay's end (which stops the server), signals, the time limit, the grace time.
SoakWatch WatchChildren(const SoakArgs& args, const SoakPlan& plan, Child* serve, Child* replay) {
  SoakWatch w;
  const int64_t limit_ns =
      MonotonicNowNs() +
      static_cast<int64_t>((plan.duration_s + args.discovery_timeout_s + 60.0) * 1e9);
  int64_t next_rss_ns = 0;
  const auto on_replay_line = [&](const std::string& line) {
    if (w.publishing_ns == 0 && line.find("felt replay: publishing") != std::string::npos) {
      // The replay starts now: the server's memory and CPU at the start.
      w.publishing_ns = MonotonicNowNs();
      w.rss_start_kb = w.rss_max_kb = ReadRssKb(serve->process.pid());
      w.serve_cpu_start_s = ReadCpuS(serve->process.pid());
      w.replay_cpu_start_s = ReadCpuS(replay->process.pid());
      next_rss_ns = w.publishing_ns + 1000000000;
    }
  };
  while (serve->process.running() || replay->process.running()) {
    pollfd fds[2] = {{serve->process.output_fd(), POLLIN, 0},
                     {replay->process.output_fd(), POLLIN, 0}};
    (void)poll(fds, 2, 100);
    serve->Drain([](const std::string&) {});
    replay->Drain(on_replay_line);
    const int64_t now_ns = MonotonicNowNs();
    if (w.publishing_ns != 0 && w.replay_end_ns == 0 && now_ns >= next_rss_ns) {
      w.rss_max_kb = std::max(w.rss_max_kb, ReadRssKb(serve->process.pid()));
      next_rss_ns += 1000000000;
    }
    // The replay's end: the server's memory and CPU at the end, then the server is stopped.
    if (replay->process.running() && replay->process.Poll()) replay->Drain(on_replay_line);
    if (!replay->process.running() && w.replay_end_ns == 0) {
      w.replay_end_ns = now_ns;
      if (serve->process.running()) {
        w.rss_end_kb = ReadRssKb(serve->process.pid());
        w.rss_max_kb = std::max(w.rss_max_kb, w.rss_end_kb);
        w.serve_cpu_end_s = ReadCpuS(serve->process.pid());
      }
      serve->RequestStop();
    }
    if (serve->process.running() && serve->process.Poll()) {
      serve->Drain([](const std::string&) {});
      if (replay->process.running()) {
        w.serve_died = true;
        replay->RequestStop();
      }
    }
    // A signal stops the replay first; its end then stops the server as usual (so the memory at
    // the end and the server's counts are still taken). The overall limit stops both.
    if (StopRequested().load() && !w.interrupted) {
      w.interrupted = true;
      replay->RequestStop();
    }
    if (now_ns > limit_ns && !w.timed_out) {
      w.timed_out = true;
      serve->RequestStop();
      replay->RequestStop();
    }
    // A child that does not stop within the grace time is killed.
    for (Child* c : {serve, replay}) {
      if (c->process.running() && c->stop_sent_ns != 0 && now_ns - c->stop_sent_ns > kStopGraceNs) {
        c->process.Signal(SIGKILL);
      }
    }
  }
  return w;
}

// Whether a child failed; after SIGINT/SIGTERM, a child that ended on the SIGINT passed on (even
// before its handler was installed) or gave up early is expected, not a failure. Prints each
// child's last output when one failed.
bool ReportChildFailures(const SoakWatch& w, const Child& serve, const Child& replay) {
  const auto failed = [](const Child& c) {
    return c.process.term_signal() != 0 ||
           (c.process.exit_code() != 0 && c.process.exit_code() != -1);
  };
  const bool child_failed =
      !w.interrupted && (failed(serve) || failed(replay) || w.serve_died || w.timed_out);
  if (!child_failed) return false;
  for (const Child* c : {&serve, &replay}) {
    std::fprintf(stderr, "felt soak: %s: %s; its last output:\n", c->name.c_str(),
                 c->process.Outcome().c_str());
    for (const std::string& line : c->tail) std::fprintf(stderr, "  | %s\n", line.c_str());
  }
  if (w.serve_died) std::fprintf(stderr, "felt soak: the server ended before the replay\n");
  if (w.timed_out) std::fprintf(stderr, "felt soak: the run passed its time limit\n");
  return true;
}

// Everything a soak reports: the children's reports, the derived figures and the checks.
struct SoakResult {
  Json serve_report, replay_report;  // null when missing
  double window_s = 0, serve_cpu_s = 0, replay_cpu_s = 0, rss_growth_kb = 0;
  double pointer_lost = 0, dropped = 0;
  std::vector<Check> checks;
  bool pass = true;  // every check passed
  bool child_failed = false;
  std::string load_start, load_end;
};

// The derived figures and the checks (a value that is unknown fails).
void Evaluate(const SoakArgs& args, const SoakWatch& w, const Child& replay, SoakResult* r) {
  r->window_s = w.window_s();
  r->serve_cpu_s = w.serve_cpu_start_s >= 0 && w.serve_cpu_end_s >= 0
                       ? w.serve_cpu_end_s - w.serve_cpu_start_s
                       : std::nan("");
  const rusage& u = replay.process.usage();
  const double replay_total_cpu_s =
      static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
      static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e6;
  r->replay_cpu_s =
      w.replay_cpu_start_s >= 0 ? replay_total_cpu_s - w.replay_cpu_start_s : std::nan("");
  r->rss_growth_kb = w.rss_start_kb >= 0 && w.rss_end_kb >= 0
                         ? static_cast<double>(w.rss_end_kb - w.rss_start_kb)
                         : std::nan("");
  // Pointer samples lost: known only when the replay saw the server's status before and after.
  const Json& replay_report = r->replay_report;
  r->pointer_lost =
      Flag(replay_report, "server_counts") ? Num(replay_report, "pointer_lost") : std::nan("");
  r->dropped =
      r->pointer_lost + Num(replay_report, "forces_lost") + Num(replay_report, "publish_failures");
  r->checks = {
      {"dropped samples (pointer lost + forces lost + publish failures)", r->dropped,
       args.max_dropped},
      {"server RSS growth kB", r->rss_growth_kb, args.max_rss_growth_kb},
      {"haptic lateness p99 us", Num(r->serve_report, "haptic.lateness_us.p99"),
       args.max_lateness_p99_us},
      {"haptic lateness p99.9 us", Num(r->serve_report, "haptic.lateness_us.p999"),
       args.max_lateness_p999_us},
  };
  for (Check& c : r->checks) {
    c.pass = std::isfinite(c.value) && c.value <= c.limit;
    r->pass = r->pass && c.pass;
  }
}

Json SoakJson(const SoakArgs& args, const SoakPlan& plan, const SoakWatch& w, const Child& serve,
              const Child& replay, const SoakResult& r) {
  Json server{{"exit_code", serve.process.exit_code()},
              {"rss_start_kB", w.rss_start_kb},
              {"rss_end_kB", w.rss_end_kb},
              {"rss_max_kB", w.rss_max_kb},
              {"rss_growth_kB", r.rss_growth_kb},
              {"cpu_s", r.serve_cpu_s},
              {"cpu_percent", r.serve_cpu_s / r.window_s * 100.0}};
  if (!r.serve_report.is_null()) server["stats"] = r.serve_report;
  Json replayed{{"exit_code", replay.process.exit_code()},
                {"cpu_s", r.replay_cpu_s},
                {"cpu_percent", r.replay_cpu_s / r.window_s * 100.0}};
  if (!r.replay_report.is_null()) replayed["report"] = r.replay_report;
  Json check_json = Json::object();
  for (const Check& c : r.checks) {
    check_json[c.name] = Json{{"value", c.value}, {"limit", c.limit}, {"pass", c.pass}};
  }
  return Json{{"command", fmt::format("felt soak --minutes {} --scene {} --trace {}", args.minutes,
                                      args.scene, args.trace)},
              {"minutes", args.minutes},
              {"scene", args.scene},
              {"trace", args.trace},
              {"device_id", plan.device_id},
              {"domain", plan.domain},
              {"load_average_start", r.load_start},
              {"load_average_end", r.load_end},
              {"window_s", r.window_s},
              {"interrupted", w.interrupted},
              {"children_ok", !r.child_failed},
              {"server", server},
              {"replay", replayed},
              {"thresholds", Json{{"max_dropped", args.max_dropped},
                                  {"max_rss_growth_kB", args.max_rss_growth_kb},
                                  {"max_haptic_lateness_p99_us", args.max_lateness_p99_us},
                                  {"max_haptic_lateness_p999_us", args.max_lateness_p999_us}}},
              {"checks", check_json},
              {"pass", r.pass && !r.child_failed}};
}

std::string SoakMarkdown(const SoakArgs& args, const SoakWatch& w, const SoakResult& r) {
  const Json& serve_report = r.serve_report;
  const Json& replay_report = r.replay_report;
  std::string md = "# felt soak\n\n";
  md += fmt::format("Command: `felt soak --minutes {} --scene {} --trace {}{}`  \n", args.minutes,
                    args.scene, args.trace, args.no_realtime ? " --no-realtime" : "");
  md += fmt::format("Load average (1, 5, 15 min): start {}, end {}. Replay window {} s.\n\n",
                    r.load_start, r.load_end, Fixed(r.window_s, 1));
  md += "| quantity | p50 | p99 | p99.9 | max |\n|---|---|---|---|---|\n";
  const auto row = [&](const std::string& label, const Json& root, const std::string& path,
                       int decimals) {
    md += fmt::format(
        "| {} | {} | {} | {} | {} |\n", label, Fixed(Num(root, path + ".p50"), decimals),
        Fixed(Num(root, path + ".p99"), decimals), Fixed(Num(root, path + ".p999"), decimals),
        Fixed(Num(root, path + ".max"), decimals));
  };
  row("haptic lateness (us)", serve_report, "haptic.lateness_us", 0);
  row("haptic period (us)", serve_report, "haptic.period_us", 0);
  row("haptic compute (us)", serve_report, "haptic.compute_us", 0);
  row("sim frame (ms)", serve_report, "sim.frame_ms", 2);
  row("sim lateness (us)", serve_report, "sim.lateness_us", 0);
  row("end-to-end latency (us)", replay_report, "latency_us", 0);
  row("replay publish lateness (us)", replay_report, "lateness_us", 0);
  md += "\n| quantity | value |\n|---|---|\n";
  const auto item = [&](const std::string& label, const std::string& value) {
    md += fmt::format("| {} | {} |\n", label, value);
  };
  // "a / b" of two counts in a report.
  const auto pair = [](const Json& root, const char* a, const char* b) {
    return Fixed(Num(root, a), 0) + " / " + Fixed(Num(root, b), 0);
  };
  item("realtime (SCHED_FIFO)", Flag(serve_report, "realtime") ? "true" : "false");
  item("haptic ticks / overruns", pair(serve_report, "haptic.ticks", "haptic.overruns"));
  item("sim frames / overruns", pair(serve_report, "sim.frames", "sim.overruns"));
  item("pointer samples published / late", pair(replay_report, "published", "late"));
  item("pointer samples lost (server count)", Fixed(r.pointer_lost, 0));
  item("pointer samples answered / unanswered", pair(replay_report, "answered", "unanswered"));
  item("forces received / lost", pair(replay_report, "forces_received", "forces_lost"));
  item("contact ticks / peak force (N)", Fixed(Num(serve_report, "contacts"), 0) + " / " +
                                             Fixed(Num(serve_report, "peak_force_N"), 2));
  item("server RSS start / end / max (kB)", Fixed(static_cast<double>(w.rss_start_kb), 0) + " / " +
                                                Fixed(static_cast<double>(w.rss_end_kb), 0) +
                                                " / " +
                                                Fixed(static_cast<double>(w.rss_max_kb), 0));
  item("server CPU (% of one core)", Fixed(r.serve_cpu_s / r.window_s * 100.0, 1));
  item("replay CPU (% of one core)", Fixed(r.replay_cpu_s / r.window_s * 100.0, 1));
  md += "\n| check | value | limit | pass |\n|---|---|---|---|\n";
  for (const Check& c : r.checks) {
    md += fmt::format("| {} | {} | {} | {} |\n", c.name, Fixed(c.value, 0), Fixed(c.limit, 0),
                      c.pass ? "yes" : "**no**");
  }
  return md;
}

// The short summary on stdout.
void PrintSoakSummary(const SoakArgs& args, const SoakWatch& w, const SoakResult& r) {
  const Json& serve_report = r.serve_report;
  const Json& replay_report = r.replay_report;
  // "p50 1 p99 2 p99.9 3 max 4" of a percentile object in a report.
  const auto times = [](const Json& root, const std::string& path, int decimals, bool p999) {
    std::string out = "p50 " + Fixed(Num(root, path + ".p50"), decimals) + " p99 " +
                      Fixed(Num(root, path + ".p99"), decimals);
    if (p999) out += " p99.9 " + Fixed(Num(root, path + ".p999"), decimals);
    return out + " max " + Fixed(Num(root, path + ".max"), decimals);
  };
  std::printf("haptic loop   lateness us %s; %s ticks, %s overruns; realtime %s\n",
              times(serve_report, "haptic.lateness_us", 0, true).c_str(),
              Fixed(Num(serve_report, "haptic.ticks"), 0).c_str(),
              Fixed(Num(serve_report, "haptic.overruns"), 0).c_str(),
              Flag(serve_report, "realtime") ? "true" : "false");
  std::printf("sim loop      frame ms %s; %s frames\n",
              times(serve_report, "sim.frame_ms", 2, false).c_str(),
              Fixed(Num(serve_report, "sim.frames"), 0).c_str());
  std::printf("latency us    %s (pointer published -> force received)\n",
              times(replay_report, "latency_us", 0, true).c_str());
  std::printf("samples       %s published, %s late, %s lost; forces %s received, %s lost\n",
              Fixed(Num(replay_report, "published"), 0).c_str(),
              Fixed(Num(replay_report, "late"), 0).c_str(), Fixed(r.pointer_lost, 0).c_str(),
              Fixed(Num(replay_report, "forces_received"), 0).c_str(),
              Fixed(Num(replay_report, "forces_lost"), 0).c_str());
  std::printf("contacts      %s ticks in contact, peak force %s N\n",
              Fixed(Num(serve_report, "contacts"), 0).c_str(),
              Fixed(Num(serve_report, "peak_force_N"), 2).c_str());
  std::printf("server        RSS %s -> %s kB (growth %s kB), CPU %s%%; replay CPU %s%%\n",
              Fixed(static_cast<double>(w.rss_start_kb), 0).c_str(),
              Fixed(static_cast<double>(w.rss_end_kb), 0).c_str(),
              Fixed(r.rss_growth_kb, 0).c_str(),
              Fixed(r.serve_cpu_s / r.window_s * 100.0, 1).c_str(),
              Fixed(r.replay_cpu_s / r.window_s * 100.0, 1).c_str());
  // With --report-only a crossed threshold is information, not a failure (the `make run` demo).
  const char* crossed = args.report_only ? "over" : "FAIL";
  for (const Check& c : r.checks) {
    std::printf("check         %-4s %s = %s (limit %s)\n", c.pass ? "ok" : crossed, c.name.c_str(),
                Fixed(c.value, 0).c_str(), Fixed(c.limit, 0).c_str());
  }
  std::printf("felt soak: %s (load %s)\n",
              w.interrupted      ? "interrupted"
              : r.child_failed   ? "FAILED: a child process failed"
              : r.pass           ? "PASS"
              : args.report_only ? "over a threshold, reported only (--report-only: exit 0)"
                                 : "FAIL: a threshold was crossed",
              r.load_end.c_str());
  std::fflush(stdout);
}

// `--plot DIR`: the server's haptic and sim lateness histograms (their bins travel in the serve
// child's report) drawn into DIR/lateness.png (rt/histogram_plot.h).
void PlotSoak(const SoakArgs& args, const SoakResult& r) {
  std::vector<PlotSeries> series;
  for (const auto& [loop, label] :
       {std::pair<const char*, const char*>{"haptic", "haptic loop"}, {"sim", "sim loop"}}) {
    const Json* bins = nullptr;
    if (r.serve_report.is_object() && r.serve_report.contains(loop) &&
        r.serve_report[loop].contains("lateness_bins_us")) {
      bins = &r.serve_report[loop]["lateness_bins_us"];
    }
    if (bins == nullptr) continue;
    series.push_back(
        PlotSeries{label, PlotBinsFromJson(*bins, std::string(loop) + ".lateness_bins_us")});
  }
  if (series.empty()) {
    std::fprintf(stderr,
                 "felt soak: --plot: the server's report has no lateness bins (it did not "
                 "finish); nothing drawn\n");
    return;
  }
  WriteHistogramPlot(args.plot_dir, "lateness", series,
                     fmt::format("felt soak --minutes {} --scene {} --trace {}: wake-up lateness",
                                 args.minutes, args.scene, args.trace),
                     "lateness: wake-up minus deadline [us]");
}

int Soak(const SoakArgs& args) {
  // Set-up: options, the scene and the trace read and checked before anything starts.
  const SoakPlan plan = PlanSoak(args);
  // Signals: SIGINT/SIGTERM stop both children; no SA_RESTART, so poll() returns at once.
  InstallStopHandlers();
  SoakResult r;
  r.load_start = report::LoadAverage();
  std::printf("felt soak: %.1f s of %s into %s over DDS domain %u (device %s), load %s\n",
              plan.duration_s, args.trace.c_str(), args.scene.c_str(), plan.domain,
              plan.device_id.c_str(), r.load_start.c_str());
  std::fflush(stdout);

  // The two children, watched until both end.
  auto [serve, replay] = SpawnChildren(args, plan);
  const SoakWatch w = WatchChildren(args, plan, &serve, &replay);
  r.load_end = report::LoadAverage();
  r.child_failed = ReportChildFailures(w, serve, replay);

  // The children's reports (missing when a child failed early), the figures and the checks.
  if (std::filesystem::exists(plan.serve_json)) r.serve_report = ReadJsonFile(plan.serve_json);
  if (std::filesystem::exists(plan.replay_json)) r.replay_report = ReadJsonFile(plan.replay_json);
  if (args.keep_files) {
    std::printf("felt soak: the children's reports are in %s\n", plan.dir.c_str());
  } else {
    std::filesystem::remove_all(plan.dir);
  }
  Evaluate(args, w, replay, &r);

  // Files, then the summary.
  if (!args.json.empty()) {
    WriteOptionFile("--json", args.json, JsonText(SoakJson(args, plan, w, serve, replay, r)));
  }
  std::string md_path = args.md;
  if (md_path.empty() && !args.json.empty()) {
    md_path = std::filesystem::path(args.json).replace_extension(".md").string();
  }
  if (!md_path.empty()) WriteOptionFile("--md", md_path, SoakMarkdown(args, w, r));
  if (!args.plot_dir.empty()) {
    try {
      PlotSoak(args, r);
    } catch (const std::exception& e) {  // the reports above are written; say why, go on
      std::fprintf(stderr, "felt soak: --plot: %s\n", e.what());
    }
  }
  PrintSoakSummary(args, w, r);
  if (w.interrupted) return kExitInterrupted;
  if (r.child_failed) return 1;
  if (!r.pass && !args.report_only) return kExitThreshold;
  return 0;
}

CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<SoakArgs>();
  cmd.add_option("--minutes", args->minutes, "replay time in minutes (e.g. 10, or 0.5)")
      ->required();
  cmd.add_option("--scene", args->scene, "scene file (default scenes/curtain.toml)");
  cmd.add_option("--trace", args->trace, "trace to loop (default recordings/poke_hold.trace)");
  cmd.add_option("--json", args->json, "write the report as JSON here");
  cmd.add_option("--plot", args->plot_dir,
                 "draw the server's haptic and sim lateness histograms into DIR/lateness.png "
                 "(gnuplot)");
  cmd.add_option("--md", args->md, "write the markdown table here (default: the JSON path, .md)");
  cmd.add_option("--domain", args->domain, "DDS domain id (default 100 + pid % 100)")
      ->check(CLI::Range(0, 230));
  cmd.add_option("--view", args->view_port,
                 "the server also serves the live 3-D view on this port (docs/view.md)");
  cmd.add_option("--security", args->security,
                 "DDS Security directory of `felt security init` for the server and the replay "
                 "(identities server and device-<the scene's device>)");
  cmd.add_flag("--no-realtime", args->no_realtime, "run the server without real-time settings");
  cmd.add_flag("--verbose", args->verbose, "echo the children's output");
  cmd.add_flag("--keep-files", args->keep_files, "keep the children's JSON files (path printed)");
  cmd.add_flag("--report-only", args->report_only,
               "exit 0 when a threshold is crossed (still reported)");
  // The thresholds: each a non-negative limit with its default in the help.
  const struct {
    const char* flag;
    double* limit;
    const char* help;
  } thresholds[] = {
      {"--max-dropped", &args->max_dropped, "threshold: dropped samples (default 0)"},
      {"--max-rss-growth-kb", &args->max_rss_growth_kb,
       "threshold: server RSS growth, kB (default 1024)"},
      {"--max-lateness-p99-us", &args->max_lateness_p99_us,
       "threshold: haptic lateness p99, us (default 100)"},
      {"--max-lateness-p999-us", &args->max_lateness_p999_us,
       "threshold: haptic lateness p99.9, us (default 500)"},
  };
  for (const auto& t : thresholds) {
    cmd.add_option(t.flag, *t.limit, t.help)->check(CLI::NonNegativeNumber);
  }
  cmd.add_option("--discovery-timeout", args->discovery_timeout_s,
                 "seconds the replay waits for the server (default 20)")
      ->check(CLI::PositiveNumber);
  return [args]() -> int { return Soak(*args); };
}

const bool kRegistered = RegisterCommand(
    {"", "soak",
     "run the server and a replay as two processes over loopback DDS; report timing, latency, "
     "drops, memory, CPU; fail on thresholds",
     Setup});

}  // namespace
}  // namespace felt::app::cmd_soak
