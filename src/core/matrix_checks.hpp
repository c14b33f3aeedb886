#pragma once
// Checks on the affine 4x4 matrices that come in from files and options:
// bind matrices, frames, inverse bind matrices. A singular one would turn
// into NaN positions downstream.

#include <Eigen/Core>

namespace curvenet::detail {

/// Finite, and its 3x3 part invertible: its smallest singular value is
/// more than Tolerances::invertible_rel of its largest.
bool invertible(const Eigen::Matrix4d& m);
/// Invertible, and scaling by no more than Tolerances::max_matrix_scale nor
/// less than its inverse: a joint's bind matrix (a rig's frame may scale
/// by anything, as its mesh's units do).
bool bounded_scale(const Eigen::Matrix4d& m);

/// Invertible, and its 3x3 part a rotation (or reflection) times one
/// uniform scale, to Tolerances::similarity_rel.
bool similarity(const Eigen::Matrix4d& m);

} // namespace curvenet::detail
