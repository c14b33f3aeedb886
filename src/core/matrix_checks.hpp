#pragma once
// Checks on the affine 4x4 matrices that come in from files and options:
// bind matrices, frames, inverse bind matrices. A singular one would turn
// into NaN positions downstream.

#include <Eigen/Core>

namespace curvenet::detail {

/// Finite, and its 3x3 part invertible: its smallest singular value is
/// more than Tolerances::invertible_rel of its largest, and it scales by
/// no more than Tolerances::max_matrix_scale, nor less than its inverse.
bool invertible(const Eigen::Matrix4d& m);

/// Invertible, and its 3x3 part a rotation (or reflection) times one
/// uniform scale, to Tolerances::similarity_rel.
bool similarity(const Eigen::Matrix4d& m);

} // namespace curvenet::detail
