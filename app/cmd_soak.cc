// `felt soak --minutes M [--scene FILE] [--trace FILE] [--json FILE] [--md FILE] [thresholds]`:
// runs the server (`felt serve`) and a replay (`felt replay`) as two child processes of this
// binary over loopback DDS, then reports the server's loop timing (from serve's --stats-json),
// the end-to-end latency and drops (from replay's --json), the server's resident memory at the
// start and end of the replay (/proc/PID/status VmRSS) and the CPU of both (/proc/PID/stat), as
// JSON and a markdown table. Exits 3 when a threshold is crossed (defaults: issue 7's target).
// SIGINT/SIGTERM stop both children cleanly; children also get SIGTERM should this process die
// (PR_SET_PDEATHSIG), so none is left behind (docs/replay.md).
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
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
#include "base/json_writer.h"
#include "recordings/trace.h"
#include "scene/scene_file.h"
#include "server/server_spec.h"
#include "transport/clock.h"

namespace felt::app::cmd_soak {
namespace {

// Set by the signal handler; lock-free, so async-signal-safe.
std::atomic<bool> g_soak_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free);

extern "C" void OnSoakStopSignal(int /*signal*/) { g_soak_stop.store(true); }

constexpr int kExitThreshold = 3;              // a threshold was crossed
constexpr int kExitInterrupted = 130;          // SIGINT/SIGTERM (128 + SIGINT, the shell's habit)
constexpr int64_t kStopGraceNs = 10000000000;  // SIGINT, then SIGKILL after 10 s
constexpr size_t kTailLines = 40;              // output lines kept per child for error reports

// ---- A small JSON reader (for serve's and replay's own JSON files) ----

// A parsed JSON value: null, boolean, number, string, object (members in order) or array.
struct JsonValue {
  enum class Kind { kNull, kBool, kNumber, kString, kObject, kArray };
  Kind kind = Kind::kNull;
  bool boolean = false;
  double number = 0.0;
  std::string text;
  std::vector<std::pair<std::string, JsonValue>> members;
  std::vector<JsonValue> items;

  // The value at a dotted path ("haptic.lateness_us.p99"), or null when absent.
  const JsonValue* Find(std::string_view path) const {
    const JsonValue* v = this;
    while (!path.empty()) {
      const size_t dot = path.find('.');
      const std::string_view key = path.substr(0, dot);
      if (v->kind != Kind::kObject) return nullptr;
      const JsonValue* next = nullptr;
      for (const auto& [k, child] : v->members) {
        if (k == key) next = &child;
      }
      if (next == nullptr) return nullptr;
      v = next;
      path = dot == std::string_view::npos ? std::string_view() : path.substr(dot + 1);
    }
    return v;
  }
};

// Recursive-descent parser of RFC 8259 JSON; errors name the file and the byte offset.
class JsonReader {
 public:
  JsonReader(std::string text, std::string file) : text_(std::move(text)), file_(std::move(file)) {}

  JsonValue Parse() {
    JsonValue v = Value();
    Skip();
    if (pos_ != text_.size()) Fail("trailing characters after the document");
    return v;
  }

