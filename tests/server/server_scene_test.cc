// [haptic] keys read by ParseHapticSpec: cpu_dma_latency_zero (default, value, error naming it).
#include <gtest/gtest.h>

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

}  // namespace
}  // namespace felt
