// Training poses from the skeleton alone (bake.hpp): each joint bent both
// ways about the two axes across its bone and twisted about it, one joint at
// a time, then random poses that move every joint at once. Each is a set of
// skinning matrices built by forward kinematics in the rest frame: a joint's
// matrix is its parent's times a rotation about the joint's rest position.

#include "curvenet/bake.hpp"

#include "curvenet/errors.hpp"
#include "core/memory_budget.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <map>
#include <numbers>
#include <random>

namespace curvenet {
namespace {

struct Frame {
  Vec3 at, along, across1, across2;
};

/// Each joint's rest position and bone direction (towards its children, or
/// on from its parent for a leaf), with two axes across the bone.
std::vector<Frame> joint_frames(const std::vector<Joint>& joints) {
  std::map<std::string, int> index;
  for (size_t j = 0; j < joints.size(); ++j)
    index[joints[j].name] = static_cast<int>(j);
  std::vector<Frame> f(joints.size());
  std::vector<Vec3> child_sum(joints.size(), Vec3::Zero());
  std::vector<int> children(joints.size(), 0);
  for (size_t j = 0; j < joints.size(); ++j) {
    f[j].at = joints[j].bind.block<3, 1>(0, 3);
    if (joints[j].parent) {
      const auto it = index.find(*joints[j].parent);
      if (it != index.end()) {
        child_sum[static_cast<size_t>(it->second)] += f[j].at;
        ++children[static_cast<size_t>(it->second)];
      }
    }
  }
  for (size_t j = 0; j < joints.size(); ++j) {
    Vec3 d = Vec3::Zero();
    if (children[j] > 0)
      d = child_sum[j] / children[j] - f[j].at;
    if (d.norm() == 0 && joints[j].parent) {
      const auto it = index.find(*joints[j].parent);
      if (it != index.end())
        d = f[j].at - f[static_cast<size_t>(it->second)].at;
    }
    if (!(d.norm() > 0))
      d = joints[j].bind.block<3, 1>(0, 1); // no bone: the joint's own y axis
    f[j].along = d.normalized();
    f[j].across1 = f[j].along.unitOrthogonal();
    f[j].across2 = f[j].along.cross(f[j].across1);
  }
  return f;
}

Mat4 rotation_about(const Vec3& at, const Vec3& axis, double degrees) {
  Mat4 m = Mat4::Identity();
  const Eigen::Matrix3d r = Eigen::AngleAxisd(degrees * std::numbers::pi / 180, axis.normalized()).toRotationMatrix();
  m.block<3, 3>(0, 0) = r;
  m.block<3, 1>(0, 3) = at - r * at;
  return m;
}

/// Skinning matrices from one rest-frame rotation per joint (identity for none): M_j = M_parent A_j.
std::vector<Mat4> forward(const std::vector<Joint>& joints, const std::vector<Mat4>& local) {
  std::map<std::string, size_t> index;
  std::vector<Mat4> M(joints.size(), Mat4::Identity());
  for (size_t j = 0; j < joints.size(); ++j) {
    const auto it = joints[j].parent ? index.find(*joints[j].parent) : index.end();
    M[j] = (it != index.end() ? M[it->second] : Mat4::Identity()) * local[j];
    index[joints[j].name] = j;
  }
  return M;
}

} // namespace

std::vector<std::vector<Mat4>> training_poses(const std::vector<Joint>& joints, const TrainingPoses& options) {
  for (size_t j = 0; j < joints.size(); ++j)
    if (!joints[j].bind.allFinite())
      throw InputError("skeleton", joints[j].name, "has a non-finite bind matrix");
  for (const double bend : options.bends)
    if (!std::isfinite(bend))
      throw InputError("training poses", "bends", "must be finite angles");
  if (!std::isfinite(options.twist) || !std::isfinite(options.random_bend) || !std::isfinite(options.random_twist))
    throw InputError("training poses", "twist", "the twist and the random angles must be finite");
  if (options.random_poses < 0)
    throw InputError("training poses", "random_poses", "must not be negative");
  const size_t nj = joints.size();
  // Each pose holds a matrix per joint, and each joint makes ten poses:
  // refused past the memory budget (half the machine's, at least 4 GB)
  // rather than run out of memory.
  const double count = static_cast<double>(nj) * (4 * static_cast<double>(options.bends.size()) + 2) +
                       static_cast<double>(options.random_poses);
  if (const double bytes = count * static_cast<double>(nj) * sizeof(Mat4); bytes > detail::memory_budget())
    throw InputError("skeleton", std::to_string(nj) + " joints",
                     "its " + std::to_string(static_cast<long long>(count)) + " training poses would take " +
                         std::to_string(static_cast<long long>(bytes / 1e9)) +
                         " GB: bake the harmonic weights (--weights harmonic), or fit over clips alone (--fit)");
  const std::vector<Frame> f = joint_frames(joints);
  std::vector<std::vector<Mat4>> poses;
  // One joint at a time: bent both ways about both axes across the bone, and twisted.
  for (size_t j = 0; j < nj; ++j) {
    for (const double bend : options.bends)
      for (const double sign : {1.0, -1.0})
        for (const Vec3* axis : {&f[j].across1, &f[j].across2}) {
          std::vector<Mat4> local(nj, Mat4::Identity());
          local[j] = rotation_about(f[j].at, *axis, sign * bend);
          poses.push_back(forward(joints, local));
        }
    for (const double sign : {1.0, -1.0}) {
      std::vector<Mat4> local(nj, Mat4::Identity());
      local[j] = rotation_about(f[j].at, f[j].along, sign * options.twist);
      poses.push_back(forward(joints, local));
    }
  }
  // Every joint at once, at random (a fixed seed: the same poses every run).
  std::mt19937 rng(options.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0), turn(0.0, 2 * std::numbers::pi);
  for (int p = 0; p < options.random_poses; ++p) {
    std::vector<Mat4> local(nj, Mat4::Identity());
    for (size_t j = 0; j < nj; ++j) {
      const double a = turn(rng);
      const Vec3 across = std::cos(a) * f[j].across1 + std::sin(a) * f[j].across2;
      local[j] = rotation_about(f[j].at, across, options.random_bend * unit(rng)) *
                 rotation_about(f[j].at, f[j].along, options.random_twist * unit(rng));
    }
    poses.push_back(forward(joints, local));
  }
  return poses;
}

} // namespace curvenet