 private:
  [[noreturn]] void Fail(const std::string& what) const {
    throw std::runtime_error(file_ + ": JSON: byte " + std::to_string(pos_) + ": " + what);
  }
  void Skip() {
    while (pos_ < text_.size() && std::strchr(" \t\r\n", text_[pos_]) != nullptr) ++pos_;
  }
  bool Eat(char c) {
    Skip();
    if (pos_ < text_.size() && text_[pos_] == c) {
      ++pos_;
      return true;
    }
    return false;
  }
  void Expect(char c) {
    if (!Eat(c)) Fail(std::string("expected '") + c + "'");
  }
  bool Word(std::string_view word) {
    if (text_.compare(pos_, word.size(), word) != 0) return false;
    pos_ += word.size();
    return true;
  }
  std::string String() {
    Expect('"');
    std::string out;
    while (pos_ < text_.size() && text_[pos_] != '"') {
      char c = text_[pos_++];
      if (c == '\\') {
        if (pos_ >= text_.size()) Fail("unterminated escape");
        c = text_[pos_++];
        switch (c) {
          case 'n':
            c = '\n';
            break;
          case 't':
            c = '\t';
            break;
          case 'r':
            c = '\r';
            break;
          case 'b':
            c = '\b';
            break;
          case 'f':
            c = '\f';
            break;
          case 'u': {
            // Only what JsonWriter emits: \u00XX control characters.
            if (pos_ + 4 > text_.size()) Fail("short \\u escape");
            unsigned code = 0;
            const auto [end, ec] =
                std::from_chars(text_.data() + pos_, text_.data() + pos_ + 4, code, 16);
            if (ec != std::errc() || end != text_.data() + pos_ + 4 || code > 0x7f) {
              Fail("unsupported \\u escape");
            }
            pos_ += 4;
            c = static_cast<char>(code);
            break;
          }
          default:
            break;  // '"', '\\', '/'
        }
      }
      out += c;
    }
    if (pos_ >= text_.size()) Fail("unterminated string");
    ++pos_;
    return out;
  }
  JsonValue Value() {
    Skip();
    if (pos_ >= text_.size()) Fail("unexpected end of the document");
    JsonValue v;
    const char c = text_[pos_];
    if (c == '{') {
      ++pos_;
      v.kind = JsonValue::Kind::kObject;
      if (Eat('}')) return v;
      do {
        Skip();
        std::string key = String();
        Expect(':');
        v.members.emplace_back(std::move(key), Value());
      } while (Eat(','));
      Expect('}');
    } else if (c == '[') {
      ++pos_;
      v.kind = JsonValue::Kind::kArray;
      if (Eat(']')) return v;
      do {
        v.items.push_back(Value());
      } while (Eat(','));
      Expect(']');
    } else if (c == '"') {
      v.kind = JsonValue::Kind::kString;
      v.text = String();
    } else if (Word("true")) {
      v.kind = JsonValue::Kind::kBool;
      v.boolean = true;
    } else if (Word("false")) {
      v.kind = JsonValue::Kind::kBool;
    } else if (Word("null")) {
      v.kind = JsonValue::Kind::kNull;
    } else {
      v.kind = JsonValue::Kind::kNumber;
      const auto [end, ec] =
          std::from_chars(text_.data() + pos_, text_.data() + text_.size(), v.number);
      if (ec != std::errc()) Fail("expected a value");
      pos_ = static_cast<size_t>(end - text_.data());
    }
    return v;
  }

  std::string text_;
  std::string file_;
  size_t pos_ = 0;
};

// Reads and parses a JSON file; throws std::runtime_error naming the file.
JsonValue ReadJsonFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot read: " + std::strerror(errno));
  std::stringstream text;
  text << in.rdbuf();
  return JsonReader(text.str(), path).Parse();
}

// Copies object `v` member by member into `json` under `key` (arrays are not written: serve's and
// replay's JSON have none).
void CopyObject(JsonWriter& json, std::string_view key, const JsonValue& v) {
  json.BeginObject(key);
  for (const auto& [k, child] : v.members) {
    switch (child.kind) {
      case JsonValue::Kind::kObject:
        CopyObject(json, k, child);
        break;
      case JsonValue::Kind::kNumber:
        json.Number(k, child.number);
        break;
      case JsonValue::Kind::kBool:
        json.Bool(k, child.boolean);
        break;
      case JsonValue::Kind::kString:
        json.String(k, child.text);
        break;
      case JsonValue::Kind::kNull:
        json.Number(k, std::nan(""));
        break;  // written as null
      case JsonValue::Kind::kArray:
        break;
    }
  }
  json.EndObject();
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

// The three load averages of /proc/loadavg as text ("1.02 0.98 0.75").
std::string LoadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string one, five, fifteen;
  in >> one >> five >> fifteen;
  return one + " " + five + " " + fifteen;
}

// ---- Child processes ----

// One child: `felt <args>` with stdout and stderr into a pipe that this process reads.
struct Child {
  std::string name;
  pid_t pid = -1;
  int out_fd = -1;
  bool running = false;
  int exit_code = -1;   // when it exited normally
  int term_signal = 0;  // when a signal ended it
  rusage usage{};
  int64_t stop_sent_ns = 0;  // when SIGINT was sent (0 = not yet)
  std::string partial;       // the unfinished last line
  std::deque<std::string> tail;
  bool echo = false;

