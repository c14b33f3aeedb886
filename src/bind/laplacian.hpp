#pragma once
// Laplacians of the cut mesh. Cut faces are general polygons and real meshes
// have obtuse triangles, where plain cotangent weights turn negative and the
// maximum principle fails. Two choices:
//  - Uniform: weight 1 on every edge of the cut mesh.
//  - IntrinsicDelaunay: the cut faces are triangulated, the triangulation is
//    flipped to an intrinsic Delaunay triangulation (edge lengths only, the
//    surface does not move), and cotangent weights are taken from it; they
//    are non-negative on every interior edge.

#include "cut/cut_mesh.hpp"

#include <Eigen/Sparse>

namespace curvenet::detail {

enum class LaplacianKind { Uniform, IntrinsicDelaunay };

struct LaplacianStats {
  int triangles = 0;
  int negative_before = 0; ///< edges with a negative cotangent weight before the flips
  int negative_after = 0;  ///< after them (boundary edges only can stay negative)
  int flips = 0;
};

/// The #V x #V matrix with L_ij = -w_ij and L_ii = sum_j w_ij: symmetric,
/// positive semi-definite, rows summing to zero.
Eigen::SparseMatrix<double> cut_mesh_laplacian(const CutMesh& mesh, LaplacianKind kind, LaplacianStats* stats = nullptr);

/// Cotangent Laplacian of a triangle soup with the same conventions, after
/// intrinsic Delaunay flips (exposed for tests).
Eigen::SparseMatrix<double> intrinsic_delaunay_laplacian(int num_vertices, const std::vector<Eigen::Vector3d>& positions,
                                                         const std::vector<std::array<int, 3>>& triangles,
                                                         LaplacianStats* stats = nullptr);

} // namespace curvenet::detail
