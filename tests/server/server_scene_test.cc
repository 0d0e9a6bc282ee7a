// [haptic] keys read by ParseHapticSpec: cpu_dma_latency_zero, tick and tick_device (defaults,
// values, errors naming them).
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "scene/scene_file.h"
#include "server/server_spec.h"

namespace felt {
namespace {

TEST(ServerSceneTest, CpuDmaLatencyZeroDefaultsOnAndIsRead) {
  EXPECT_TRUE(ParseHapticSpec(ParseSceneText("", "t.toml")).cpu_dma_latency_zero);
  EXPECT_TRUE(ParseHapticSpec(ParseSceneText("[haptic]\nhaptic_rate_hz = 1000.0\n", "t.toml"))
                  .cpu_dma_latency_zero);
  EXPECT_FALSE(ParseHapticSpec(ParseSceneText("[haptic]\ncpu_dma_latency_zero = false\n", "t.toml"))
                   .cpu_dma_latency_zero);
  try {
    ParseHapticSpec(ParseSceneText("[haptic]\ncpu_dma_latency_zero = 0\n", "t.toml"));
    FAIL() << "a number was accepted for a boolean";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("t.toml:2:1: haptic.cpu_dma_latency_zero"),
              std::string::npos)
        << e.what();
  }
}

TEST(ServerSceneTest, TickDefaultsToArrivalOfTheFirstDeviceAndIsRead) {
  const HapticSpec defaults = ParseHapticSpec(ParseSceneText("", "t.toml"));
  EXPECT_EQ(defaults.tick_trigger, HapticTickTrigger::kArrival);
  EXPECT_EQ(defaults.tick_device, "");
  EXPECT_EQ(
      ParseHapticSpec(ParseSceneText("[haptic]\ntick = \"periodic\"\n", "t.toml")).tick_trigger,
      HapticTickTrigger::kPeriodic);
  try {
    ParseHapticSpec(ParseSceneText("[haptic]\ntick = \"sometimes\"\n", "t.toml"));
    FAIL() << "an unknown tick was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("t.toml:2:1: haptic.tick"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("periodic"), std::string::npos) << e.what();
  }
  std::ifstream curtain(FELT_SOURCE_DIR "/scenes/curtain.toml");
  std::stringstream text;
  text << curtain.rdbuf();
  const std::string two_hands =
      text.str() + "\n[[devices]]\nid = \"left\"\n[[devices]]\nid = \"right\"\n[haptic]\n";
  ServerSpec spec =
      ParseServerSpec(ParseSceneText(two_hands + "tick_device = \"right\"\n", "t.toml"));
  EXPECT_EQ(TickDeviceIndex(spec), 1);
  spec.haptic.tick_device.clear();
  EXPECT_EQ(TickDeviceIndex(spec), 0);
  try {
    ParseServerSpec(ParseSceneText(two_hands + "tick_device = \"middle\"\n", "t.toml"));
    FAIL() << "an unknown tick_device was accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find(":1: haptic.tick_device: 'middle' is not a device"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace felt