  // Reads what is available, line by line; calls on_line for each complete line.
  template <typename OnLine>
  void Drain(OnLine&& on_line) {
    char buffer[4096];
    while (out_fd >= 0) {
      const ssize_t n = read(out_fd, buffer, sizeof(buffer));
      if (n < 0) return;  // EAGAIN: nothing now
      if (n == 0) {
        // End of file: the child has closed its output; poll() skips a negative fd.
        close(out_fd);
        out_fd = -1;
        if (!partial.empty()) partial += '\n';
      }
      partial.append(buffer, static_cast<size_t>(std::max<ssize_t>(n, 0)));
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
  }

  // Reaps the child when it has exited (never blocks); true when it is (now) gone.
  bool Reap() {
    if (!running) return true;
    int status = 0;
    const pid_t r = wait4(pid, &status, WNOHANG, &usage);
    if (r != pid) return false;
    running = false;
    if (WIFEXITED(status)) exit_code = WEXITSTATUS(status);
    if (WIFSIGNALED(status)) term_signal = WTERMSIG(status);
    return true;
  }

  // Asks the child to stop (SIGINT: serve and replay stop cleanly and write their reports).
  void RequestStop() {
    if (running && stop_sent_ns == 0) {
      kill(pid, SIGINT);
      stop_sent_ns = transport::MonotonicNowNs();
    }
  }

  // What ended it, for messages.
  std::string Outcome() const {
    if (running) return "still running";
    if (term_signal != 0) return std::string("killed by signal ") + strsignal(term_signal);
    return "exit code " + std::to_string(exit_code);
  }
};

// Starts `exe args...` with its output into a pipe; it gets SIGTERM when this process dies.
Child Spawn(const std::string& name, const std::string& exe, const std::vector<std::string>& args,
            bool echo) {
  // Everything the child needs is prepared before fork: after it, only async-signal-safe calls.
  std::vector<std::string> all;
  all.push_back(exe);
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  int fds[2];
  if (pipe2(fds, O_CLOEXEC) != 0) {
    throw std::runtime_error("soak: pipe2 failed: " + std::string(std::strerror(errno)));
  }
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) {
    close(fds[0]);
    close(fds[1]);
    throw std::runtime_error("soak: fork failed: " + std::string(std::strerror(errno)));
  }
  if (pid == 0) {
    // The child: die with the parent (and check it has not died already), output to the pipe.
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(126);
    dup2(fds[1], STDOUT_FILENO);
    dup2(fds[1], STDERR_FILENO);
    execv(exe.c_str(), argv.data());
    constexpr char kMessage[] = "felt soak: execv failed\n";
    (void)!write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
    _exit(127);
  }
  close(fds[1]);
  fcntl(fds[0], F_SETFL, fcntl(fds[0], F_GETFL) | O_NONBLOCK);
  Child child;
  child.name = name;
  child.pid = pid;
  child.out_fd = fds[0];
  child.running = true;
  child.echo = echo;
  return child;
}

// Kills and reaps whatever child is still running when it goes out of scope (an exception
// path): no orphan is ever left behind.
struct ChildGuard {
  std::vector<Child*> children;
  ~ChildGuard() {
    for (Child* c : children) {
      if (c->running) {
        kill(c->pid, SIGKILL);
        waitpid(c->pid, nullptr, 0);
        c->running = false;
      }
      if (c->out_fd >= 0) close(c->out_fd);
      c->out_fd = -1;
    }
  }
};

// ---- The soak ----

