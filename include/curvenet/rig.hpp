#pragma once
/// \file rig.hpp
/// The logical Curvenet: nodes, profiles, skeleton and node weights, as in
/// the rig file format (`docs/rig-format.md`). It never holds a mesh index.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace curvenet {

using Mat4 = Eigen::Matrix4d;

enum class Coverage { Auto, Full, Local };
const char* to_string(Coverage c);

struct Node {
  std::string id;
  Eigen::Vector3d position;
};

/// The shape of one profile curve, in one of three forms.
struct Curve {
  enum class Kind { Polyline, Bezier, Nurbs };
  Kind kind = Kind::Polyline;
  std::vector<Eigen::Vector3d> points; ///< polyline points, Bezier or NURBS control points
  int degree = 3;                      ///< NURBS only
  std::vector<double> knots;           ///< NURBS only: #points + degree + 1
  std::vector<double> weights;         ///< NURBS only; empty when non-rational
};

struct Profile {
  std::string id;
  std::string from; ///< node id
  std::string to;   ///< node id
  Curve curve;
};

struct Joint {
  std::string name;
  std::optional<std::string> parent;
  Mat4 bind = Mat4::Identity(); ///< rest world transform, acts on column vectors
};

struct Rig {
  Coverage coverage = Coverage::Auto;
  Mat4 frame = Mat4::Identity();
  std::vector<Node> nodes;
  std::vector<Profile> profiles;
  std::vector<Joint> joints;
  bool has_skeleton = false;
  /// node id -> (joint name -> weight)
  std::map<std::string, std::map<std::string, double>> weights;
  /// Top-level extensions (keys starting with `x_`) as JSON text, kept
  /// through a read and a write.
  std::map<std::string, std::string> extensions;

  [[nodiscard]] int node_index(const std::string& id) const; ///< -1 when absent
};

} // namespace curvenet
