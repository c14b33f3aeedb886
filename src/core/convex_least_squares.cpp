// Least squares over the simplex (convex_least_squares.hpp).

#include "core/convex_least_squares.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <limits>
#include <numeric>
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

Eigen::VectorXd convex_least_squares_top_k(const Eigen::MatrixXd& G, const Eigen::VectorXd& h,
                                           const Eigen::VectorXd& start, int k) {
  const int c = static_cast<int>(h.size());
  // The weights on a subset (indices), from the start's, and their objective.
  auto solve = [&](const std::vector<int>& S) {
    const int s = static_cast<int>(S.size());
    Eigen::MatrixXd Gs(s, s);
    Eigen::VectorXd hs(s), xs(s);
    for (int a = 0; a < s; ++a) {
      for (int q = 0; q < s; ++q)
        Gs(a, q) = G(S[a], S[q]);
      hs[a] = h[S[a]];
      xs[a] = start[S[a]];
    }
    xs = convex_least_squares(Gs, hs, xs);
    Eigen::VectorXd full = Eigen::VectorXd::Zero(c);
    for (int a = 0; a < s; ++a)
      full[S[a]] = xs[a];
    return std::pair{full, quadratic_objective(Gs, hs, xs)};
  };
  std::vector<int> all(static_cast<size_t>(c));
  std::iota(all.begin(), all.end(), 0);
  Eigen::VectorXd sol = solve(all).first;
  if ((sol.array() > 0).count() <= k)
    return sol;
  auto largest = [&](const Eigen::VectorXd& by) {
    std::vector<int> order = all;
    std::stable_sort(order.begin(), order.end(), [&](int a, int q) { return by[a] > by[q]; });
    order.resize(static_cast<size_t>(std::min(k, c)));
    return order;
  };
  auto by_fit = solve(largest(sol));
  const auto by_given = solve(largest(start));
  return by_given.second < by_fit.second ? by_given.first : by_fit.first;
}

namespace {

/// The nearest point to the origin of the affine hull of q[S], as weights
/// summing to one (a least squares on the differences, which a repeated or
/// dependent point leaves solvable).
void affine_minimum(const std::vector<Eigen::Vector3d>& q, const std::vector<int>& S, std::vector<double>& a) {
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
}

/// The same nearest point by brute force: every subset of at most four
/// points whose affine minimum has non-negative weights (Caratheodory, in
/// 3D); the nearest. For the rare input where Wolfe's steps stall in
/// rounding.
std::pair<std::vector<int>, std::vector<double>> nearest_by_subsets(const std::vector<Eigen::Vector3d>& q) {
  const int n = static_cast<int>(q.size());
  std::pair<std::vector<int>, std::vector<double>> best;
  double best_d = std::numeric_limits<double>::infinity();
  std::vector<int> S;
  std::vector<double> a;
  auto visit = [&](auto&& self, int from) -> void {
    if (!S.empty()) {
      affine_minimum(q, S, a);
      if (*std::min_element(a.begin(), a.end()) >= 0) {
        Eigen::Vector3d p = Eigen::Vector3d::Zero();
        for (size_t i = 0; i < S.size(); ++i)
          p += a[i] * q[static_cast<size_t>(S[i])];
        if (p.squaredNorm() < best_d)
          best_d = p.squaredNorm(), best = {S, a};
      }
    }
    if (S.size() == 4)
      return;
    for (int i = from; i < n; ++i) {
      S.push_back(i);
      self(self, i + 1);
      S.pop_back();
    }
  };
  visit(visit, 0);
  return best;
}

} // namespace

