#include "core/predicates.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <cmath>

namespace curvenet::detail {
namespace {
using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
Kernel::Point_2 p2(const Eigen::Vector2d& p) {
  return {p.x(), p.y()};
}
Kernel::Point_3 p3(const Eigen::Vector3d& p) {
  return {p.x(), p.y(), p.z()};
}
int sign_of(CGAL::Orientation o) {
  return o == CGAL::POSITIVE ? 1 : (o == CGAL::NEGATIVE ? -1 : 0);
}
/// The sign of the planar orientation of (a, b, c) where floating point
/// alone is certain of it, 0 where it is not: Shewchuk's static error bound
/// for the 2x2 determinant (ccwerrboundA, Robust Adaptive Floating-Point
/// Geometric Predicates, 1997). Products near the bottom of the double range
/// could underflow, which the bound does not cover: those are left uncertain.
int filtered_orient2d(double ax, double ay, double bx, double by, double cx, double cy) {
  const double left = (ax - cx) * (by - cy), right = (ay - cy) * (bx - cx);
  const double det = left - right;
  const double bound = 3.3306690738754716e-16 * (std::abs(left) + std::abs(right));
  if (!(bound > 1e-280))
    return 0;
  return det > bound ? 1 : (-det > bound ? -1 : 0);
}
} // namespace

int orient2d(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  if (const int s = filtered_orient2d(a.x(), a.y(), b.x(), b.y(), c.x(), c.y()))
    return s;
  return sign_of(CGAL::orientation(p2(a), p2(b), p2(c)));
}

int orient3d(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  // First the determinant in floating point, with Shewchuk's static error
  // bound for it (Robust Adaptive Floating-Point Geometric Predicates,
  // 1997): where its sign is certain, it is the answer; only the rest go to
  // CGAL's exact predicate.
  const double ux = b.x() - a.x(), uy = b.y() - a.y(), uz = b.z() - a.z();
  const double vx = c.x() - a.x(), vy = c.y() - a.y(), vz = c.z() - a.z();
  const double wx = d.x() - a.x(), wy = d.y() - a.y(), wz = d.z() - a.z();
  const double m1 = vy * wz, m2 = vz * wy, m3 = vz * wx, m4 = vx * wz, m5 = vx * wy, m6 = vy * wx;
  const double det = ux * (m1 - m2) + uy * (m3 - m4) + uz * (m5 - m6);
  const double permanent = std::abs(ux) * (std::abs(m1) + std::abs(m2)) + std::abs(uy) * (std::abs(m3) + std::abs(m4)) +
                           std::abs(uz) * (std::abs(m5) + std::abs(m6));
  const double bound = 7.7715611723761027e-16 * permanent;
  if (det > bound)
    return 1;
  if (-det > bound)
    return -1;
  // CGAL's orientation(p,q,r,s) is POSITIVE when s lies on the side of the
  // plane (p,q,r) that (q-p)x(r-p) points to (tested in predicates_test).
  return sign_of(CGAL::orientation(p3(a), p3(b), p3(c), p3(d)));
}

bool collinear3d(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Collinear in space is collinear in each coordinate plane: one plane
  // where the points certainly turn settles it without CGAL.
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    if (filtered_orient2d(a[i], a[j], b[i], b[j], c[i], c[j]) != 0)
      return false;
  }
  return CGAL::collinear(p3(a), p3(b), p3(c));
}

} // namespace curvenet::detail
