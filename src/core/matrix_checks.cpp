#include "core/matrix_checks.hpp"

#include "core/tolerances.hpp"

#include <Eigen/SVD>

namespace curvenet::detail {

bool invertible(const Eigen::Matrix4d& m) {
  if (!m.allFinite())
    return false;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.topLeftCorner<3, 3>());
  const auto& s = svd.singularValues();
  return s(0) > 0 && s(2) > Tolerances::invertible_rel * s(0);
}

bool bounded_scale(const Eigen::Matrix4d& m) {
  if (!invertible(m))
    return false;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.topLeftCorner<3, 3>());
  const auto& s = svd.singularValues();
  return s(0) <= Tolerances::max_matrix_scale && s(2) >= 1 / Tolerances::max_matrix_scale;
}

bool similarity(const Eigen::Matrix4d& m) {
  if (!invertible(m))
    return false;
  // Measured on the matrix divided by its largest entry: a scale of 1e154
  // squared overflowed, and a similarity was refused as not one.
  const Eigen::Matrix3d a = m.topLeftCorner<3, 3>() / m.topLeftCorner<3, 3>().cwiseAbs().maxCoeff();
  const Eigen::Matrix3d g = a.transpose() * a;
  const double s2 = g.trace() / 3;
  return (g - s2 * Eigen::Matrix3d::Identity()).norm() <= Tolerances::similarity_rel * s2;
}

} // namespace curvenet::detail
