#include "core/polygon.hpp"

#include "core/predicates.hpp"

#include <Eigen/Geometry>
#include <cmath>

namespace curvenet::detail {

std::vector<std::array<int, 3>> triangulate_polygon(const std::vector<Eigen::Vector3d>& corners) {
  std::vector<std::array<int, 3>> tris;
  triangulate_polygon(corners, tris);
  return tris;
}

void triangulate_polygon(std::span<const Eigen::Vector3d> corners, std::vector<std::array<int, 3>>& tris) {
  tris.clear();
  const int n = static_cast<int>(corners.size());
  if (n == 3) {
    tris.push_back({0, 1, 2});
    return;
  }
  Eigen::Vector3d normal = Eigen::Vector3d::Zero(); // Newell
  for (int i = 0; i < n; ++i)
    normal += corners[i].cross(corners[(i + 1) % n]);
  normal.normalize();
  const Eigen::Vector3d axis = std::abs(normal.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d u = normal.cross(axis).normalized(), w = normal.cross(u);
  Eigen::Vector2d small[8]; // the common polygons need no allocation
  std::vector<Eigen::Vector2d> large(n > 8 ? n : 0);
  Eigen::Vector2d* p2 = n > 8 ? large.data() : small;
  for (int i = 0; i < n; ++i)
    p2[i] = {corners[i].dot(u), corners[i].dot(w)};
  if (n == 4) {
    // A quad: the shorter diagonal, when both splits are valid in the plane
    // (the common "beauty" choice, and what most exporters do).
    // (A triangle of three collinear corners is never valid, whatever the
    // rounding of the projection says: a quad with a straight corner, as
    // closing a sliver's slit makes, splits from that corner.)
    auto valid = [&](int a, int b, int c) {
      return orient2d(p2[a], p2[b], p2[c]) > 0 && !collinear3d(corners[a], corners[b], corners[c]);
    };
    const bool split02 = valid(0, 1, 2) && valid(0, 2, 3);
    const bool split13 = valid(1, 2, 3) && valid(1, 3, 0);
    const bool shorter02 = (corners[0] - corners[2]).squaredNorm() <= (corners[1] - corners[3]).squaredNorm();
    if (split02 && (!split13 || shorter02)) {
      tris.push_back({0, 1, 2});
      tris.push_back({0, 2, 3});
      return;
    }
    if (split13) {
      tris.push_back({1, 2, 3});
      tris.push_back({1, 3, 0});
      return;
    }
  }
  std::vector<int> ring(n);
  for (int i = 0; i < n; ++i)
    ring[i] = i;
  while (ring.size() > 3) {
    const int m = static_cast<int>(ring.size());
    int ear = -1;
    for (int i = 0; i < m && ear < 0; ++i) {
      const int a = ring[(i + m - 1) % m], b = ring[i], c = ring[(i + 1) % m];
      if (orient2d(p2[a], p2[b], p2[c]) <= 0 || collinear3d(corners[a], corners[b], corners[c]))
        continue;
      bool empty = true;
      for (int j : ring) {
        if (j == a || j == b || j == c)
          continue;
        if (orient2d(p2[a], p2[b], p2[j]) >= 0 && orient2d(p2[b], p2[c], p2[j]) >= 0 &&
            orient2d(p2[c], p2[a], p2[j]) >= 0) {
          empty = false;
          break;
        }
      }
      if (empty)
        ear = i;
    }
    if (ear < 0)
      ear = 0;
    tris.push_back({ring[(ear + m - 1) % m], ring[ear], ring[(ear + 1) % m]});
    ring.erase(ring.begin() + ear);
  }
  tris.push_back({ring[0], ring[1], ring[2]});
}

TriClosest closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Real-Time Collision Detection, section 5.1.5 (Ericson), keeping the
  // barycentric coordinates of every Voronoi region.
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0)
    return {a, {1, 0, 0}};
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3)
    return {b, {0, 1, 0}};
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return {a + v * ab, {1 - v, v, 0}};
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6)
    return {c, {0, 0, 1}};
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return {a + w * ac, {1 - w, 0, w}};
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return {b + w * (c - b), {0, 1 - w, w}};
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return {a + ab * v + ac * w, {1 - v - w, v, w}};
}

} // namespace curvenet::detail
