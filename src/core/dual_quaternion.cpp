#include "core/dual_quaternion.hpp"

#include <Eigen/SVD>

#include <cmath>

namespace curvenet::detail {

Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& a) {
  // Newton's iteration for the polar factor, X <- (X + X^-T) / 2, with X^-T
  // the cofactor matrix over the determinant. It converges fast from a blend
  // of rotations; a matrix far from one goes through the SVD.
  const double scale = a.norm() / std::sqrt(3.0);
  if (scale > 0 && a.determinant() > 1e-3 * scale * scale * scale) {
    Eigen::Matrix3d x = a / scale;
    for (int k = 0; k < 30; ++k) {
      Eigen::Matrix3d cof;
      cof.col(0) = x.col(1).cross(x.col(2));
      cof.col(1) = x.col(2).cross(x.col(0));
      cof.col(2) = x.col(0).cross(x.col(1));
      const double det = x.col(0).dot(cof.col(0));
      const Eigen::Matrix3d next = 0.5 * (x + cof / det);
      const double change = (next - x).cwiseAbs().maxCoeff();
      x = next;
      if (change < 1e-13)
        break;
    }
    return x;
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1 : 1;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

} // namespace curvenet::detail
