// Least squares over the simplex (convex_least_squares.hpp).

#include "core/convex_least_squares.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <vector>

namespace curvenet::detail {

double quadratic_objective(const Eigen::MatrixXd& G, const Eigen::VectorXd& h, const Eigen::VectorXd& x) {
  return 0.5 * x.dot(G * x) - h.dot(x);
}

Eigen::VectorXd convex_least_squares(const Eigen::MatrixXd& G, const Eigen::VectorXd& h, Eigen::VectorXd x) {
  const int n = static_cast<int>(h.size());
  if (n == 0)
    return x;
  x = x.cwiseMax(0.0);
  if (!(x.sum() > 0))
    x.setConstant(1.0 / n);
  x /= x.sum();
  const double tol = 1e-13 * (G.cwiseAbs().maxCoeff() + h.cwiseAbs().maxCoeff());
  std::vector<bool> free(n);
  for (int i = 0; i < n; ++i)
    free[i] = x[i] > 0;
  std::vector<int> F;
  // Each pass either frees a weight (the objective falls strictly) or fixes
  // one at zero; the bound keeps rounding from cycling.
  for (int pass = 0; pass < 8 * n + 8; ++pass) {
    F.clear();
    for (int i = 0; i < n; ++i)
      if (free[i])
        F.push_back(i);
    const int m = static_cast<int>(F.size());
    // The minimum on the free weights with their sum one: [G_FF 1; 1' 0] [z; nu] = [h_F; 1].
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(m + 1, m + 1);
    Eigen::VectorXd r(m + 1);
    for (int a = 0; a < m; ++a) {
      for (int b = 0; b < m; ++b)
        K(a, b) = G(F[a], F[b]);
      K(a, m) = K(m, a) = 1;
      r[a] = h[F[a]];
    }
    r[m] = 1;
    const Eigen::VectorXd z = K.fullPivLu().solve(r);
    if (!z.allFinite())
      break;
    bool inside = true;
    for (int a = 0; a < m; ++a)
      inside = inside && z[a] >= 0;
    if (inside) {
      x.setZero();
      for (int a = 0; a < m; ++a)
        x[F[a]] = z[a];
      // A fixed weight enters where the objective falls along it faster than
      // along the free ones (its bound's multiplier is negative).
      const Eigen::VectorXd g = G * x - h;
      const double level = -z[m]; // the free weights' common gradient
      int enter = -1;
      for (int i = 0; i < n; ++i)
        if (!free[i] && g[i] - level < -tol && (enter < 0 || g[i] < g[enter]))
          enter = i;
      if (enter < 0)
        break;
      free[enter] = true;
      continue;
    }
    // Towards z, as far as the first free weight that reaches zero; fix it there.
    double alpha = 1;
    int block = -1;
    for (int a = 0; a < m; ++a)
      if (z[a] < 0) {
        const double t = x[F[a]] / (x[F[a]] - z[a]);
        if (t < alpha)
          alpha = t, block = F[a];
      }
    for (int a = 0; a < m; ++a)
      x[F[a]] += alpha * (z[a] - x[F[a]]);
    if (block >= 0)
      x[block] = 0;
    for (int i : F)
      if (x[i] <= 0)
        x[i] = 0, free[i] = false;
  }
  x = x.cwiseMax(0.0);
  const double s = x.sum();
  if (s > 0)
    x /= s;
  else
    x.setConstant(1.0 / n);
  return x;
}

} // namespace curvenet::detail
