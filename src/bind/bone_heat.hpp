#pragma once
// Bone heat (Baran and Popovic 2007; Blender's "With Automatic Weights"):
// per joint, a smooth weight over the cut mesh that is 1 next to the joint's
// bones and falls off where the neighbouring bones take over. It solves
//
//     (L + M H) w_j = M H p_j
//
// with L the cut mesh's cotangent Laplacian (laplacian.hpp), M the lumped
// vertex areas, H = c / d^2 where d is the distance to the nearest bone the
// vertex sees (the segment to it crosses no triangle), and p_j the weight
// of joint j at the vertex by the weight rule (weights.hpp) on that bone: so
// a bone is rigid in its middle and blends into the next over the rule's
// zone about each joint, as the net's own nodes do. The scale cancels
// (M / d^2 has no unit), so a hand in metres and a tube in centimetres get
// the same weights.
//
// It is a field of the input surface, whatever the net. The binding uses it
// inside the regions (binding.cpp, docs/deform.md): the net decides the
// curves, the bones the inside of a region.

#include "curvenet/rig.hpp"
#include "curvenet/weights.hpp"
#include "cut/cut_mesh.hpp"

#include <Eigen/Sparse>

#include <vector>

namespace curvenet::detail {

class TraceMesh;

struct BoneHeatInput {
  const CutMesh* cut = nullptr;                           ///< the input surface (CutMesh::from_surface)
  const Eigen::SparseMatrix<double>* laplacian = nullptr; ///< of `cut`, L_ii = sum_j w_ij
  const TraceMesh* surface = nullptr;                     ///< the input surface, for what a vertex sees
  const std::vector<Joint>* joints = nullptr;             ///< in mesh space
  /// Per joint: whether it takes part. A joint's bones run to each of its
  /// children (taking part or not); a joint with none is a point.
  std::vector<char> deforming;
  AutoWeightOptions rule; ///< how a bone's weight passes to the next at a joint
  /// Weights below this are dropped (and the rest renormalised), so that a
  /// vertex keeps the joints that matter to it and not every joint's tail.
  double floor = 0.01;
};

struct BoneHeat {
  /// Per joint: its weight at every cut-mesh vertex, or empty for a joint
  /// that takes no part. At each vertex the weights sum to 1.
  std::vector<Eigen::VectorXd> weight;
  /// Vertices of parts of the surface that see no bone at all: they take
  /// their nearest bone, seen or not.
  int blind = 0;
};

/// \pre in.deforming has a joint that takes part.
BoneHeat bone_heat(const BoneHeatInput& in);

} // namespace curvenet::detail
