// Distances between polylines: the maths the fidelity measure rests on.

#include "core/polyline_distance.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace curvenet::detail;
using V = Eigen::Vector3d;

TEST(PolylineDistance, PointToSegmentClampsToTheEnds) {
  EXPECT_DOUBLE_EQ(point_segment_distance({0.5, 2, 0}, {0, 0, 0}, {1, 0, 0}), 2);
  EXPECT_DOUBLE_EQ(point_segment_distance({3, 4, 0}, {0, 0, 0}, {0, 0, 0}), 5);
  EXPECT_DOUBLE_EQ(point_segment_distance({-3, 4, 0}, {0, 0, 0}, {1, 0, 0}), 5);
}

TEST(PolylineDistance, SegmentToSegmentInEveryCase) {
  // Skew: the common perpendicular, of length 1.
  EXPECT_NEAR(segment_distance({-1, 0, 0}, {1, 0, 0}, {0, -1, 1}, {0, 1, 1}), 1, 1e-15);
  // Crossing in a plane: zero.
  EXPECT_NEAR(segment_distance({-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}), 0, 1e-15);
  // Parallel and overlapping, 2 apart.
  EXPECT_NEAR(segment_distance({0, 0, 0}, {4, 0, 0}, {1, 2, 0}, {3, 2, 0}), 2, 1e-15);
  // Apart along their line: end to end.
  EXPECT_NEAR(segment_distance({0, 0, 0}, {1, 0, 0}, {4, 0, 0}, {5, 0, 0}), 3, 1e-15);
}

TEST(PolylineDistance, HausdorffIsSymmetricAndSeesBothWays) {
  const std::vector<V> line{{0, 0, 0}, {10, 0, 0}};
  const std::vector<V> bump{{0, 0, 0}, {5, 1, 0}, {10, 0, 0}};
  EXPECT_NEAR(hausdorff(line, bump), 1, 1e-15);
  EXPECT_NEAR(hausdorff(bump, line), 1, 1e-15);
  // A short polyline near one end of a long one: the long one's far end is 9 away.
  const std::vector<V> stub{{0, 0.5, 0}, {1, 0.5, 0}};
  EXPECT_NEAR(hausdorff(line, stub), std::hypot(9.0, 0.5), 1e-12);
  EXPECT_EQ(hausdorff(line, line), 0);
}

TEST(PolylineDistance, WindowedDistanceOnlyOverstatesAndSkipsWhatItIsTold) {
  std::vector<KeyedPoint> a, b;
  for (int i = 0; i <= 10; ++i) {
    a.push_back({V(i, 0, 0), i});
    b.push_back({V(i, 0.25, 0), i});
  }
  EXPECT_NEAR(directed_hausdorff(a, b, 1).distance, 0.25, 1e-15);
  // Sparse keys on one side (a run along one edge): its long segment is
  // measured against everything between its ends.
  std::vector<KeyedPoint> sparse{{V(0, 0, 0), 0}, {V(10, 0, 0), 10}};
  EXPECT_NEAR(directed_hausdorff(sparse, b, 1).distance, 0.25, 1e-15);
  EXPECT_NEAR(directed_hausdorff(b, sparse, 1).distance, 0.25, 1e-15);
  // A far point is found, and skipping it hides it.
  b[5].pos.y() = 3;
  const DirectedDistance far = directed_hausdorff(b, a, 1);
  EXPECT_NEAR(far.distance, 3, 1e-15);
  EXPECT_EQ(far.at, 5u);
  b[5].skip = true;
  b[6].skip = true; // the segment from 5 to 6 ends at a skipped point
  EXPECT_LT(directed_hausdorff(b, a, 1).distance, 3);
}

TEST(PolylineDistance, SimplifyKeepsTheShapeWithinTheTolerance) {
  // An L, each leg with a little noise: only its corner and ends stay.
  std::vector<V> pts;
  for (int i = 0; i <= 100; ++i)
    pts.emplace_back(std::min(i, 50) + 0.001 * std::sin(i), std::max(0, i - 50) + 0.001 * std::cos(i), 0);
  const auto kept = simplify_polyline(pts, 0.01);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[0], 0u);
  EXPECT_EQ(kept[1], 50u);
  EXPECT_EQ(kept[2], 100u);
  std::vector<V> out;
  for (size_t k : kept)
    out.push_back(pts[k]);
  EXPECT_LE(hausdorff(pts, out), 0.01 + 1e-12);
  // Nothing to drop from two points; a tolerance of zero keeps every bend.
  EXPECT_EQ(simplify_polyline({pts[0], pts[1]}, 1).size(), 2u);
  EXPECT_EQ(simplify_polyline(pts, 0).size(), pts.size());
}