struct SoakArgs {
  double minutes = 0.0;
  std::string scene = "scenes/curtain.toml";
  std::string trace = "recordings/poke_hold.trace";
  std::string json;
  std::string md;
  std::optional<uint32_t> domain;
  bool no_realtime = false;
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

double Num(const JsonValue& root, std::string_view path) {
  const JsonValue* v = root.Find(path);
  return v != nullptr && v->kind == JsonValue::Kind::kNumber ? v->number : std::nan("");
}

int Soak(const SoakArgs& args) {
  // Set-up: options, then the scene and the trace are read and checked before anything starts.
  if (!(args.minutes > 0.0 && args.minutes <= 1440.0)) {
    throw std::invalid_argument(
        fmt::format("--minutes must be in (0, 1440], got {}", args.minutes));
  }
  const ServerSpec spec = ParseServerSpec(LoadSceneDocument(args.scene));
  if (spec.devices.empty()) throw std::invalid_argument(args.scene + ": the scene has no device");
  const std::string device_id = spec.devices.front().id;
  const Trace trace = ReadTrace(args.trace);
  const double duration_s = args.minutes * 60.0;
  const uint32_t domain = args.domain.value_or(100 + static_cast<uint32_t>(getpid() % 100));

  // A private directory for the children's reports.
  std::string dir_template = (std::filesystem::temp_directory_path() / "felt-soak-XXXXXX").string();
  if (mkdtemp(dir_template.data()) == nullptr) {
    throw std::runtime_error("soak: cannot create a temporary directory: " +
                             std::string(std::strerror(errno)));
  }
  const std::string dir = dir_template;
  const std::string serve_json = dir + "/serve.json";
  const std::string replay_json = dir + "/replay.json";
  char exe_buffer[4096];
  const ssize_t exe_length = readlink("/proc/self/exe", exe_buffer, sizeof(exe_buffer) - 1);
  if (exe_length <= 0) throw std::runtime_error("soak: cannot read /proc/self/exe");
  const std::string exe(exe_buffer, static_cast<size_t>(exe_length));

  // Signals: SIGINT/SIGTERM stop both children; no SA_RESTART, so poll() returns at once.
  struct sigaction action {};
  action.sa_handler = OnSoakStopSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);

  const std::string load_start = LoadAverage();
  std::printf("felt soak: %.1f s of %s into %s over DDS domain %u (device %s), load %s\n",
              duration_s, args.trace.c_str(), args.scene.c_str(), domain, device_id.c_str(),
              load_start.c_str());
  std::fflush(stdout);

  // The two children.
  std::vector<std::string> serve_args = {
      "serve",        "--scene", args.scene, "--domain", std::to_string(domain),
      "--stats-json", serve_json};
  if (args.no_realtime) serve_args.push_back("--no-realtime");
  const std::vector<std::string> replay_args = {"replay",
                                                args.trace,
                                                "--domain",
                                                std::to_string(domain),
                                                "--device",
                                                device_id,
                                                "--duration",
                                                fmt::format("{}", duration_s),
                                                "--json",
                                                replay_json,
                                                "--discovery-timeout",
                                                fmt::format("{}", args.discovery_timeout_s)};
  Child serve, replay;
  ChildGuard guard{{&serve, &replay}};  // destroyed first: kills what still runs on an exception
  serve = Spawn("serve", exe, serve_args, args.verbose);
  replay = Spawn("replay", exe, replay_args, args.verbose);

