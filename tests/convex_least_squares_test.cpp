// Least squares over the simplex (core/convex_least_squares.hpp): the
// minimum of 1/2 x'Gx - h'x with x >= 0 and sum(x) = 1, checked against the
// best of every face of the simplex, solved on its own.

#include "core/convex_least_squares.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

using namespace curvenet;
using detail::convex_least_squares;
using detail::quadratic_objective;

namespace {

/// The true minimum by brute force: on every subset of the weights, the
/// minimum of the plane sum = 1 restricted to it; the least of those that are
/// non-negative.
/// Every non-empty subset of 0..n-1 with at most `most` members.
std::vector<std::vector<int>> subsets(int n, int most) {
  std::vector<std::vector<int>> out;
  for (int mask = 1; mask < (1 << n); ++mask) {
    std::vector<int> S;
    for (int i = 0; i < n; ++i)
      if (mask & (1 << i))
        S.push_back(i);
    if (static_cast<int>(S.size()) <= most)
      out.push_back(std::move(S));
  }
  return out;
}

double brute_force_minimum(const Eigen::MatrixXd& G, const Eigen::VectorXd& h) {
  const int n = static_cast<int>(h.size());
  double best = std::numeric_limits<double>::infinity();
  for (const auto& S : subsets(n, n)) {
    const int m = static_cast<int>(S.size());
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(m + 1, m + 1);
    Eigen::VectorXd r(m + 1);
    for (int a = 0; a < m; ++a) {
      for (int b = 0; b < m; ++b)
        K(a, b) = G(S[a], S[b]);
      K(a, m) = K(m, a) = 1;
      r[a] = h[S[a]];
    }
    r[m] = 1;
    const Eigen::VectorXd z = K.fullPivLu().solve(r);
    if (z.head(m).minCoeff() < 0)
      continue;
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    for (int a = 0; a < m; ++a)
      x[S[a]] = z[a];
    best = std::min(best, quadratic_objective(G, h, x));
  }
  return best;
}

/// Normal equations of a random least squares, as a vertex's fit makes them:
/// columns that are nearly alike (joints that move together), and a ridge.
std::pair<Eigen::MatrixXd, Eigen::VectorXd> random_problem(std::mt19937& rng, int n) {
  std::normal_distribution<double> g;
  const int rows = 3 * 12;
  Eigen::MatrixXd A(rows, n);
  Eigen::VectorXd common(rows), b(rows);
  for (int r = 0; r < rows; ++r)
    common[r] = g(rng);
  for (int c = 0; c < n; ++c)
    for (int r = 0; r < rows; ++r)
      A(r, c) = common[r] + 0.3 * g(rng);
  for (int r = 0; r < rows; ++r)
    b[r] = common[r] + 0.5 * g(rng);
  return {A.transpose() * A + 1e-6 * Eigen::MatrixXd::Identity(n, n), A.transpose() * b};
}

void expect_on_simplex(const Eigen::VectorXd& x) {
  EXPECT_GE(x.minCoeff(), 0);
  EXPECT_NEAR(x.sum(), 1, 1e-12);
}

} // namespace

TEST(ConvexLeastSquares, FindsTheBestOfEveryFaceOfTheSimplexFromAnyStart) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 300; ++trial) {
    const int n = 1 + trial % 8;
    const auto [G, h] = random_problem(rng, n);
    const double best = brute_force_minimum(G, h);
    // From the centre, from one corner, and from a random point (Eigen's
    // Random draws from std::rand: the same points every run).
    std::vector<Eigen::VectorXd> starts{Eigen::VectorXd::Constant(n, 1.0 / n), Eigen::VectorXd::Unit(n, n - 1),
                                        Eigen::VectorXd::Random(n).cwiseAbs()};
    for (const auto& start : starts) {
      const Eigen::VectorXd x = convex_least_squares(G, h, start);
      expect_on_simplex(x);
      EXPECT_NEAR(quadratic_objective(G, h, x), best, 1e-9 * (1 + std::abs(best))) << "trial " << trial;
    }
  }
}

