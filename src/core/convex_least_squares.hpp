#pragma once
// Least squares over the simplex: the weights of one vertex of a linear
// skin, non-negative and summing to one, fitted to where a deformation puts
// it (bake/weights.cpp, and the anchor in bench/weights_anchor.cpp).

#include <Eigen/Core>

#include <span>

namespace curvenet::detail {

/// The minimum of 1/2 x'Gx - h'x over x >= 0, sum(x) = 1 (G symmetric
/// positive definite, as the normal equations A'A + a ridge are), from the
/// feasible start `x` (non-negative, summing to one), by a primal active-set
/// method: on the free weights the equality-constrained minimum, a step back
/// to the first weight that would turn negative, and a weight freed where the
/// bounds' multipliers say it lowers the objective. Small dense problems (a
/// vertex's joints). Returns x on the simplex.
Eigen::VectorXd convex_least_squares(const Eigen::MatrixXd& G, const Eigen::VectorXd& h, Eigen::VectorXd x);

/// convex_least_squares from `start`; where more than k weights come out
/// non-zero, solved again on the k largest of that solution and on the k
/// largest of `start`, keeping whichever has the smaller objective (a
/// vertex's fit to at most k joints: bake/weights.cpp says why both).
Eigen::VectorXd convex_least_squares_top_k(const Eigen::MatrixXd& G, const Eigen::VectorXd& h,
                                           const Eigen::VectorXd& start, int k);

/// 1/2 x'Gx - h'x.
double quadratic_objective(const Eigen::MatrixXd& G, const Eigen::VectorXd& h, const Eigen::VectorXd& x);

/// The point of the convex hull of `points` nearest `x`: its convex weights
/// on the points and its distance from x. A linear skin puts a vertex at a
/// convex blend of where its joints move it, so this is the closest any
/// linear skin of those joints can come to `x` at that pose, whatever its
/// weights (the floor a baked skin's fidelity report states). Empty points:
/// no weights and an infinite distance; a non-finite coordinate: a NaN
/// distance. Exact to rounding relative to the points' spread about x (the
/// minimum-norm-point algorithm, checked against every subset of up to four
/// points where its steps stall, for up to 20 points).
struct HullPoint {
  Eigen::VectorXd weights;
  double distance = 0;
};
HullPoint nearest_in_hull(std::span<const Eigen::Vector3d> points, const Eigen::Vector3d& x);

} // namespace curvenet::detail
