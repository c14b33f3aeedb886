#pragma once
// Dual quaternions for skinning (Kavan, Collins, Zara and O'Sullivan 2008):
// a joint matrix M = [R S | t] is split into its rigid part (R, t), held as
// a unit dual quaternion q0 + e q1 with q1 = t q0 / 2, and its stretch
// S = R^T A. A blend of joints is the normalised, hemisphere-aligned sum of
// their dual quaternions, applied after the blend of their stretches. It
// turns a twist instead of shrinking it, and is exact at rest and for rigid
// motions. Used by the baseline skinning (skeleton/skin.cpp, bake/weights.cpp)
// and by the net's deformation (bind/).

#include "curvenet/rig.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace curvenet::detail {

/// The nearest rotation to a 3x3 matrix (its polar factor; the rotation of
/// its SVD, when the matrix is far from one).
Eigen::Matrix3d nearest_rotation(const Eigen::Matrix3d& a);

/// One joint matrix split for blending.
struct DualJoint {
  Eigen::Vector4d real = Eigen::Vector4d(0, 0, 0, 1); ///< (x, y, z, w) of q0
  Eigen::Vector4d dual = Eigen::Vector4d::Zero();     ///< (x, y, z, w) of q1
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d stretch = Eigen::Matrix3d::Identity(); ///< R^T A
  bool rigid = true;                                     ///< the stretch is the identity (to rounding)
};

inline DualJoint split_joint(const Mat4& m) {
  DualJoint d;
  const Eigen::Matrix3d a = m.topLeftCorner<3, 3>();
  d.rotation = nearest_rotation(a);
  d.stretch = d.rotation.transpose() * a;
  d.rigid = (d.stretch - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-12;
  const Eigen::Quaterniond q0 = Eigen::Quaterniond(d.rotation).normalized();
  const Eigen::Vector3d t = m.block<3, 1>(0, 3);
  const Eigen::Quaterniond q1(0.5 * (Eigen::Quaterniond(0, t.x(), t.y(), t.z()) * q0).coeffs());
  d.real = q0.coeffs();
  d.dual = q1.coeffs();
  return d;
}

/// Accumulates a weighted blend of joints and applies it to points. The
/// hemisphere is the heaviest joint's: every quaternion goes the short way
/// round from it. (Aligned to whichever joint came first, a light joint
/// turned far from the heavy ones, a wrist under a curled finger, split the
/// heavy ones onto opposite sides, and their sum cancelled.)
class DualBlend {
public:
  void clear() {
    entries_.clear();
    done_ = false;
  }
  void add(const DualJoint& j, double w) {
    entries_.push_back({&j, w});
    done_ = false;
  }
  /// False when the rotations cancel (no direction to normalise).
  [[nodiscard]] bool valid() const {
    sum();
    return b0_.norm() > 1e-12;
  }
  /// The blended rotation (valid() must hold).
  [[nodiscard]] Eigen::Quaterniond rotation() const {
    sum();
    Eigen::Quaterniond q;
    q.coeffs() = b0_ / b0_.norm();
    return q;
  }
  /// The blend as one matrix: apply(p) is matrix() * p (valid() must hold).
  [[nodiscard]] Mat4 matrix() const {
    const Unit u = unit();
    Mat4 m = Mat4::Identity();
    m.topLeftCorner<3, 3>() = rigid_ ? u.q0.toRotationMatrix() : Eigen::Matrix3d(u.q0.toRotationMatrix() * stretch_);
    m.block<3, 1>(0, 3) = u.t;
    return m;
  }
  [[nodiscard]] Eigen::Vector3d apply(const Eigen::Vector3d& p) const {
    const Unit u = unit();
    const Eigen::Vector3d x = rigid_ ? p : Eigen::Vector3d(stretch_ * p);
    return u.q0 * x + u.t;
  }

private:
  struct Unit {
    Eigen::Quaterniond q0; ///< the blend's rotation
    Eigen::Vector3d t;     ///< and translation
  };
  /// The blend normalised to a unit dual quaternion, as a rotation and a translation.
  [[nodiscard]] Unit unit() const {
    sum();
    const double n = b0_.norm();
    Eigen::Quaterniond q0, q1;
    q0.coeffs() = b0_ / n;
    q1.coeffs() = b1_ / n;
    // The translation of a unit dual quaternion: 2 (q1 q0*) minus its
    // component along q0 that normalisation leaves: t = 2 (w0 v1 - w1 v0 + v0 x v1).
    const Eigen::Vector3d v0 = q0.vec(), v1 = q1.vec();
    return {q0, 2 * (q0.w() * v1 - q1.w() * v0 + v0.cross(v1))};
  }
  struct Entry {
    const DualJoint* joint;
    double w;
  };
  void sum() const {
    if (done_)
      return;
    b0_.setZero();
    b1_.setZero();
    stretch_.setZero();
    rigid_ = true;
    const Entry* pivot = nullptr;
    for (const Entry& e : entries_)
      if (!pivot || e.w > pivot->w)
        pivot = &e;
    for (const Entry& e : entries_) {
      const double s = pivot->joint->real.dot(e.joint->real) < 0 ? -e.w : e.w; // the short way round
      b0_ += s * e.joint->real;
      b1_ += s * e.joint->dual;
      stretch_ += e.w * e.joint->stretch;
      rigid_ = rigid_ && e.joint->rigid;
    }
    done_ = true;
  }
  std::vector<Entry> entries_;
  mutable Eigen::Vector4d b0_ = Eigen::Vector4d::Zero(), b1_ = Eigen::Vector4d::Zero();
  mutable Eigen::Matrix3d stretch_ = Eigen::Matrix3d::Zero();
  mutable bool rigid_ = true, done_ = false;
};

} // namespace curvenet::detail