  // Watch: output, the start of publication, RSS once a second, the ends.
  const int64_t start_ns = transport::MonotonicNowNs();
  const int64_t limit_ns =
      start_ns + static_cast<int64_t>((duration_s + args.discovery_timeout_s + 60.0) * 1e9);
  int64_t publishing_ns = 0, replay_end_ns = 0, next_rss_ns = 0;
  int64_t rss_start_kb = -1, rss_end_kb = -1, rss_max_kb = -1;
  double serve_cpu_start_s = -1, serve_cpu_end_s = -1, replay_cpu_start_s = -1;
  bool interrupted = false, timed_out = false, serve_died = false;
  const auto on_replay_line = [&](const std::string& line) {
    if (publishing_ns == 0 && line.find("felt replay: publishing") != std::string::npos) {
      // The replay starts now: the server's memory and CPU at the start.
      publishing_ns = transport::MonotonicNowNs();
      rss_start_kb = rss_max_kb = ReadRssKb(serve.pid);
      serve_cpu_start_s = ReadCpuS(serve.pid);
      replay_cpu_start_s = ReadCpuS(replay.pid);
      next_rss_ns = publishing_ns + 1000000000;
    }
  };
  while (serve.running || replay.running) {
    pollfd fds[2] = {{serve.out_fd, POLLIN, 0}, {replay.out_fd, POLLIN, 0}};
    (void)poll(fds, 2, 100);
    serve.Drain([](const std::string&) {});
    replay.Drain(on_replay_line);
    const int64_t now_ns = transport::MonotonicNowNs();
    if (publishing_ns != 0 && replay_end_ns == 0 && now_ns >= next_rss_ns) {
      rss_max_kb = std::max(rss_max_kb, ReadRssKb(serve.pid));
      next_rss_ns += 1000000000;
    }
    // The replay's end: the server's memory and CPU at the end, then the server is stopped.
    if (replay.running && replay.Reap()) {
      replay.Drain(on_replay_line);
    }
    if (!replay.running && replay_end_ns == 0) {
      replay_end_ns = now_ns;
      if (serve.running) {
        rss_end_kb = ReadRssKb(serve.pid);
        rss_max_kb = std::max(rss_max_kb, rss_end_kb);
        serve_cpu_end_s = ReadCpuS(serve.pid);
      }
      serve.RequestStop();
    }
    if (serve.running && serve.Reap()) {
      serve.Drain([](const std::string&) {});
      if (replay.running) {
        serve_died = true;
        replay.RequestStop();
      }
    }
    // A signal, or the overall limit: stop both.
    // A signal stops the replay first; its end then stops the server as usual (so the memory at
    // the end and the server's counts are still taken).
    if (g_soak_stop.load() && !interrupted) {
      interrupted = true;
      replay.RequestStop();
    }
    if (now_ns > limit_ns && !timed_out) {
      timed_out = true;
      serve.RequestStop();
      replay.RequestStop();
    }
    // A child that does not stop within the grace time is killed.
    for (Child* c : {&serve, &replay}) {
      if (c->running && c->stop_sent_ns != 0 && now_ns - c->stop_sent_ns > kStopGraceNs) {
        kill(c->pid, SIGKILL);
      }
    }
  }
  const std::string load_end = LoadAverage();
  const double window_s = publishing_ns != 0 && replay_end_ns != 0
                              ? static_cast<double>(replay_end_ns - publishing_ns) / 1e9
                              : std::nan("");

  // The children's failures: their last output.
  const auto failed = [](const Child& c) {
    return c.term_signal != 0 || (c.exit_code != 0 && c.exit_code != -1);
  };
  // After SIGINT/SIGTERM, a child that ended on the SIGINT passed on (even before its handler was
  // installed) or gave up early is expected, not a failure.
  const bool child_failed =
      !interrupted && (failed(serve) || failed(replay) || serve_died || timed_out);
  if (child_failed) {
    for (const Child* c : {&serve, &replay}) {
      std::fprintf(stderr, "felt soak: %s: %s; its last output:\n", c->name.c_str(),
                   c->Outcome().c_str());
      for (const std::string& line : c->tail) std::fprintf(stderr, "  | %s\n", line.c_str());
    }
    if (serve_died) std::fprintf(stderr, "felt soak: the server ended before the replay\n");
    if (timed_out) std::fprintf(stderr, "felt soak: the run passed its time limit\n");
  }

  // The children's reports (missing when a child failed early).
  JsonValue serve_report, replay_report;
  bool have_serve = false, have_replay = false;
  if (std::filesystem::exists(serve_json)) {
    serve_report = ReadJsonFile(serve_json);
    have_serve = true;
  }
  if (std::filesystem::exists(replay_json)) {
    replay_report = ReadJsonFile(replay_json);
    have_replay = true;
  }
  if (args.keep_files) {
    std::printf("felt soak: the children's reports are in %s\n", dir.c_str());
  } else {
    std::filesystem::remove_all(dir);
  }

