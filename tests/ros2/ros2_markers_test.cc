// The cloth and proxies as markers (ros2/markers.h): a triangle list of 3 points per triangle at
// the particles' positions, spheres of the proxies' diameters, the device-frame map, stable ids,
// and filling without allocation.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "ros2/markers.h"
#include "tests/alloc_counter.h"

namespace felt::ros2 {
namespace {

// A W x H grid of particles 0.1 m apart in the x-y plane, z = 0.01 i, and its 2 (W-1)(H-1)
// triangles (two per cell).
struct MarkerTestGrid {
  std::vector<float> xyz;
  std::vector<std::array<int32_t, 3>> triangles;
};
MarkerTestGrid MakeMarkerTestGrid(int w, int h) {
  MarkerTestGrid g;
  for (int j = 0; j < h; ++j) {
    for (int i = 0; i < w; ++i) {
      g.xyz.push_back(0.1f * static_cast<float>(i));
      g.xyz.push_back(0.1f * static_cast<float>(j));
      g.xyz.push_back(0.01f * static_cast<float>(i + w * j));
    }
  }
  for (int j = 0; j + 1 < h; ++j) {
    for (int i = 0; i + 1 < w; ++i) {
      const int32_t a = i + w * j, b = a + 1, c = a + w, d = c + 1;
      g.triangles.push_back({a, b, d});
      g.triangles.push_back({a, d, c});
    }
  }
  return g;
}

TEST(Ros2Markers, TheClothIsATriangleListOfTheParticlesPositions) {
  const MarkerTestGrid g = MakeMarkerTestGrid(5, 4);
  MarkerStyle style;
  style.frame_id = "felt_world";
  MarkerArray a = MakeMarkerArray(g.triangles.size(), 2, style);
  ASSERT_EQ(a.markers.size(), 3u);
  Marker& cloth = a.markers[0];
  FillClothMarker(g.xyz, g.triangles, MarkerMap{}, &cloth);
  EXPECT_EQ(cloth.type, Marker::kTriangleList);
  EXPECT_EQ(cloth.ns, kClothMarkerNs);
  EXPECT_EQ(cloth.id, 0);
  EXPECT_EQ(cloth.header.frame_id, "felt_world");
  EXPECT_EQ(cloth.scale, (Vector3{1, 1, 1}));
  ASSERT_EQ(cloth.points.size(), 3u * 2u * 4u * 3u);  // 3 points x 2 (W-1)(H-1) triangles
  for (size_t t = 0; t < g.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const size_t v = 3 * static_cast<size_t>(g.triangles[t][static_cast<size_t>(k)]);
      const Vector3& p = cloth.points[3 * t + static_cast<size_t>(k)];
      EXPECT_EQ(p.x, static_cast<double>(g.xyz[v]));
      EXPECT_EQ(p.y, static_cast<double>(g.xyz[v + 1]));
      EXPECT_EQ(p.z, static_cast<double>(g.xyz[v + 2]));
    }
  }
  // Proxies: ids by device index, stable; stamps set on all.
  EXPECT_EQ(a.markers[1].ns, kProxyMarkerNs);
  EXPECT_EQ(a.markers[1].id, 0);
  EXPECT_EQ(a.markers[2].id, 1);
  EXPECT_EQ(a.markers[2].type, Marker::kSphere);
  StampMarkers(Time{12, 34}, &a);
  for (const Marker& m : a.markers) EXPECT_EQ(m.header.stamp, (Time{12, 34}));
}

TEST(Ros2Markers, AProxyIsASphereOfItsDiameterColouredByContact) {
  MarkerStyle style;
  MarkerArray a = MakeMarkerArray(0, 1, style);
  Marker& p = a.markers[1];
  FillProxyMarker({0.1, -0.2, 0.3}, 0.004, false, MarkerMap{}, style, &p);
  EXPECT_EQ(p.pose.position, (Vector3{0.1, -0.2, 0.3}));
  EXPECT_EQ(p.pose.orientation, Quaternion{});
  EXPECT_EQ(p.scale, (Vector3{0.008, 0.008, 0.008}));
  EXPECT_EQ(p.color, style.proxy_free);
  FillProxyMarker({0.1, -0.2, 0.3}, 0.004, true, MarkerMap{}, style, &p);
  EXPECT_EQ(p.color, style.proxy_contact);
  EXPECT_NE(style.proxy_contact, style.proxy_free);
}

TEST(Ros2Markers, ADeviceFrameMapAppliesTheInverseWorkspaceMap) {
  // World -> device for scale 3, a 90 degree turn about z (R_WD: x_D -> y_W), offset (1, 2, 3):
  // p_D = R_WD^T (p_W - o) / 3. The world point o + 3 R_WD (0.01, 0, 0) = (1, 2.03, 3) is the
  // device's (0.01, 0, 0); a 4 mm radius is 8/3 mm across in the device frame.
  MarkerMap map;
  map.linear = {0, 1.0 / 3, 0, -1.0 / 3, 0, 0, 0, 0, 1.0 / 3};
  map.offset = {-2.0 / 3, 1.0 / 3, -1.0};
  map.size_scale = 1.0 / 3;
  MarkerStyle style;
  MarkerArray a = MakeMarkerArray(0, 1, style);
  FillProxyMarker({1.0, 2.03, 3.0}, 0.004, false, map, style, &a.markers[1]);
  EXPECT_NEAR(a.markers[1].pose.position.x, 0.01, 1e-12);
  EXPECT_NEAR(a.markers[1].pose.position.y, 0.0, 1e-12);
  EXPECT_NEAR(a.markers[1].pose.position.z, 0.0, 1e-12);
  EXPECT_NEAR(a.markers[1].scale.x, 0.008 / 3, 1e-15);
}

TEST(Ros2Markers, FillingAPreparedArrayDoesNotAllocate) {
  const MarkerTestGrid g = MakeMarkerTestGrid(16, 16);
  MarkerStyle style;
  MarkerArray a = MakeMarkerArray(g.triangles.size(), 2, style);
  AllocationGuard guard;
  FillClothMarker(g.xyz, g.triangles, MarkerMap{}, &a.markers[0]);
  FillProxyMarker({0, 0, 0}, 0.004, true, MarkerMap{}, style, &a.markers[1]);
  StampMarkers(Time{1, 2}, &a);
  EXPECT_EQ(guard.allocations(), 0u);
  for (const Vector3& p : a.markers[0].points) {
    EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
  }
}

}  // namespace
}  // namespace felt::ros2
