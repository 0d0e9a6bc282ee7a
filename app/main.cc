// `felt`: the one command, with subcommands registered by app/*.cc and bench/*.cc.
#include <cstdio>
#include <exception>
#include <map>

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "app/command.h"

int main(int argc, char** argv) {
  CLI::App app{"Felt: a real-time haptic cloth server (see README.md)", "felt"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "felt 0.1.0");

  // Build the command tree: groups ("bench", "trace") hold their own subcommands.
  std::map<std::string, CLI::App*> groups;
  std::vector<std::pair<CLI::App*, felt::app::CommandRun>> runs;
  for (const felt::app::CommandEntry& entry : felt::app::RegisteredCommands()) {
    CLI::App* parent = &app;
    if (!entry.group.empty()) {
      auto [it, inserted] = groups.try_emplace(entry.group, nullptr);
      if (inserted) {
        it->second = app.add_subcommand(entry.group, entry.group + " commands");
        it->second->require_subcommand(1);
      }
      parent = it->second;
    }
    CLI::App* cmd = parent->add_subcommand(entry.name, entry.description);
    runs.emplace_back(cmd, entry.setup(*cmd));
  }

  CLI11_PARSE(app, argc, argv);

  // Run the one command that was parsed; bad input surfaces as an exception naming what was wrong.
  try {
    for (auto& [cmd, run] : runs) {
      if (cmd->parsed()) return run();
    }
  } catch (const std::exception& e) {
    spdlog::shutdown();
    std::fprintf(stderr, "felt: error: %s\n", e.what());
    return 2;
  }
  std::fprintf(stderr, "felt: no command ran\n");
  return 2;
}