  // Derived figures.
  const double serve_cpu_s = serve_cpu_start_s >= 0 && serve_cpu_end_s >= 0
                                 ? serve_cpu_end_s - serve_cpu_start_s
                                 : std::nan("");
  const double replay_total_cpu_s =
      static_cast<double>(replay.usage.ru_utime.tv_sec + replay.usage.ru_stime.tv_sec) +
      static_cast<double>(replay.usage.ru_utime.tv_usec + replay.usage.ru_stime.tv_usec) / 1e6;
  const double replay_cpu_s =
      replay_cpu_start_s >= 0 ? replay_total_cpu_s - replay_cpu_start_s : std::nan("");
  const double rss_growth_kb = rss_start_kb >= 0 && rss_end_kb >= 0
                                   ? static_cast<double>(rss_end_kb - rss_start_kb)
                                   : std::nan("");
  // Pointer samples lost: known only when the replay saw the server's status before and after.
  const JsonValue* server_counts = replay_report.Find("server_counts");
  const double pointer_lost = server_counts != nullptr && server_counts->boolean
                                  ? Num(replay_report, "pointer_lost")
                                  : std::nan("");
  const double dropped =
      pointer_lost + Num(replay_report, "forces_lost") + Num(replay_report, "publish_failures");

  // The checks (a value that is unknown fails).
  std::vector<Check> checks = {
      {"dropped samples (pointer lost + forces lost + publish failures)", dropped,
       args.max_dropped},
      {"server RSS growth kB", rss_growth_kb, args.max_rss_growth_kb},
      {"haptic lateness p99 us", Num(serve_report, "haptic.lateness_us.p99"),
       args.max_lateness_p99_us},
      {"haptic lateness p99.9 us", Num(serve_report, "haptic.lateness_us.p999"),
       args.max_lateness_p999_us},
  };
  bool pass = true;
  for (Check& c : checks) {
    c.pass = std::isfinite(c.value) && c.value <= c.limit;
    pass = pass && c.pass;
  }

  // JSON.
  JsonWriter json;
  json.BeginObject();
  json.String("command", fmt::format("felt soak --minutes {} --scene {} --trace {}", args.minutes,
                                     args.scene, args.trace));
  json.Number("minutes", args.minutes);
  json.String("scene", args.scene);
  json.String("trace", args.trace);
  json.String("device_id", device_id);
  json.Unsigned("domain", domain);
  json.String("load_average_start", load_start);
  json.String("load_average_end", load_end);
  json.Number("window_s", window_s);
  json.Bool("interrupted", interrupted);
  json.Bool("children_ok", !child_failed);
  json.BeginObject("server");
  json.Integer("exit_code", serve.exit_code);
  json.Integer("rss_start_kB", rss_start_kb);
  json.Integer("rss_end_kB", rss_end_kb);
  json.Integer("rss_max_kB", rss_max_kb);
  json.Number("rss_growth_kB", rss_growth_kb);
  json.Number("cpu_s", serve_cpu_s);
  json.Number("cpu_percent", serve_cpu_s / window_s * 100.0);
  if (have_serve) CopyObject(json, "stats", serve_report);
  json.EndObject();
  json.BeginObject("replay");
  json.Integer("exit_code", replay.exit_code);
  json.Number("cpu_s", replay_cpu_s);
  json.Number("cpu_percent", replay_cpu_s / window_s * 100.0);
  if (have_replay) CopyObject(json, "report", replay_report);
  json.EndObject();
  json.BeginObject("thresholds");
  json.Number("max_dropped", args.max_dropped);
  json.Number("max_rss_growth_kB", args.max_rss_growth_kb);
  json.Number("max_haptic_lateness_p99_us", args.max_lateness_p99_us);
  json.Number("max_haptic_lateness_p999_us", args.max_lateness_p999_us);
  json.EndObject();
  json.BeginObject("checks");
  for (const Check& c : checks) {
    json.BeginObject(c.name);
    json.Number("value", c.value);
    json.Number("limit", c.limit);
    json.Bool("pass", c.pass);
    json.EndObject();
  }
  json.EndObject();
  json.Bool("pass", pass && !child_failed);
  json.EndObject();

