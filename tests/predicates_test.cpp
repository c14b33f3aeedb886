#include "core/predicates.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

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

TEST(Predicates, Orient3dIsExactNearThePlaneWhereTheQuickDeterminantIsNot) {
  // Integer points up to 2^24 (their products overflow a double's 53 bits,
  // so the quick floating-point determinant can round the wrong way), with
  // the fourth on the plane of the first three or one unit off it: the
  // exact sign, computed with 128-bit integers, is what orient3d must give.
  std::uint64_t state = 42;
  auto next = [&]() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<std::int64_t>((state >> 33) % (1 << 24)) - (1 << 23);
  };
  int checked = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const std::int64_t a[3] = {next(), next(), next()};
    std::int64_t u[3], v[3];
    for (int k = 0; k < 3; ++k) {
      u[k] = next() / 64;
      v[k] = next() / 64;
    }
    const std::int64_t s = next() % 5, t = next() % 5, e = next() % 3 - 1;
    std::int64_t b[3], c[3], d[3];
    for (int k = 0; k < 3; ++k) {
      b[k] = a[k] + u[k];
      c[k] = a[k] + v[k];
      d[k] = a[k] + s * u[k] + t * v[k] + (k == 2 ? e : 0);
    }
    auto exact = [&]() {
      __int128 m[3][3];
      for (int k = 0; k < 3; ++k) {
        m[0][k] = b[k] - a[k];
        m[1][k] = c[k] - a[k];
        m[2][k] = d[k] - a[k];
      }
      const __int128 det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
      return det > 0 ? 1 : det < 0 ? -1 : 0;
    };
    auto vec = [](const std::int64_t* p) {
      return Eigen::Vector3d(static_cast<double>(p[0]), static_cast<double>(p[1]), static_cast<double>(p[2]));
    };
    ASSERT_EQ(orient3d(vec(a), vec(b), vec(c), vec(d)), exact()) << trial;
    ++checked;
  }
  EXPECT_EQ(checked, 20000);
}

TEST(Predicates, Orient2dAndCollinear3dAreExactNearTheLineWhereTheQuickDeterminantIsNot) {
  // As above, in the plane: integer points up to 2^30 (products past 53
  // bits), the third on the line of the first two or one unit off it, and
  // the exact sign from 128-bit integers. collinear3d gets the same points
  // lifted into space along a second line, so that each coordinate plane
  // sees a near-degenerate triple and the quick filter rarely settles it.
  std::uint64_t state = 7;
  auto next = [&]() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<std::int64_t>((state >> 33) % (1LL << 30)) - (1LL << 29);
  };
  int off_line = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const std::int64_t a[2] = {next(), next()}, u[2] = {next() / 64, next() / 64};
    const std::int64_t s = next() % 7, e = next() % 3 - 1;
    const std::int64_t b[2] = {a[0] + u[0], a[1] + u[1]}, c[2] = {a[0] + s * u[0], a[1] + s * u[1] + e};
    const __int128 det = static_cast<__int128>(b[0] - a[0]) * (c[1] - a[1]) -
                         static_cast<__int128>(b[1] - a[1]) * (c[0] - a[0]);
    const int exact = det > 0 ? 1 : det < 0 ? -1 : 0;
    auto d = [](std::int64_t x) { return static_cast<double>(x); };
    ASSERT_EQ(orient2d({d(a[0]), d(a[1])}, {d(b[0]), d(b[1])}, {d(c[0]), d(c[1])}), exact) << trial;
    // In space: z follows x along the line, so the triple is collinear
    // exactly when it is in the plane.
    const Eigen::Vector3d a3(d(a[0]), d(a[1]), d(a[0])), b3(d(b[0]), d(b[1]), d(b[0])), c3(d(c[0]), d(c[1]), d(c[0]));
    ASSERT_EQ(collinear3d(a3, b3, c3), exact == 0) << trial;
    off_line += exact != 0;
  }
  EXPECT_GT(off_line, 2000); // both kinds were tried
  EXPECT_GT(20000 - off_line, 2000);
}
