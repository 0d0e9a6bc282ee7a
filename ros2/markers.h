#pragma once
// The cloth and the proxies as RViz / Foxglove markers (issue 24): one
// visualization_msgs/MarkerArray holding the cloth as a TRIANGLE_LIST (namespace "felt_cloth",
// id 0) and each device's proxy as a SPHERE (namespace "felt_proxy", id = the device's index in
// the scene), so one MarkerArray display shows the whole scene, cloth and proxies of the same
// instant. Pure functions on plain values: no DDS, no threads (server/ros2_marker_feed.h publishes
// them).
//
// Positions: Felt's world frame (the scene's cloth frame, metres) mapped by a MarkerMap
// p_out = A p + b (identity for the world; a device's inverse workspace map p_D = R_WD^T (p_W -
// offset_W) / scale to draw in that device's frame, where its driver's pose lives). Sizes are
// multiplied by MarkerMap::size_scale (1 / scale for a device frame). REP 103 units: metres.

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include "ros2/messages.h"

namespace felt::ros2 {

/// The cloth marker's namespace and id; the proxies' namespace (id = device index).
inline constexpr const char* kClothMarkerNs = "felt_cloth";
inline constexpr int32_t kClothMarkerId = 0;
inline constexpr const char* kProxyMarkerNs = "felt_proxy";

/// An affine map of positions, p_out = linear p + offset (row-major 3 x 3), and the factor of
/// sizes (a uniform scale's).
struct MarkerMap {
  std::array<double, 9> linear = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::array<double, 3> offset = {0, 0, 0};  ///< [m]
  double size_scale = 1.0;                   ///< output metres per world metre of a size
};

/// What the markers look like (from the scene; RGBA in [0, 1]).
struct MarkerStyle {
  std::string frame_id = "world";                      ///< header.frame_id of every marker
  ColorRGBA cloth{0.90f, 0.55f, 0.20f, 1.0f};          ///< the cloth, one colour
  ColorRGBA proxy_free{0.20f, 0.75f, 0.30f, 1.0f};     ///< a proxy out of contact
  ColorRGBA proxy_contact{0.90f, 0.15f, 0.10f, 1.0f};  ///< a proxy touching the cloth
  /// How long RViz keeps a marker without an update (so markers vanish when Felt stops).
  Duration lifetime{1, 0};
};

/// A MarkerArray for a cloth of `triangle_count` triangles and `proxy_count` proxies with every
/// constant field set (namespaces, ids, types, frame, colours, lifetime) and the cloth's points
/// sized (3 per triangle). Set-up: allocates; the Fill* functions then do not.
MarkerArray MakeMarkerArray(size_t triangle_count, size_t proxy_count, const MarkerStyle& style);

/// The cloth marker's points: for each triangle (i, j, k) of `triangles`, the particles' positions
/// from `xyz_m` (x0 y0 z0 x1 ..., world, m, float32 as the view tap holds them) mapped by `map`.
/// `cloth->points` must already hold 3 per triangle (MakeMarkerArray). Allocation-free.
void FillClothMarker(std::span<const float> xyz_m,
                     std::span<const std::array<int32_t, 3>> triangles, const MarkerMap& map,
                     Marker* cloth);

/// A proxy's sphere: centre `center_W_m` (world, m) mapped by `map`, diameter 2 radius_m x
/// map.size_scale on every axis, the contact colour when `in_contact`. Allocation-free.
void FillProxyMarker(const std::array<double, 3>& center_W_m, double radius_m, bool in_contact,
                     const MarkerMap& map, const MarkerStyle& style, Marker* proxy);

/// Sets every marker's header.stamp to `stamp`.
void StampMarkers(const Time& stamp, MarkerArray* array);

}  // namespace felt::ros2
