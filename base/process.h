#pragma once
// The project's one way to start a child process: spawn an argv (or fork a function), with its
// stdout and stderr left alone, sent to a file, or sent to a pipe this process reads; wait with a
// timeout; stop with SIGTERM, then SIGKILL. Not real-time safe (it allocates and forks).

#include <sys/resource.h>
#include <sys/types.h>

#include <chrono>
#include <functional>
#include <string>
#include <vector>

namespace felt {

/// Where a child's stdout and stderr go, and how it is tied to this process.
struct SpawnOptions {
  enum class Output {
    kInherit,  ///< this process's stdout and stderr
    kFile,     ///< both into `output_file` (created or truncated)
    kPipe,     ///< both into a pipe: Process::ReadOutput / ReadAllOutput
  };
  Output output = Output::kInherit;  ///< where stdout and stderr go
  std::string output_file;           ///< the file for Output::kFile
  bool die_with_parent = false;      ///< the child gets SIGTERM when this process dies
  std::vector<std::string> env;      ///< NAME=value entries added to the child's environment
};

/// A child process. Move-only; destroying one that still runs kills (SIGKILL) and reaps it, so
/// none is left behind on an exception path.
class Process {
 public:
  /// Starts `argv[0]` (a path, not searched in PATH) with arguments `argv`; throws
  /// std::runtime_error when the pipe, the file or the fork fails (an exec failure exits 127).
  static Process Spawn(const std::vector<std::string>& argv, const SpawnOptions& options = {});
  /// Forks this process; the child runs `child` and exits with its result (exit code 1 on an
  /// exception, its message on stderr) without running atexit handlers.
  static Process Fork(const std::function<int()>& child, const SpawnOptions& options = {});

  Process() = default;
  Process(Process&& other) noexcept;
  Process& operator=(Process&& other) noexcept;
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;
  ~Process();

  /// The child's process id (-1 when none was started).
  pid_t pid() const { return pid_; }
  /// True until the child has been reaped (Poll, Wait, Terminate).
  bool running() const { return running_; }
  /// The read end of the output pipe (non-blocking), -1 without one or after its end of file.
  int output_fd() const { return out_fd_; }

  /// Reaps the child if it has exited, without blocking; true when it is gone.
  bool Poll();
  /// Waits up to `timeout` [ms resolution] for the child to exit; true when it is gone.
  bool Wait(std::chrono::milliseconds timeout);
  /// Waits for the child to exit, however long it takes.
  void Wait();
  /// Sends `signal` to a running child (nothing once it is reaped).
  void Signal(int signal);
  /// SIGTERM, then SIGKILL after `grace` [ms]; returns once the child is reaped.
  void Terminate(std::chrono::milliseconds grace = std::chrono::seconds(5));

  /// Appends the output available now to `out` (never blocks); false once the pipe reached its end.
  bool ReadOutput(std::string* out);
  /// Reads the output to its end (blocks until the child closes it).
  std::string ReadAllOutput();

  /// The exit code when the child exited normally, else -1 (still running, or a signal ended it).
  int exit_code() const { return exit_code_; }
  /// The signal that ended the child, 0 when none did.
  int term_signal() const { return term_signal_; }
  /// The child's resource usage (CPU times), filled when it is reaped.
  const rusage& usage() const { return usage_; }
  /// "exit code N", "killed by signal NAME" or "still running", for messages.
  std::string Outcome() const;

 private:
  static Process Start(const std::vector<std::string>* argv, const std::function<int()>* child,
                       const SpawnOptions& options);
  void Reaped(int status);
  void Release();

  pid_t pid_ = -1;
  int out_fd_ = -1;
  bool running_ = false;
  int exit_code_ = -1;
  int term_signal_ = 0;
  rusage usage_{};
};

/// What RunCaptured returned.
struct CapturedRun {
  int exit_code = -1;      ///< the exit code, -1 when a signal ended it (or the timeout did)
  bool timed_out = false;  ///< the child outlived the timeout and was killed
  std::string output;      ///< stdout and stderr together
};

/// Runs `argv` to its end with stdout and stderr captured; after `timeout` [ms] the child is
/// terminated (SIGTERM, then SIGKILL).
CapturedRun RunCaptured(const std::vector<std::string>& argv,
                        std::chrono::milliseconds timeout = std::chrono::minutes(10));

}  // namespace felt
