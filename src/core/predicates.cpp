#include "core/predicates.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

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
} // namespace

int orient2d(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return sign_of(CGAL::orientation(p2(a), p2(b), p2(c)));
}

int orient3d(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  // CGAL's orientation(p,q,r,s) is POSITIVE when s lies on the side of the
  // plane (p,q,r) that (q-p)x(r-p) points to (tested in predicates_test).
  return sign_of(CGAL::orientation(p3(a), p3(b), p3(c), p3(d)));
}

bool collinear3d(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return CGAL::collinear(p3(a), p3(b), p3(c));
}

} // namespace curvenet::detail
