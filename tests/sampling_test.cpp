// Stage "sample": curve evaluation and arc-length resampling.

#include "sample/sampling.hpp"

#include <gtest/gtest.h>

#include <algorithm>

using namespace curvenet;
using namespace curvenet::detail;

namespace {
SpacingFn constant(double h) {
  return [h](const Vec3&) { return h; };
}
} // namespace

TEST(Sampling, SpacingIsAtMostTheLocalEdgeLengthOverTheDensity) {
  Curve c;
  c.points = {{0, 0, 0}, {10, 0, 0}};
  // Edge length 1, density 5: steps of at most 0.2, so 50 segments.
  const auto s = sample_profile(ProfileCurve(c, {0, 0, 0}, {10, 0, 0}), constant(1.0 / 5.0));
  EXPECT_EQ(s.points.size(), 51u);
  // Edges longer than the curve: only its two ends.
  EXPECT_EQ(sample_profile(ProfileCurve(c, {0, 0, 0}, {10, 0, 0}), constant(100.0 / 5.0)).points.size(), 2u);
}

TEST(Sampling, SpacingFollowsTheLocalEdgeLength) {
  // Fine edges (0.1) for x < 5, coarse ones (1) beyond: ten times the
  // samples on the fine half.
  Curve c;
  c.points = {{0, 0, 0}, {10, 0, 0}};
  const auto s =
      sample_profile(ProfileCurve(c, {0, 0, 0}, {10, 0, 0}), [](const Vec3& p) { return p.x() < 5 ? 0.1 : 1.0; });
  int fine = 0, coarse = 0;
  for (size_t i = 1; i < s.points.size(); ++i) {
    const double step = (s.points[i] - s.points[i - 1]).norm();
    EXPECT_LE(step, (s.points[i - 1].x() < 5 ? 0.1 : 1.0) + 1e-12) << i;
    (s.points[i - 1].x() < 5 ? fine : coarse)++;
  }
  EXPECT_GE(fine, 50);
  EXPECT_LE(coarse, 6);
}

TEST(Sampling, TheRiggersPointsAreAlwaysSamples) {
  Curve c;
  c.points = {{0, 0, 0}, {1, 0, 0}, {1, 3, 0}, {1.01, 3, 0}}; // lengths 1, 3 and 0.01
  const auto s = sample_profile(ProfileCurve(c, c.points.front(), c.points.back()), constant(0.5));
  for (const Vec3& corner : c.points)
    EXPECT_TRUE(std::any_of(s.points.begin(), s.points.end(), [&](const Vec3& p) { return p == corner; }))
        << corner.transpose();
  // Equal steps between two corners: 2 on the first span, 6 on the second, 1 on the last.
  ASSERT_EQ(s.points.size(), 10u);
  for (size_t i = 1; i < s.points.size(); ++i) {
    const double step = (s.points[i] - s.points[i - 1]).norm();
    EXPECT_NEAR(step, i <= 2 ? 0.5 : i <= 8 ? 0.5 : 0.01, 1e-12) << i;
    EXPECT_GT(s.t[i], s.t[i - 1]);
  }
}

TEST(Sampling, AClosedProfileGetsAtLeastEightSegments) {
  Curve c;
  c.points = {{1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}, {1, 0, 0}};
  const auto s = sample_profile(ProfileCurve(c, {1, 0, 0}, {1, 0, 0}), constant(100.0));
  EXPECT_EQ(s.points.size(), 9u);
}

TEST(Sampling, EndsAreMovedOntoTheNodes) {
  Curve c;
  c.points = {{0, 0.1, 0}, {5, 0.1, 0}, {10, -0.2, 0}};
  const Vec3 a(0, 0, 0), b(10, 0, 0);
  const ProfileCurve pc(c, a, b);
  const auto s = sample_profile(pc, constant(0.2));
  EXPECT_EQ(s.points.front(), a);
  EXPECT_EQ(s.points.back(), b);
  EXPECT_EQ(s.t.front(), 0.0);
  EXPECT_EQ(s.t.back(), 1.0);
  // The curve between: the middle point is moved by the faded displacement.
  EXPECT_NEAR((pc.at(0.5) - Vec3(5, 0.15, 0)).norm(), 0, 1e-2);
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
