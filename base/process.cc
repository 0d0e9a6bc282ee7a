#include "base/process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <thread>
#include <utility>

extern char** environ;

namespace felt {
namespace {

[[noreturn]] void Fail(const std::string& what) {
  throw std::runtime_error("spawn: " + what + ": " + std::strerror(errno));
}

// In the child, between fork and exec or _exit: async-signal-safe calls only.
void SetUpChild(pid_t parent, bool die_with_parent, int out_fd) {
  if (die_with_parent) {
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent) _exit(126);  // the parent died before prctl
  }
  if (out_fd >= 0) {
    dup2(out_fd, STDOUT_FILENO);
    dup2(out_fd, STDERR_FILENO);
  }
}

}  // namespace

Process Process::Spawn(const std::vector<std::string>& argv, const SpawnOptions& options) {
  if (argv.empty()) throw std::invalid_argument("spawn: an empty argv");
  return Start(&argv, nullptr, options);
}

Process Process::Fork(const std::function<int()>& child, const SpawnOptions& options) {
  return Start(nullptr, &child, options);
}

Process Process::Start(const std::vector<std::string>* argv, const std::function<int()>* child,
                       const SpawnOptions& options) {
  // Everything exec needs is built before fork: after it, only async-signal-safe calls.
  std::vector<std::string> args = argv != nullptr ? *argv : std::vector<std::string>();
  std::vector<char*> arg_ptrs;
  for (std::string& a : args) arg_ptrs.push_back(a.data());
  arg_ptrs.push_back(nullptr);
  std::vector<std::string> env_text;
  for (char** e = environ; *e != nullptr; ++e) {
    // An inherited variable that options.env sets is replaced, not shadowed.
    const std::string entry(*e);
    const std::string name = entry.substr(0, entry.find('=') + 1);
    bool replaced = false;
    for (const std::string& set : options.env) replaced = replaced || set.rfind(name, 0) == 0;
    if (!replaced) env_text.push_back(entry);
  }
  env_text.insert(env_text.end(), options.env.begin(), options.env.end());
  std::vector<char*> env_ptrs;
  for (std::string& e : env_text) env_ptrs.push_back(e.data());
  env_ptrs.push_back(nullptr);

  int child_out = -1, parent_out = -1;
  if (options.output == SpawnOptions::Output::kFile) {
    child_out = open(options.output_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (child_out < 0) Fail("cannot open " + options.output_file);
  } else if (options.output == SpawnOptions::Output::kPipe) {
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) Fail("pipe2");
    parent_out = fds[0];
    child_out = fds[1];
  }
  std::fflush(nullptr);  // a forked child must not write this process's buffered output again
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) {
    if (child_out >= 0) close(child_out);
    if (parent_out >= 0) close(parent_out);
    Fail("fork");
  }
  if (pid == 0) {
    SetUpChild(parent, options.die_with_parent, child_out);
    if (child == nullptr) {
      execve(arg_ptrs[0], arg_ptrs.data(), env_ptrs.data());
      constexpr char kMessage[] = "spawn: execve failed\n";
      (void)!write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
      _exit(127);
    }
    int code = 1;
    try {
      code = (*child)();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "forked child: %s\n", e.what());
    }
    std::fflush(nullptr);
    _exit(code);
  }
  if (child_out >= 0) close(child_out);
  if (parent_out >= 0) fcntl(parent_out, F_SETFL, fcntl(parent_out, F_GETFL) | O_NONBLOCK);
  Process process;
  process.pid_ = pid;
  process.out_fd_ = parent_out;
  process.running_ = true;
  return process;
}

Process::Process(Process&& other) noexcept { *this = std::move(other); }

Process& Process::operator=(Process&& other) noexcept {
  if (this != &other) {
    Release();
    pid_ = std::exchange(other.pid_, -1);
    out_fd_ = std::exchange(other.out_fd_, -1);
    running_ = std::exchange(other.running_, false);
    exit_code_ = other.exit_code_;
    term_signal_ = other.term_signal_;
    usage_ = other.usage_;
  }
  return *this;
}

Process::~Process() { Release(); }

void Process::Release() {
  if (running_) {
    kill(pid_, SIGKILL);
    Wait();
  }
  if (out_fd_ >= 0) close(out_fd_);
  out_fd_ = -1;
}

void Process::Reaped(int status) {
  running_ = false;
  if (WIFEXITED(status)) exit_code_ = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) term_signal_ = WTERMSIG(status);
}

bool Process::Poll() {
  if (!running_) return true;
  int status = 0;
  if (wait4(pid_, &status, WNOHANG, &usage_) != pid_) return false;
  Reaped(status);
  return true;
}

bool Process::Wait(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!Poll()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

void Process::Wait() {
  if (!running_) return;
  int status = 0;
  while (wait4(pid_, &status, 0, &usage_) != pid_) {
    if (errno != EINTR) {
      running_ = false;  // not our child any more (reaped elsewhere): nothing to wait for
      return;
    }
  }
  Reaped(status);
}

void Process::Signal(int signal) {
  if (running_) kill(pid_, signal);
}

void Process::Terminate(std::chrono::milliseconds grace) {
  Signal(SIGTERM);
  if (!Wait(grace)) {
    Signal(SIGKILL);
    Wait();
  }
}

bool Process::ReadOutput(std::string* out) {
  char buffer[4096];
  while (out_fd_ >= 0) {
    const ssize_t n = read(out_fd_, buffer, sizeof(buffer));
    if (n > 0) {
      out->append(buffer, static_cast<size_t>(n));
    } else if (n == 0) {
      close(out_fd_);
      out_fd_ = -1;
    } else {
      return errno == EAGAIN || errno == EINTR;  // nothing now (or interrupted): still open
    }
  }
  return false;
}

std::string Process::ReadAllOutput() {
  std::string out;
  while (ReadOutput(&out)) {
    pollfd fd{out_fd_, POLLIN, 0};
    (void)poll(&fd, 1, 100);
  }
  return out;
}

std::string Process::Outcome() const {
  if (running_) return "still running";
  if (term_signal_ != 0) return std::string("killed by signal ") + strsignal(term_signal_);
  return "exit code " + std::to_string(exit_code_);
}

CapturedRun RunCaptured(const std::vector<std::string>& argv, std::chrono::milliseconds timeout) {
  SpawnOptions options;
  options.output = SpawnOptions::Output::kPipe;
  Process child = Process::Spawn(argv, options);
  CapturedRun run;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (child.ReadOutput(&run.output)) {
    if (std::chrono::steady_clock::now() >= deadline) {
      run.timed_out = true;
      child.Terminate(std::chrono::seconds(2));
      child.ReadOutput(&run.output);
      break;
    }
    pollfd fd{child.output_fd(), POLLIN, 0};
    (void)poll(&fd, 1, 100);
  }
  if (!run.timed_out) child.Wait();
  run.exit_code = child.exit_code();
  return run;
}

}  // namespace felt
