// The live view in a real browser (issue 25): headless Chromium (Debian's `chromium`) opens the
// page of a running view, and its screenshots (PNG, decoded with libpng) show the cloth and the
// proxy where they must be; after the proxy moved, the second screenshot differs there. Skips
// with a message when chromium is not installed.
#include <gtest/gtest.h>
#include <png.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "base/process.h"
#include "server/server.h"
#include "tests/server/server_test_util.h"
#include "tests/test_env.h"
#include "view/view_server.h"

namespace felt {
namespace {

using testing_server::Driver;
using testing_server::SmallCurtain;

constexpr char kChromium[] = "/usr/bin/chromium";
constexpr int kShotWidth = 640;
constexpr int kShotHeight = 480;

struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<uint8_t> rgb;  // [height][width][3]
  const uint8_t* At(int x, int y) const {
    return &rgb[3 * (static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x))];
  }
};

// The PNG at `path` as 8-bit RGB (libpng's simplified API); empty on failure.
RgbImage ReadPngRgb(const std::string& path) {
  RgbImage out;
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_file(&image, path.c_str()) == 0) return out;
  image.format = PNG_FORMAT_RGB;
  out.rgb.resize(PNG_IMAGE_SIZE(image));
  if (png_image_finish_read(&image, nullptr, out.rgb.data(), 0, nullptr) == 0) {
    png_image_free(&image);
    return RgbImage{};
  }
  out.width = static_cast<int>(image.width);
  out.height = static_cast<int>(image.height);
  return out;
}

// The page's proxy colour, 0xffaa00 (unlit): exactly that, give or take antialiasing.
bool IsProxyColour(const uint8_t* p) { return p[0] > 225 && p[1] > 140 && p[1] < 200 && p[2] < 60; }
// The cloth's light blue 0x6fa8dc under the head light: clearly blue, not the dark background.
bool IsClothColour(const uint8_t* p) { return p[2] > 120 && p[2] > p[0] + 40 && p[1] > 80; }

struct PixelCount {
  int count = 0;
  double cx = 0;  // centroid, px
  double cy = 0;
};

template <typename Pred>
PixelCount CountIn(const RgbImage& img, int x0, int y0, int x1, int y1, Pred&& pred) {
  PixelCount c;
  for (int y = std::max(0, y0); y < std::min(img.height, y1); ++y) {
    for (int x = std::max(0, x0); x < std::min(img.width, x1); ++x) {
      if (pred(img.At(x, y))) {
        ++c.count;
        c.cx += x;
        c.cy += y;
      }
    }
  }
  if (c.count > 0) {
    c.cx /= c.count;
    c.cy /= c.count;
  }
  return c;
}

// A screenshot of `url` by headless Chromium into `png` (3 s of virtual time for the page to
// connect and draw); returns its output when it failed.
std::string Screenshot(const std::string& url, const std::string& png, const std::string& profile) {
  SpawnOptions options;
  options.output = SpawnOptions::Output::kPipe;
  Process p = Process::Spawn(
      {kChromium, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
       "--user-data-dir=" + profile,
       "--window-size=" + std::to_string(kShotWidth) + "," + std::to_string(kShotHeight),
       "--virtual-time-budget=3000", "--screenshot=" + png, url},
      options);
  std::string out;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!p.Wait(std::chrono::milliseconds(100))) {
    p.ReadOutput(&out);
    if (std::chrono::steady_clock::now() > deadline) {
      p.Terminate(std::chrono::milliseconds(500));
      return "chromium timed out: " + out;
    }
  }
  p.ReadOutput(&out);
  return std::filesystem::exists(png) ? "" : "no screenshot; chromium said: " + out;
}

