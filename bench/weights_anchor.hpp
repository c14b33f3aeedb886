#pragma once
// The anchor for fitted bakes (docs/bake.md): the weights-only step of
// smooth skinning decomposition with rigid bones (Le and Deng, SIGGRAPH Asia
// 2012), as Electronic Arts' Dem Bones runs it when the bones' transforms are
// given. Written here from the paper and from reading Dem Bones; no code of
// it is copied. Used by bench/bake_bench only.

#include "curvenet/deform.hpp"

#include <span>
#include <vector>

namespace curvenet::bench {

struct AnchorOptions {
  int nnz = 4;                 ///< influences per vertex
  int iterations = 90;         ///< weight updates: Dem Bones' compute() with the transforms fixed runs nIters (30) times nWeightsIters (3)
  double smooth = 1e-4;        ///< pull towards the Laplacian-smoothed weights (weightsSmooth)
  double smooth_step = 1;      ///< the smoothing's step (weightsSmoothStep)
  /// Grow the rigid labels across the mesh from each joint's best vertex,
  /// as Dem Bones does (each joint's label then covers one connected
  /// patch); false keeps each vertex's own best joint.
  bool grow_labels = true;
};

/// Weights per vertex (rows: vertices; each a list of (joint, weight), at
/// most `nnz`, non-negative, summing to 1) such that linear blend skinning
/// with `transforms[f]` (one skinning matrix per joint) moves `rest` closest
/// to `frames[f]`, over all frames; smoothed over the mesh `faces` (vertex
/// indices into `rest`, any polygon size).
/// 1. Each vertex starts rigidly bound to the joint that fits it best, and
///    (grow_labels) the labels are grown from each joint's best vertex
///    across the mesh, cheapest first.
/// 2. Each update smooths the weights implicitly with a Laplacian whose edge
///    weights fall with how much the edge's length changes over the frames,
///    picks each vertex's `nnz` largest smoothed weights, and solves a
///    non-negative least squares with the weights summing to one, pulled by
///    `smooth` towards the smoothed weights.
std::vector<std::vector<std::pair<int, double>>> anchor_weights(std::span<const Vec3> rest,
                                                               const std::vector<std::vector<int>>& faces,
                                                               const std::vector<std::vector<Mat4>>& transforms,
                                                               const std::vector<std::vector<Vec3>>& frames,
                                                               const AnchorOptions& options = {});

} // namespace curvenet::bench
