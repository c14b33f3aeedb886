#include "generate/tube.hpp"

#include <cmath>
#include <numbers>
#include <string>

namespace curvenet {

RawMesh make_capped_tube(const TubeSpec& s) {
  RawMesh m;
  const int n = s.around;
  auto ring_point = [&](double r, int i, double y) {
    const double a = 2 * std::numbers::pi * i / n;
    return Vec3(r * std::cos(a), y, r * std::sin(a));
  };
  // Side rings 0..along.
  for (int j = 0; j <= s.along; ++j)
    for (int i = 0; i < n; ++i)
      m.positions.push_back(ring_point(s.radius, i, s.length * j / s.along));
  auto side = [&](int i, int j) { return j * n + (i % n); };
  // Cap rings: k = 1..cap_rings-1 inside the rim, then the centre.
  auto add_cap = [&](double y, int rim_row) {
    std::vector<int> prev(n);
    for (int i = 0; i < n; ++i)
      prev[i] = side(i, rim_row);
    std::vector<std::vector<int>> rings{prev};
    for (int k = 1; k < s.cap_rings; ++k) {
      std::vector<int> r(n);
      for (int i = 0; i < n; ++i) {
        r[i] = static_cast<int>(m.positions.size());
        m.positions.push_back(ring_point(s.radius * (1.0 - static_cast<double>(k) / s.cap_rings), i, y));
      }
      rings.push_back(r);
    }
    const int centre = static_cast<int>(m.positions.size());
    m.positions.emplace_back(0, y, 0);
    return std::make_pair(rings, centre);
  };
  std::vector<std::vector<int>> faces;
  auto quad = [&](int a, int b, int c, int d, bool flip_diag) {
    if (!s.triangulate) {
      faces.push_back({a, b, c, d});
    } else if (!flip_diag) {
      faces.push_back({a, b, c});
      faces.push_back({a, c, d});
    } else {
      faces.push_back({a, b, d});
      faces.push_back({b, c, d});
    }
  };
  for (int j = 0; j < s.along; ++j)
    for (int i = 0; i < n; ++i)
      quad(side(i, j), side(i, j + 1), side(i + 1, j + 1), side(i + 1, j), (i + j) % 2 == 1);
  for (int end = 0; end < 2; ++end) {
    const double y = end == 0 ? 0.0 : s.length;
    auto [rings, centre] = add_cap(y, end == 0 ? 0 : s.along);
    for (size_t k = 0; k + 1 < rings.size(); ++k)
      for (int i = 0; i < n; ++i) {
        const int a = rings[k][i], b = rings[k][(i + 1) % n], c = rings[k + 1][(i + 1) % n], d = rings[k + 1][i];
        if (end == 0)
          quad(a, b, c, d, (i + static_cast<int>(k)) % 2 == 1);
        else
          quad(a, d, c, b, (i + static_cast<int>(k)) % 2 == 1);
      }
    const auto& last = rings.back();
    for (int i = 0; i < n; ++i) {
      if (end == 0)
        faces.push_back({last[i], last[(i + 1) % n], centre});
      else
        faces.push_back({last[i], centre, last[(i + 1) % n]});
    }
  }
  // Orient outward: the signed volume must be positive.
  double vol = 0;
  for (const auto& f : faces)
    for (size_t k = 1; k + 1 < f.size(); ++k)
      vol += m.positions[f[0]].dot(m.positions[f[k]].cross(m.positions[f[k + 1]]));
  for (auto& f : faces) {
    if (vol < 0)
      std::reverse(f.begin(), f.end());
    m.add_face(f);
  }
  return m;
}

Rig make_tube_net(const TubeNetSpec& s) {
  Rig rig;
  rig.coverage = Coverage::Full;
  const double r = s.radius;
  const int np = s.points_per_profile;
  const int rings = static_cast<int>(s.ring_heights.size()), n = s.nodes_per_ring;
  const double step = 2 * std::numbers::pi / n;
  auto angle = [&](int k) { return s.first_angle_deg * std::numbers::pi / 180.0 + step * k; };
  auto on_side = [&](double a, double y) { return Eigen::Vector3d(r * std::cos(a), y, r * std::sin(a)); };
  auto ring_node = [](int i, int k) { return "ring" + std::to_string(i) + "_" + std::to_string(k); };
  for (int i = 0; i < rings; ++i)
    for (int k = 0; k < n; ++k)
      rig.nodes.push_back({ring_node(i, k), on_side(angle(k), s.ring_heights[i])});
  const Eigen::Vector3d bottom = Eigen::Vector3d(0, 0, 0) + s.cap_offset;
  const Eigen::Vector3d top = Eigen::Vector3d(0, s.length, 0) + s.cap_offset;
  rig.nodes.push_back({"cap_bottom", bottom});
  rig.nodes.push_back({"cap_top", top});
  auto add = [&](std::string id, std::string from, std::string to, std::vector<Eigen::Vector3d> pts) {
    Profile p;
    p.id = std::move(id);
    p.from = std::move(from);
    p.to = std::move(to);
    p.curve.points = std::move(pts);
    // The ends are the nodes themselves, not the same angle rounded anew.
    p.curve.points.front() = rig.nodes[rig.node_index(p.from)].position;
    p.curve.points.back() = rig.nodes[rig.node_index(p.to)].position;
    rig.profiles.push_back(std::move(p));
  };
  // Ring arcs.
  for (int i = 0; i < rings; ++i)
    for (int k = 0; k < n; ++k) {
      std::vector<Eigen::Vector3d> pts;
      for (int q = 0; q <= np; ++q)
        pts.push_back(on_side(angle(k) + step * q / np, s.ring_heights[i]));
      add("ring" + std::to_string(i) + "_arc" + std::to_string(k) + std::to_string((k + 1) % n), ring_node(i, k),
          ring_node(i, (k + 1) % n), pts);
    }
  // Along the side, between consecutive rings.
  for (int i = 0; i + 1 < rings; ++i)
    for (int k = 0; k < n; ++k) {
      std::vector<Eigen::Vector3d> pts;
      for (int q = 0; q <= np; ++q)
        pts.push_back(on_side(angle(k), s.ring_heights[i] + (s.ring_heights[i + 1] - s.ring_heights[i]) * q / np));
      add("side" + std::to_string(i) + std::to_string(i + 1) + "_" + std::to_string(k), ring_node(i, k),
          ring_node(i + 1, k), pts);
    }
  // Spokes: from each cap's centre across the cap, over the rim, to the nearest ring.
  for (int end = 0; end < 2; ++end) {
    const double y_cap = end == 0 ? 0.0 : s.length;
    const double y_ring = end == 0 ? s.ring_heights.front() : s.ring_heights.back();
    const Eigen::Vector3d centre = end == 0 ? bottom : top;
    for (int k = 0; k < n; ++k) {
      std::vector<Eigen::Vector3d> pts;
      const Eigen::Vector3d rim = on_side(angle(k), y_cap);
      for (int q = 0; q < np; ++q)
        pts.push_back(centre + (rim - centre) * q / np);
      for (int q = 0; q <= np; ++q)
        pts.push_back(on_side(angle(k), y_cap + (y_ring - y_cap) * q / np));
      add(std::string(end == 0 ? "spoke_bottom_" : "spoke_top_") + std::to_string(k),
          end == 0 ? "cap_bottom" : "cap_top", ring_node(end == 0 ? 0 : rings - 1, k), pts);
    }
  }
  // A three-joint skeleton along the axis.
  rig.has_skeleton = true;
  const char* names[] = {"root", "mid", "tip"};
  for (int j = 0; j < 3; ++j) {
    Joint jt;
    jt.name = names[j];
    if (j > 0)
      jt.parent = names[j - 1];
    jt.bind(1, 3) = s.length * j / 2.0;
    rig.joints.push_back(jt);
  }
  return rig;
}

std::vector<Joint> make_tube_skeleton(const std::vector<double>& heights) {
  std::vector<Joint> joints;
  for (size_t i = 0; i < heights.size(); ++i) {
    Joint j;
    j.name = std::string("j").append(std::to_string(i)); // (GCC 12 warns, wrongly, of "j" + a temporary)
    if (i > 0)
      j.parent = std::string("j").append(std::to_string(i - 1));
    j.bind(1, 3) = heights[i];
    joints.push_back(j);
  }
  return joints;
}

} // namespace curvenet
