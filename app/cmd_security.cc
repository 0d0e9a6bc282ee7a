// `felt security init DIR [--participants server,device:default,recorder] [--force]
// [--days N]`: makes a DDS Security directory with Debian's openssl (docs/transport.md,
// "Security"): one CA (identity and permissions CA in one), a signed governance document, and for
// each participant a key, a certificate and a signed permissions document. Existing keys are kept
// unless --force is given; an existing CA is reused, so identities can be added later.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "app/command.h"
#include "transport/security.h"

namespace felt::app::cmd_security {
namespace {

struct SecurityInitArgs {
  std::string dir;
  std::string participants = "server,device:default,recorder";
  bool force = false;
  int days = 3650;
};

int SecurityInit(const SecurityInitArgs& args) {
  transport::SecurityInitOptions options;
  options.dir = args.dir;
  options.identities = transport::ParseSecurityParticipants(args.participants);
  options.force = args.force;
  options.validity_days = args.days;
  const std::vector<std::string> written = transport::InitSecurityDir(options);
  std::printf("felt security init: %zu files in %s (CA = identity and permissions CA)\n",
              written.size(), args.dir.c_str());
  for (const std::string& path : written) std::printf("  %s\n", path.c_str());
  std::printf("identities:");
  for (const transport::SecurityIdentity& identity : options.identities) {
    std::printf(" %s", identity.Name().c_str());
  }
  std::printf("\nuse: felt serve --security %s ...; felt_device_client --security %s ...\n",
              args.dir.c_str(), args.dir.c_str());
  return 0;
}

const bool kRegistered = RegisterCommand({
    "security",
    "init",
    "make a DDS Security directory: CA, identities, signed governance and permissions (openssl)",
    [](CLI::App& cmd) -> CommandRun {
      auto args = std::make_shared<SecurityInitArgs>();
      cmd.add_option("dir", args->dir, "the directory to fill (created when missing)")->required();
      cmd.add_option("--participants", args->participants,
                     "comma-separated identities: server, recorder, device:ID (default "
                     "server,device:default,recorder)");
      cmd.add_flag("--force", args->force,
                   "make a new CA and replace existing keys (then list every identity: the "
                   "others' certificates no longer verify)");
      cmd.add_option("--days", args->days, "validity of certificates and permissions (3650)")
          ->check(CLI::Range(1, 36500));
      return [args] { return SecurityInit(*args); };
    },
});

}  // namespace
}  // namespace felt::app::cmd_security
