// `felt view` and `felt serve --view` (issue 25, docs/view.md): they print the view's URL, serve
// it while they run, and end cleanly; a port in use is refused with a message naming it.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <string>

#include "tests/app/felt_process.h"

namespace felt::test {
namespace {

TEST(ViewCommand, PlaysATraceAndPrintsTheUrl) {
  // The 6 s poke-and-hold at 20 x speed: about 0.3 s of wall time.
  const Outcome o = RunFelt("view --scene " + kSource + "/scenes/curtain.toml --trace " +
                            kPokeHoldTrace + " --port 0 --speed 20 --exit-at-end");
  EXPECT_EQ(o.exit_code, 0) << o.output;
  EXPECT_NE(o.output.find("live view at http://127.0.0.1:"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("trace played"), std::string::npos) << o.output;
}

TEST(ViewCommand, ServeWithViewReportsTheViewAndStops) {
  const Outcome o = RunFelt("serve --scene " + kSource + "/scenes/curtain.toml --trace " +
                            kPokeHoldTrace + " --duration 1 --no-realtime --view 0");
  EXPECT_EQ(o.exit_code, 0) << o.output;
  EXPECT_NE(o.output.find("felt serve: live view at http://127.0.0.1:"), std::string::npos)
      << o.output;
  EXPECT_NE(o.output.find("view: 0 clients, 0 frames sent"), std::string::npos) << o.output;
}

TEST(ViewCommand, APortInUseIsNamed) {
  // Hold a port, then ask the view for it.
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  ASSERT_EQ(listen(fd, 1), 0);
  socklen_t len = sizeof(addr);
  ASSERT_EQ(getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  const int port = ntohs(addr.sin_port);
  const Outcome o = RunFelt("view --scene " + kSource + "/scenes/curtain.toml --trace " +
                            kPokeHoldTrace + " --port " + std::to_string(port) + " --exit-at-end");
  close(fd);
  EXPECT_NE(o.exit_code, 0) << o.output;
  EXPECT_NE(o.output.find("view: cannot listen on 127.0.0.1:" + std::to_string(port)),
            std::string::npos)
      << o.output;
}

}  // namespace
}  // namespace felt::test
