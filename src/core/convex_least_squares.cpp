// Least squares over the simplex (convex_least_squares.hpp).

#include "core/convex_least_squares.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <limits>
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

HullPoint nearest_in_hull(std::span<const Eigen::Vector3d> points, const Eigen::Vector3d& x) {
  // Wolfe's minimum-norm-point algorithm (1976) on the points relative to x,
  // so that coordinates far from the origin cost no digits. It keeps a set
  // of affinely independent points (at most four in 3D) whose hull holds
  // the current point y: it adds the point that lies furthest along -y,
  // moves to the nearest point of the new set's affine hull, and steps back
  // to the set's hull, dropping points, while that nearest point is not
  // inside it. The distances fall strictly, so no set repeats.
  HullPoint out;
  const int n = static_cast<int>(points.size());
  if (n == 0) {
    out.distance = std::numeric_limits<double>::infinity();
    return out;
  }
  std::vector<Eigen::Vector3d> q(points.size());
  double scale = 0;
  for (size_t i = 0; i < q.size(); ++i) {
    q[i] = points[i] - x;
    scale = std::max(scale, q[i].squaredNorm());
  }
  std::vector<int> S;     // the set
  std::vector<double> l;  // y's weights on it
  int first = 0;
  for (int i = 1; i < n; ++i)
    if (q[static_cast<size_t>(i)].squaredNorm() < q[static_cast<size_t>(first)].squaredNorm())
      first = i;
  S.push_back(first);
  l.push_back(1.0);
  Eigen::Vector3d y = q[static_cast<size_t>(first)];
  // The nearest point to the origin of the affine hull of S, as weights summing to one.
  auto affine = [&](std::vector<double>& a) {
    const int m = static_cast<int>(S.size());
    a.assign(static_cast<size_t>(m), 0.0);
    if (m == 1) {
      a[0] = 1;
      return;
    }
    Eigen::MatrixXd E(3, m - 1);
    const Eigen::Vector3d& o = q[static_cast<size_t>(S[0])];
    for (int i = 1; i < m; ++i)
      E.col(i - 1) = q[static_cast<size_t>(S[static_cast<size_t>(i)])] - o;
    const Eigen::VectorXd c = E.colPivHouseholderQr().solve(-o);
    a[0] = 1 - c.sum();
    for (int i = 1; i < m; ++i)
      a[static_cast<size_t>(i)] = c[i - 1];
  };
  const double eps = 1e-14 * scale;
  std::vector<double> a;
  for (int major = 0; major < 4 * n + 16; ++major) {
    int j = 0;
    for (int i = 1; i < n; ++i)
      if (q[static_cast<size_t>(i)].dot(y) < q[static_cast<size_t>(j)].dot(y))
        j = i;
    // y is the nearest point when no point lies beyond the plane through it across y.
    if (y.squaredNorm() - q[static_cast<size_t>(j)].dot(y) <= eps ||
        std::find(S.begin(), S.end(), j) != S.end() || S.size() == 4)
      break;
    S.push_back(j);
    l.push_back(0.0);
    for (int minor = 0; minor < 8; ++minor) {
      affine(a);
      bool inside = true;
      for (const double ai : a)
        inside = inside && ai > 0;
      if (inside) {
        l = a;
        break;
      }
      // Towards the affine minimum as far as the set's hull goes; drop the weights that reach zero.
      double theta = 1;
      for (size_t i = 0; i < a.size(); ++i)
        if (a[i] <= 0 && l[i] - a[i] > 0)
          theta = std::min(theta, l[i] / (l[i] - a[i]));
      for (size_t i = 0; i < a.size(); ++i)
        l[i] += theta * (a[i] - l[i]);
      std::vector<int> keptS;
      std::vector<double> keptl;
      for (size_t i = 0; i < S.size(); ++i)
        if (l[i] > 1e-15) {
          keptS.push_back(S[i]);
          keptl.push_back(l[i]);
        }
      if (keptS.empty()) {
        keptS.push_back(S.back());
        keptl.push_back(1.0);
      }
      S = std::move(keptS);
      l = std::move(keptl);
    }
    double sum = 0;
    for (const double li : l)
      sum += li;
    Eigen::Vector3d next = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < S.size(); ++i) {
      l[i] /= sum;
      next += l[i] * q[static_cast<size_t>(S[i])];
    }
    if (!(next.squaredNorm() < y.squaredNorm())) { // rounding: no progress left
      if (next.squaredNorm() <= y.squaredNorm())
        y = next;
      break;
    }
    y = next;
  }
  out.weights = Eigen::VectorXd::Zero(n);
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < S.size(); ++i) {
    out.weights[S[i]] = l[i];
    p += l[i] * q[static_cast<size_t>(S[i])];
  }
  out.distance = p.norm();
  return out;
}

} // namespace curvenet::detail
