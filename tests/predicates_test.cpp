#include "core/predicates.hpp"

#include <gtest/gtest.h>

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
  // Points that are collinear in exact arithmetic but whose naive
  // determinant rounds to a non-zero value.
  const Eigen::Vector2d a(0.1, 0.1), b(0.2, 0.2), c(0.3, 0.3);
  EXPECT_EQ(orient2d(a, b, c), orient2d(a, b, c)); // deterministic
  EXPECT_EQ(orient2d({0, 0}, {1e-300, 1e-300}, {1, 1}), 0);
  EXPECT_TRUE(collinear3d({0, 0, 0}, {1, 2, 3}, {2, 4, 6}));
  EXPECT_FALSE(collinear3d({0, 0, 0}, {1, 2, 3}, {2, 4, 6.000000000001}));
}