HullPoint nearest_in_hull(std::span<const Eigen::Vector3d> points, const Eigen::Vector3d& x) {
  // Wolfe's minimum-norm-point algorithm (1976) on the points relative to x,
  // so that coordinates far from the origin cost no digits. It keeps a set
  // of affinely independent points (at most four in 3D) whose hull holds
  // the current point y: it adds the point that lies furthest along -y,
  // moves to the nearest point of the new set's affine hull, and steps back
  // to the set's hull, dropping the point whose weight reaches zero first,
  // while that nearest point is not inside it. The distances fall, so no set
  // repeats; the best point met is kept, and checked at the end.
  HullPoint out;
  const int n = static_cast<int>(points.size());
  if (n == 0) {
    out.distance = std::numeric_limits<double>::infinity();
    return out;
  }
  bool finite = x.allFinite();
  for (const auto& p : points)
    finite = finite && p.allFinite();
  if (!finite) {
    out.weights = Eigen::VectorXd::Constant(n, 1.0 / n);
    out.distance = std::numeric_limits<double>::quiet_NaN();
    return out;
  }
  std::vector<Eigen::Vector3d> q(points.size());
  double scale = 0;
  for (size_t i = 0; i < q.size(); ++i) {
    q[i] = points[i] - x;
    scale = std::max(scale, q[i].lpNorm<Eigen::Infinity>());
  }
  if (!(scale > 0)) { // every point at x
    out.weights = Eigen::VectorXd::Unit(n, 0);
    return out;
  }
  for (auto& p : q)
    p /= scale; // unit size: the tolerance is relative and nothing overflows
  std::vector<int> S;    // the set
  std::vector<double> l; // y's weights on it
  int first = 0;
  for (int i = 1; i < n; ++i)
    if (q[static_cast<size_t>(i)].squaredNorm() < q[static_cast<size_t>(first)].squaredNorm())
      first = i;
  S.push_back(first);
  l.push_back(1.0);
  Eigen::Vector3d y = q[static_cast<size_t>(first)];
  auto point_of = [&](const std::vector<int>& set, const std::vector<double>& w) {
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < set.size(); ++i)
      p += w[i] * q[static_cast<size_t>(set[i])];
    return p;
  };
  // How far y is from optimal: no point may lie beyond the plane through y across it.
  auto gap = [&](const Eigen::Vector3d& at, int* furthest) {
    int j = 0;
    for (int i = 1; i < n; ++i)
      if (q[static_cast<size_t>(i)].dot(at) < q[static_cast<size_t>(j)].dot(at))
        j = i;
    if (furthest)
      *furthest = j;
    return at.squaredNorm() - q[static_cast<size_t>(j)].dot(at);
  };
  const double eps = 1e-14;
  std::vector<int> best_S = S;
  std::vector<double> best_l = l;
  double best = y.squaredNorm();
  std::vector<double> a;
  for (int major = 0; major < 4 * n + 16; ++major) {
    int j = 0;
    if (gap(y, &j) <= eps || std::find(S.begin(), S.end(), j) != S.end())
      break;
    S.push_back(j);
    l.push_back(0.0);
    for (int minor = 0; minor < 8 && !S.empty(); ++minor) {
      affine_minimum(q, S, a);
      if (*std::min_element(a.begin(), a.end()) > 0) {
        l = a;
        break;
      }
      // Towards the affine minimum as far as the set's hull goes: the
      // weight that reaches zero first is set to zero exactly, and dropped
      // with any other at zero.
      double theta = 1;
      int block = -1;
      for (size_t i = 0; i < a.size(); ++i)
        if (a[i] <= 0 && l[i] - a[i] > 0 && l[i] / (l[i] - a[i]) < theta) {
          theta = l[i] / (l[i] - a[i]);
          block = static_cast<int>(i);
        }
      for (size_t i = 0; i < a.size(); ++i)
        l[i] += theta * (a[i] - l[i]);
      if (block >= 0)
        l[static_cast<size_t>(block)] = 0;
      std::vector<int> keptS;
      std::vector<double> keptl;
      for (size_t i = 0; i < S.size(); ++i)
        if (l[i] > 0) {
          keptS.push_back(S[i]);
          keptl.push_back(l[i]);
        }
      S = std::move(keptS);
      l = std::move(keptl);
    }
    if (S.empty())
      break;
    double sum = 0;
    for (const double li : l)
      sum += li;
    for (double& li : l)
      li /= sum;
    y = point_of(S, l);
    if (y.squaredNorm() < best) {
      best = y.squaredNorm();
      best_S = S;
      best_l = l;
    } else {
      break; // rounding: no progress left
    }
  }
  // Checked: where the best point met is not optimal (Wolfe's steps stalled
  // in rounding), every subset of up to four points is tried (up to 20
  // points: 6,195 subsets).
  if (gap(point_of(best_S, best_l), nullptr) > 1e-12 && n <= 20) {
    auto [S2, l2] = nearest_by_subsets(q);
    if (!S2.empty() && point_of(S2, l2).squaredNorm() < best)
      best_S = std::move(S2), best_l = std::move(l2);
  }
  out.weights = Eigen::VectorXd::Zero(n);
  for (size_t i = 0; i < best_S.size(); ++i)
    out.weights[best_S[i]] = best_l[i];
  out.distance = scale * point_of(best_S, best_l).norm();
  return out;
}

} // namespace curvenet::detail
