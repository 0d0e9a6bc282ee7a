#include "app/command.h"

namespace felt::app {
namespace {
std::vector<CommandEntry>& Registry() {
  static std::vector<CommandEntry> registry;  // function-local: safe across static initializers
  return registry;
}
}  // namespace

bool RegisterCommand(CommandEntry entry) {
  Registry().push_back(std::move(entry));
  return true;
}

const std::vector<CommandEntry>& RegisteredCommands() { return Registry(); }

}  // namespace felt::app
