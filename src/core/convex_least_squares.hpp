#pragma once
// Least squares over the simplex: the weights of one vertex of a linear
// skin, non-negative and summing to one, fitted to where a deformation puts
// it (bake/weights.cpp, and the anchor in bench/weights_anchor.cpp).

#include <Eigen/Core>

namespace curvenet::detail {

/// The minimum of 1/2 x'Gx - h'x over x >= 0, sum(x) = 1 (G symmetric
/// positive definite, as the normal equations A'A + a ridge are), from the
/// feasible start `x` (non-negative, summing to one), by a primal active-set
/// method: on the free weights the equality-constrained minimum, a step back
/// to the first weight that would turn negative, and a weight freed where the
/// bounds' multipliers say it lowers the objective. Small dense problems (a
/// vertex's joints). Returns x on the simplex.
Eigen::VectorXd convex_least_squares(const Eigen::MatrixXd& G, const Eigen::VectorXd& h, Eigen::VectorXd x);

/// 1/2 x'Gx - h'x.
double quadratic_objective(const Eigen::MatrixXd& G, const Eigen::VectorXd& h, const Eigen::VectorXd& x);

} // namespace curvenet::detail