  // Markdown.
  std::string md = "# felt soak\n\n";
  md += fmt::format("Command: `felt soak --minutes {} --scene {} --trace {}{}`  \n", args.minutes,
                    args.scene, args.trace, args.no_realtime ? " --no-realtime" : "");
  md += fmt::format("Load average (1, 5, 15 min): start {}, end {}. Replay window {} s.\n\n",
                    load_start, load_end, Fixed(window_s, 1));
  md += "| quantity | p50 | p99 | p99.9 | max |\n|---|---|---|---|---|\n";
  const auto row = [&](const std::string& label, const JsonValue& root, const std::string& path,
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
  item("realtime (SCHED_FIFO)",
       serve_report.Find("realtime") != nullptr && serve_report.Find("realtime")->boolean
           ? "true"
           : "false");
  item("haptic ticks / overruns", Fixed(Num(serve_report, "haptic.ticks"), 0) + " / " +
                                      Fixed(Num(serve_report, "haptic.overruns"), 0));
  item("sim frames / overruns", Fixed(Num(serve_report, "sim.frames"), 0) + " / " +
                                    Fixed(Num(serve_report, "sim.overruns"), 0));
  item("pointer samples published / late",
       Fixed(Num(replay_report, "published"), 0) + " / " + Fixed(Num(replay_report, "late"), 0));
  item("pointer samples lost (server count)", Fixed(pointer_lost, 0));
  item("pointer samples answered / unanswered", Fixed(Num(replay_report, "answered"), 0) + " / " +
                                                    Fixed(Num(replay_report, "unanswered"), 0));
  item("forces received / lost", Fixed(Num(replay_report, "forces_received"), 0) + " / " +
                                     Fixed(Num(replay_report, "forces_lost"), 0));
  item("contact ticks / peak force (N)", Fixed(Num(serve_report, "contacts"), 0) + " / " +
                                             Fixed(Num(serve_report, "peak_force_N"), 2));
  item("server RSS start / end / max (kB)", Fixed(static_cast<double>(rss_start_kb), 0) + " / " +
                                                Fixed(static_cast<double>(rss_end_kb), 0) + " / " +
                                                Fixed(static_cast<double>(rss_max_kb), 0));
  item("server CPU (% of one core)", Fixed(serve_cpu_s / window_s * 100.0, 1));
  item("replay CPU (% of one core)", Fixed(replay_cpu_s / window_s * 100.0, 1));
  md += "\n| check | value | limit | pass |\n|---|---|---|---|\n";
  for (const Check& c : checks) {
    md += fmt::format("| {} | {} | {} | {} |\n", c.name, Fixed(c.value, 0), Fixed(c.limit, 0),
                      c.pass ? "yes" : "**no**");
  }

  // Files.
  if (!args.json.empty()) {
    std::ofstream out(args.json);
    out << json.str();
    if (!out) throw std::runtime_error("cannot write --json file '" + args.json + "'");
  }
  std::string md_path = args.md;
  if (md_path.empty() && !args.json.empty()) {
    md_path = std::filesystem::path(args.json).replace_extension(".md").string();
  }
  if (!md_path.empty()) {
    std::ofstream out(md_path);
    out << md;
    if (!out) throw std::runtime_error("cannot write --md file '" + md_path + "'");
  }

  // The short summary.
  std::printf(
      "haptic loop   lateness us p50 %s p99 %s p99.9 %s max %s; %s ticks, %s overruns; "
      "realtime %s\n",
      Fixed(Num(serve_report, "haptic.lateness_us.p50"), 0).c_str(),
      Fixed(Num(serve_report, "haptic.lateness_us.p99"), 0).c_str(),
      Fixed(Num(serve_report, "haptic.lateness_us.p999"), 0).c_str(),
      Fixed(Num(serve_report, "haptic.lateness_us.max"), 0).c_str(),
      Fixed(Num(serve_report, "haptic.ticks"), 0).c_str(),
      Fixed(Num(serve_report, "haptic.overruns"), 0).c_str(),
      serve_report.Find("realtime") != nullptr && serve_report.Find("realtime")->boolean ? "true"
                                                                                         : "false");
  std::printf("sim loop      frame ms p50 %s p99 %s max %s; %s frames\n",
              Fixed(Num(serve_report, "sim.frame_ms.p50"), 2).c_str(),
              Fixed(Num(serve_report, "sim.frame_ms.p99"), 2).c_str(),
              Fixed(Num(serve_report, "sim.frame_ms.max"), 2).c_str(),
              Fixed(Num(serve_report, "sim.frames"), 0).c_str());
  std::printf("latency us    p50 %s p99 %s p99.9 %s max %s (pointer published -> force received)\n",
              Fixed(Num(replay_report, "latency_us.p50"), 0).c_str(),
              Fixed(Num(replay_report, "latency_us.p99"), 0).c_str(),
              Fixed(Num(replay_report, "latency_us.p999"), 0).c_str(),
              Fixed(Num(replay_report, "latency_us.max"), 0).c_str());
  std::printf("samples       %s published, %s late, %s lost; forces %s received, %s lost\n",
              Fixed(Num(replay_report, "published"), 0).c_str(),
              Fixed(Num(replay_report, "late"), 0).c_str(), Fixed(pointer_lost, 0).c_str(),
              Fixed(Num(replay_report, "forces_received"), 0).c_str(),
              Fixed(Num(replay_report, "forces_lost"), 0).c_str());
  std::printf("contacts      %s ticks in contact, peak force %s N\n",
              Fixed(Num(serve_report, "contacts"), 0).c_str(),
              Fixed(Num(serve_report, "peak_force_N"), 2).c_str());
  std::printf("server        RSS %s -> %s kB (growth %s kB), CPU %s%%; replay CPU %s%%\n",
              Fixed(static_cast<double>(rss_start_kb), 0).c_str(),
              Fixed(static_cast<double>(rss_end_kb), 0).c_str(), Fixed(rss_growth_kb, 0).c_str(),
              Fixed(serve_cpu_s / window_s * 100.0, 1).c_str(),
              Fixed(replay_cpu_s / window_s * 100.0, 1).c_str());
  // With --report-only a crossed threshold is information, not a failure (the `make run` demo).
  const char* crossed = args.report_only ? "over" : "FAIL";
  for (const Check& c : checks) {
    std::printf("check         %-4s %s = %s (limit %s)\n", c.pass ? "ok" : crossed, c.name.c_str(),
                Fixed(c.value, 0).c_str(), Fixed(c.limit, 0).c_str());
  }
  std::printf("felt soak: %s (load %s)\n",
              interrupted        ? "interrupted"
              : child_failed     ? "FAILED: a child process failed"
              : pass             ? "PASS"
              : args.report_only ? "over a threshold, reported only (--report-only: exit 0)"
                                 : "FAIL: a threshold was crossed",
              load_end.c_str());
  std::fflush(stdout);
  if (interrupted) return kExitInterrupted;
  if (child_failed) return 1;
  if (!pass && !args.report_only) return kExitThreshold;
  return 0;
}

CommandRun Setup(CLI::App& cmd) {
  auto args = std::make_shared<SoakArgs>();
  cmd.add_option("--minutes", args->minutes, "replay time in minutes (e.g. 10, or 0.5)")
      ->required();
  cmd.add_option("--scene", args->scene, "scene file (default scenes/curtain.toml)");
  cmd.add_option("--trace", args->trace, "trace to loop (default recordings/poke_hold.trace)");
  cmd.add_option("--json", args->json, "write the report as JSON here");
  cmd.add_option("--md", args->md, "write the markdown table here (default: the JSON path, .md)");
  cmd.add_option("--domain", args->domain, "DDS domain id (default 100 + pid % 100)")
      ->check(CLI::Range(0, 230));
  cmd.add_flag("--no-realtime", args->no_realtime, "run the server without real-time settings");
  cmd.add_flag("--verbose", args->verbose, "echo the children's output");
  cmd.add_flag("--keep-files", args->keep_files, "keep the children's JSON files (path printed)");
  cmd.add_flag("--report-only", args->report_only,
               "exit 0 when a threshold is crossed (still reported)");
  cmd.add_option("--max-dropped", args->max_dropped, "threshold: dropped samples (default 0)")
      ->check(CLI::NonNegativeNumber);
  cmd.add_option("--max-rss-growth-kb", args->max_rss_growth_kb,
                 "threshold: server RSS growth, kB (default 1024)")
      ->check(CLI::NonNegativeNumber);
  cmd.add_option("--max-lateness-p99-us", args->max_lateness_p99_us,
                 "threshold: haptic lateness p99, us (default 100)")
      ->check(CLI::NonNegativeNumber);
  cmd.add_option("--max-lateness-p999-us", args->max_lateness_p999_us,
                 "threshold: haptic lateness p99.9, us (default 500)")
      ->check(CLI::NonNegativeNumber);
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