TEST(ConvexLeastSquares, TheFreeWeightsShareOneGradientAndNoFixedWeightWouldLowerIt) {
  // The optimality conditions: on the weights above zero the gradient is one
  // value (the multiplier of the sum), and at the weights held at zero it is
  // no lower.
  std::mt19937 rng(11);
  for (int trial = 0; trial < 100; ++trial) {
    const int n = 2 + trial % 7;
    const auto [G, h] = random_problem(rng, n);
    const Eigen::VectorXd x = convex_least_squares(G, h, Eigen::VectorXd::Constant(n, 1.0 / n));
    const Eigen::VectorXd grad = G * x - h;
    double level = 0;
    int free = 0;
    for (int i = 0; i < n; ++i)
      if (x[i] > 0)
        level += grad[i], ++free;
    ASSERT_GT(free, 0);
    level /= free;
    const double scale = G.cwiseAbs().maxCoeff() + h.cwiseAbs().maxCoeff();
    for (int i = 0; i < n; ++i) {
      if (x[i] > 0)
        EXPECT_NEAR(grad[i], level, 1e-9 * scale);
      else
        EXPECT_GE(grad[i], level - 1e-9 * scale);
    }
  }
}

TEST(ConvexLeastSquares, AnInteriorMinimumIsTheMinimumOnThePlaneAndACornerIsExact) {
  // |x - p|^2 / 2 with p inside the simplex: x = p.
  const Eigen::Vector3d p(0.2, 0.5, 0.3);
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(3, 3);
  const Eigen::VectorXd x = convex_least_squares(I, p, Eigen::VectorXd::Unit(3, 0));
  EXPECT_LT((x - p).norm(), 1e-14);
  // p beyond a corner: the corner itself.
  const Eigen::Vector3d far(5, -1, -2);
  EXPECT_LT((convex_least_squares(I, far, Eigen::VectorXd::Constant(3, 1.0 / 3)) - Eigen::Vector3d(1, 0, 0)).norm(),
            1e-14);
  // One weight: it is 1.
  EXPECT_EQ(convex_least_squares(Eigen::MatrixXd::Constant(1, 1, 2.0), Eigen::VectorXd::Constant(1, -3.0),
                                 Eigen::VectorXd::Constant(1, 1.0))[0],
            1.0);
  // A start that is not on the simplex (all zero) is taken from its centre.
  expect_on_simplex(convex_least_squares(I, p, Eigen::VectorXd::Zero(3)));
}

// --- The nearest point of a convex hull: the floor of any linear skin ---

namespace {

/// The nearest point of the hull by brute force: over every subset of at
/// most four points (Caratheodory, in 3D), the projection onto its affine
/// hull where its barycentric weights are all non-negative; the nearest.
double brute_force_hull_distance(const std::vector<Eigen::Vector3d>& P, const Eigen::Vector3d& x) {
  const int n = static_cast<int>(P.size());
  double best = std::numeric_limits<double>::infinity();
  for (const auto& S : subsets(n, 4)) {
    const int m = static_cast<int>(S.size());
    Eigen::MatrixXd E(3, m - 1);
    for (int a = 1; a < m; ++a)
      E.col(a - 1) = P[S[a]] - P[S[0]];
    Eigen::VectorXd c = m > 1 ? Eigen::VectorXd(E.colPivHouseholderQr().solve(x - P[S[0]])) : Eigen::VectorXd();
    if (m > 1 && (c.minCoeff() < 0 || c.sum() > 1))
      continue;
    const Eigen::Vector3d q = P[S[0]] + (m > 1 ? Eigen::Vector3d(E * c) : Eigen::Vector3d::Zero());
    best = std::min(best, (q - x).norm());
  }
  return best;
}

} // namespace

TEST(NearestInHull, IsTheBruteForceNearestPointAndItsWeightsMakeIt) {
  std::mt19937 rng(5);
  std::normal_distribution<double> g;
  for (int trial = 0; trial < 2000; ++trial) {
    const int n = 1 + trial % 8;
    std::vector<Eigen::Vector3d> P(n);
    for (auto& p : P)
      p = Eigen::Vector3d(g(rng), g(rng), g(rng));
    // Degenerate sets as joints give them: all in a plane, on a line, or
    // some at one place (joints that do not move).
    if (trial % 4 == 1)
      for (auto& p : P)
        p.z() = 0;
    if (trial % 4 == 2)
      for (auto& p : P)
        p = P[0] + g(rng) * Eigen::Vector3d(1, 2, -1);
    if (trial % 4 == 3 && n > 2)
      P[1] = P[2] = P[0];
    // Points on a small integer grid: affine minima that land exactly on
    // an edge or a face, with weights of zero up to rounding.
    if (trial % 8 == 5)
      for (auto& p : P)
        p = Eigen::Vector3d(std::round(g(rng)), std::round(g(rng)), std::round(g(rng)));
    const Eigen::Vector3d x = 1.5 * Eigen::Vector3d(g(rng), g(rng), g(rng));
    const auto h = detail::nearest_in_hull(P, x);
    expect_on_simplex(h.weights);
    Eigen::Vector3d q = Eigen::Vector3d::Zero();
    for (int i = 0; i < n; ++i)
      q += h.weights[i] * P[i];
    EXPECT_NEAR((q - x).norm(), h.distance, 1e-12);
    EXPECT_NEAR(h.distance, brute_force_hull_distance(P, x), 1e-7) << "trial " << trial;
  }
}

