// Stage "sample": curve evaluation and arc-length resampling.

#include "sample/sampling.hpp"

#include <gtest/gtest.h>

using namespace curvenet;
using namespace curvenet::detail;

TEST(Sampling, CountFollowsTheThesisFormula) {
  Curve c;
  c.points = {{0, 0, 0}, {10, 0, 0}};
  // n = max(2, ceil(rho * L / h)) = ceil(5 * 10 / 1) = 50
  const auto s = sample_profile(c, {0, 0, 0}, {10, 0, 0}, 1.0, 5.0);
  EXPECT_EQ(s.points.size(), 50u);
  EXPECT_EQ(sample_profile(c, {0, 0, 0}, {10, 0, 0}, 100.0, 5.0).points.size(), 2u);
}

TEST(Sampling, SamplesAreUniformInArcLength) {
  Curve c;
  c.points = {{0, 0, 0}, {1, 0, 0}, {1, 3, 0}}; // lengths 1 and 3
  const auto s = sample_profile(c, {0, 0, 0}, {1, 3, 0}, 0.5, 1.0);
  ASSERT_EQ(s.points.size(), 8u);
  for (size_t i = 1; i < s.points.size(); ++i) {
    EXPECT_NEAR(s.t[i] - s.t[i - 1], 1.0 / 7.0, 1e-15);
    if (i != 2)
      EXPECT_NEAR((s.points[i] - s.points[i - 1]).norm(), 4.0 / 7.0, 1e-12) << i;
  }
}

TEST(Sampling, EndsAreMovedOntoTheNodes) {
  Curve c;
  c.points = {{0, 0.1, 0}, {5, 0.1, 0}, {10, -0.2, 0}};
  const Vec3 a(0, 0, 0), b(10, 0, 0);
  const auto s = sample_profile(c, a, b, 1.0, 5.0);
  EXPECT_EQ(s.points.front(), a);
  EXPECT_EQ(s.points.back(), b);
  EXPECT_EQ(s.t.front(), 0.0);
  EXPECT_EQ(s.t.back(), 1.0);
}

TEST(Sampling, BezierAndNurbsReproduceTheirEnds) {
  Curve bz;
  bz.kind = Curve::Kind::Bezier;
  bz.points = {{0, 0, 0}, {1, 1, 0}, {2, 1, 0}, {3, 0, 0}, {4, -1, 0}, {5, -1, 0}, {6, 0, 0}};
  const auto d = evaluate_dense(bz);
  EXPECT_EQ(d.front(), bz.points.front());
  EXPECT_NEAR((d.back() - bz.points.back()).norm(), 0, 1e-12);
  // A clamped cubic NURBS with collinear control points stays on the line.
  Curve n;
  n.kind = Curve::Kind::Nurbs;
  n.points = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}, {4, 0, 0}};
  n.knots = {0, 0, 0, 0, 0.5, 1, 1, 1, 1};
  n.weights = {1, 2, 1, 3, 1};
  for (const auto& p : evaluate_dense(n))
    EXPECT_NEAR(p.y(), 0.0, 1e-15);
  EXPECT_NEAR((evaluate_nurbs(n, 0) - n.points.front()).norm(), 0, 1e-15);
  EXPECT_NEAR((evaluate_nurbs(n, 1) - n.points.back()).norm(), 0, 1e-15);
}
