#include "core/predicates.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace curvenet::detail;

TEST(Predicates, Orient2dSigns) {
  EXPECT_EQ(orient2d({0, 0}, {1, 0}, {0, 1}), 1);
  EXPECT_EQ(orient2d({0, 0}, {0, 1}, {1, 0}), -1);
  EXPECT_EQ(orient2d({0, 0}, {1, 1}, {2, 2}), 0);
}

TEST(Predicates, Orient3dFollowsTheNormal) {
  // +1 on the side that (b - a) x (c - a) points to.
  EXPECT_EQ(orient3d({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}), 1);
  EXPECT_EQ(orient3d({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, -1}), -1);
  EXPECT_EQ(orient3d({0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.3, 0.7, 0}), 0);
}

TEST(Predicates, ExactWhereFloatingPointIsNot) {
  // A point nudged off a line by one unit in the last place: the naive
  // determinant of these doubles rounds to zero, the exact sign does not.
  const Eigen::Vector2d a(0.5, 0.5), b(12.0, 12.0), c(24.0, std::nextafter(24.0, 25.0));
  EXPECT_EQ(orient2d(a, b, c), 1);
  EXPECT_EQ(orient2d(a, b, {24.0, std::nextafter(24.0, 23.0)}), -1);
  EXPECT_EQ(orient2d(a, b, {24.0, 24.0}), 0);
  EXPECT_EQ(orient2d({0, 0}, {1e-300, 1e-300}, {1, 1}), 0);
  EXPECT_TRUE(collinear3d({0, 0, 0}, {1, 2, 3}, {2, 4, 6}));
  EXPECT_FALSE(collinear3d({0, 0, 0}, {1, 2, 3}, {2, 4, 6.000000000001}));
}