TEST(NearestInHull, AnInsidePointIsAtDistanceZeroFarFromTheOriginToo) {
  // A tetrahedron 1e6 from the origin, at the scale of a character in
  // centimetres: the point inside it is reached (the points are taken
  // relative to x, so their distance from the origin costs no digits).
  const Eigen::Vector3d o(1e6, -2e6, 3e6);
  const std::vector<Eigen::Vector3d> P = {o, o + Eigen::Vector3d(1, 0, 0), o + Eigen::Vector3d(0, 1, 0),
                                          o + Eigen::Vector3d(0, 0, 1)};
  EXPECT_LT(detail::nearest_in_hull(P, o + Eigen::Vector3d(0.2, 0.3, 0.1)).distance, 1e-9);
  // Beyond one face: the distance to its plane.
  EXPECT_NEAR(detail::nearest_in_hull(P, o + Eigen::Vector3d(0.2, 0.3, -0.5)).distance, 0.5, 1e-9);
  // No points: nothing is near. A non-finite coordinate: no distance.
  EXPECT_TRUE(std::isinf(detail::nearest_in_hull({}, o).distance));
  EXPECT_TRUE(std::isnan(detail::nearest_in_hull(P, Eigen::Vector3d(0, std::nan(""), 0)).distance));
  auto bad = P;
  bad[2].x() = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(std::isnan(detail::nearest_in_hull(bad, o).distance));
}

TEST(NearestInHull, AnAffineMinimumOnAnEdgeOfTheSetDoesNotStopTheSearch) {
  // The affine minimum of three of these lands on an edge, one weight
  // coming out as 2e-17 instead of 0. Kept, it limited the next step to
  // nothing, the point just added was dropped with it, and the search
  // stopped at 0.97 where the hull comes within 0.79 (a reviewer's case).
  const std::vector<Eigen::Vector3d> P = {{0, 1, 1}, {2, 0, 0}, {0, 0, 0}, {1, 1, 2}};
  for (const double z : {1.3751693163772298, 1.1, 1.5, 1.9}) {
    const Eigen::Vector3d x(0, 0, z);
    EXPECT_NEAR(detail::nearest_in_hull(P, x).distance, brute_force_hull_distance(P, x), 1e-9) << z;
  }
  // And over that family as a whole.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(1, 2);
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d x(0, 0, u(rng));
    ASSERT_NEAR(detail::nearest_in_hull(P, x).distance, brute_force_hull_distance(P, x), 1e-9) << x.z();
  }
}

TEST(NearestInHull, AnArcsMiddleIsItsSagittaFromTheChord) {
  // A vertex at distance r from a joint's axis, blended half and half
  // between that joint turned by theta and its parent at rest: a
  // dual-quaternion blend turns it by theta/2, onto the arc; a linear skin
  // of the two joints keeps it on the chord. No weights bring the skin
  // closer than the sagitta, r (1 - cos(theta/2)).
  const double r = 0.3;
  const Eigen::Vector3d p(r, 0, 2);
  for (const double degrees : {20.0, 90.0, 138.0, 180.0}) {
    const double theta = degrees * 3.14159265358979323846 / 180;
    const Eigen::Vector3d turned = Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()) * p;
    const Eigen::Vector3d arc = Eigen::AngleAxisd(theta / 2, Eigen::Vector3d::UnitZ()) * p;
    const std::vector<Eigen::Vector3d> P = {p, turned};
    const auto h = detail::nearest_in_hull(P, arc);
    EXPECT_NEAR(h.distance, r * (1 - std::cos(theta / 2)), 1e-12) << degrees;
    EXPECT_NEAR(h.weights[0], 0.5, 1e-9) << degrees;
  }
}
