#include "ros2/markers.h"

namespace felt::ros2 {
namespace {

// map.linear p + map.offset.
Vector3 MapPoint(const MarkerMap& map, double x, double y, double z) {
  const std::array<double, 9>& a = map.linear;
  return Vector3{a[0] * x + a[1] * y + a[2] * z + map.offset[0],
                 a[3] * x + a[4] * y + a[5] * z + map.offset[1],
                 a[6] * x + a[7] * y + a[8] * z + map.offset[2]};
}

}  // namespace

MarkerArray MakeMarkerArray(size_t triangle_count, size_t proxy_count, const MarkerStyle& style) {
  MarkerArray array;
  array.markers.resize(1 + proxy_count);
  // The cloth: a triangle list, one colour; scale (1, 1, 1) as RViz requires for triangle lists.
  Marker& cloth = array.markers[0];
  cloth.header.frame_id = style.frame_id;
  cloth.ns = kClothMarkerNs;
  cloth.id = kClothMarkerId;
  cloth.type = Marker::kTriangleList;
  cloth.action = Marker::kAdd;
  cloth.scale = {1.0, 1.0, 1.0};
  cloth.color = style.cloth;
  cloth.lifetime = style.lifetime;
  cloth.points.resize(3 * triangle_count);
  // The proxies: spheres, id = device index (stable across runs of the same scene).
  for (size_t i = 0; i < proxy_count; ++i) {
    Marker& p = array.markers[1 + i];
    p.header.frame_id = style.frame_id;
    p.ns = kProxyMarkerNs;
    p.id = static_cast<int32_t>(i);
    p.type = Marker::kSphere;
    p.action = Marker::kAdd;
    p.color = style.proxy_free;
    p.lifetime = style.lifetime;
  }
  return array;
}

void FillClothMarker(std::span<const float> xyz_m,
                     std::span<const std::array<int32_t, 3>> triangles, const MarkerMap& map,
                     Marker* cloth) {
  size_t k = 0;
  for (const std::array<int32_t, 3>& t : triangles) {
    for (int32_t v : t) {
      const size_t i = 3 * static_cast<size_t>(v);
      cloth->points[k++] =
          MapPoint(map, static_cast<double>(xyz_m[i]), static_cast<double>(xyz_m[i + 1]),
                   static_cast<double>(xyz_m[i + 2]));
    }
  }
}

void FillProxyMarker(const std::array<double, 3>& center_W_m, double radius_m, bool in_contact,
                     const MarkerMap& map, const MarkerStyle& style, Marker* proxy) {
  proxy->pose.position = MapPoint(map, center_W_m[0], center_W_m[1], center_W_m[2]);
  proxy->pose.orientation = Quaternion{};
  // RViz draws a SPHERE with scale = its diameters along x, y, z [m].
  const double diameter_m = 2.0 * radius_m * map.size_scale;
  proxy->scale = {diameter_m, diameter_m, diameter_m};
  proxy->color = in_contact ? style.proxy_contact : style.proxy_free;
}

void StampMarkers(const Time& stamp, MarkerArray* array) {
  for (Marker& m : array->markers) m.header.stamp = stamp;
}

}  // namespace felt::ros2
