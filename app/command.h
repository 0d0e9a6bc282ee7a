#pragma once
// The registry of `felt` subcommands. Each app/*.cc or bench/*.cc file registers its commands
// from a static initializer, so adding a command never edits main.cc.

#include <functional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

namespace felt::app {

/// What runs after parsing; returns the process exit code (0 = success).
using CommandRun = std::function<int()>;

/// Adds a command's options to `cmd` (bound to variables it owns) and returns what runs it.
using CommandSetup = std::function<CommandRun(CLI::App& cmd)>;

/// One registered command: `felt <group> <name>`, or `felt <name>` when group is empty.
struct CommandEntry {
  std::string group;        ///< "" for a top-level command, else e.g. "bench" or "trace"
  std::string name;         ///< the subcommand's name
  std::string description;  ///< one line shown by --help
  CommandSetup setup;       ///< called once while the command line is being built
};

/// Registers a command; call from a static initializer (returns true so it can initialise a bool).
bool RegisterCommand(CommandEntry entry);

/// Every registered command, in registration order.
const std::vector<CommandEntry>& RegisteredCommands();

}  // namespace felt::app