TEST(ViewChromium, ScreenshotsShowTheClothAndTheProxyMoving) {
  // Not under a sanitizer: Chromium is not instrumented, and the view server's threads and
  // handlers it drives are ViewServer's tests' (a WebSocket client reading every frame, the page
  // and three.js served, the client limit) and ViewSlowClient's; one Chromium start took 10-24 s
  // of the ASan run.
  if (testing::Sanitized()) GTEST_SKIP() << "the browser test runs in the release build only";
  if (!std::filesystem::exists(kChromium)) {
    GTEST_SKIP() << "chromium is not installed (Debian package `chromium`, in the Makefile's "
                    "PACKAGES): the browser test of the live view is skipped";
  }
  ServerSpec spec = SmallCurtain();
  spec.devices[0].radius_m = 0.015;  // big enough to find in a 640 x 480 screenshot
  LatestPointerSource source(1);
  CapturingForceSink sink(1);
  Server server(spec, &source, &sink);
  ViewServer view(&server, ViewOptions{});
  server.PublishInitialSnapshot(1'000'000'000'000);
  Driver driver(&server, &source);
  // The device in front of the cloth's middle (z_D 20 mm = 60 mm in the world: free space),
  // then 40 mm to the right in the device (120 mm in the world).
  auto hold_at = [](double x_D) {
    return [x_D](uint32_t, double, PointerInput* in) {
      in->p_D_m = Vec3(x_D, 0.0, 0.020);
      in->v_D_m_per_s = Vec3::Zero();
      return true;
    };
  };
  for (int i = 0; i < 300; ++i) driver.Tick(1, hold_at(0.0));
  ASSERT_LT(server.haptic().last_result(0).proxy_W_m.x(), 0.001);

  const std::string dir = ::testing::TempDir() + "/felt_view_chromium";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string shot1 = dir + "/centre.png";
  const std::string shot2 = dir + "/right.png";
  ASSERT_EQ(Screenshot(view.url(), shot1, dir + "/profile1"), "");
  for (int i = 0; i < 200; ++i) driver.Tick(1, hold_at(0.040));
  ASSERT_GT(server.haptic().last_result(0).proxy_W_m.x(), 0.11);
  ASSERT_EQ(Screenshot(view.url(), shot2, dir + "/profile2"), "");

  const RgbImage a = ReadPngRgb(shot1);
  const RgbImage b = ReadPngRgb(shot2);
  ASSERT_EQ(a.width, kShotWidth) << shot1;
  ASSERT_EQ(b.width, kShotWidth) << shot2;
  const int cx = kShotWidth / 2;
  const int cy = kShotHeight / 2;
  // The cloth fills the middle (the camera frames it); a patch left of the centre is cloth.
  const PixelCount cloth_a = CountIn(a, cx - 120, cy - 20, cx - 60, cy + 20, IsClothColour);
  EXPECT_GT(cloth_a.count, 60 * 40 * 9 / 10) << "cloth colour left of the centre in " << shot1;
  // The proxy is at the centre in the first shot, and nowhere right of it.
  const PixelCount proxy_a = CountIn(a, cx - 30, cy - 30, cx + 30, cy + 30, IsProxyColour);
  EXPECT_GT(proxy_a.count, 100) << shot1;
  EXPECT_EQ(CountIn(a, cx + 40, 0, kShotWidth, kShotHeight, IsProxyColour).count, 0) << shot1;
  // In the second it moved right (120 mm at ~650 px/m: ~80 px), and the centre shows cloth.
  const PixelCount proxy_b = CountIn(b, 0, 0, kShotWidth, kShotHeight, IsProxyColour);
  EXPECT_GT(proxy_b.count, 100) << shot2;
  EXPECT_GT(proxy_b.cx - proxy_a.cx, 50.0) << shot2;
  EXPECT_LT(proxy_b.cx - proxy_a.cx, 130.0) << shot2;
  EXPECT_NEAR(proxy_b.cy, proxy_a.cy, 10.0) << shot2;
  EXPECT_EQ(CountIn(b, cx - 8, cy - 8, cx + 8, cy + 8, IsProxyColour).count, 0) << shot2;
  EXPECT_GT(CountIn(b, cx - 8, cy - 8, cx + 8, cy + 8, IsClothColour).count, 16 * 16 * 9 / 10)
      << shot2;
}

}  // namespace
}  // namespace felt
