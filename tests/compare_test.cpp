// Symmetric surface distance, point to surface; and the measures of a
// deformation's quality (curvenet/quality.hpp).

#include "curvenet/compare.hpp"
#include "curvenet/quality.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

using namespace curvenet;

TEST(Compare, AMeshIsAtDistanceZeroFromItself) {
  const SurfaceMesh m = make_surface_mesh(make_capped_tube({}), "tube");
  const SurfaceDistance d = surface_distance(m, m);
  EXPECT_LT(d.max, 1e-12);
  EXPECT_NEAR(d.diagonal, m.bbox_diagonal(), 1e-15);
}

TEST(Compare, AShiftedPlaneIsAtTheShift) {
  const SurfaceMesh a = make_surface_mesh(test::grid(6, 4, true), "a");
  RawMesh shifted = test::grid(6, 4, false); // another tessellation too
  for (auto& p : shifted.positions)
    p.z() += 0.1;
  const SurfaceMesh b = make_surface_mesh(shifted, "b");
  const SurfaceDistance d = surface_distance(a, b);
  EXPECT_NEAR(d.mean, 0.1, 1e-12);
  EXPECT_NEAR(d.rms, 0.1, 1e-12);
  EXPECT_NEAR(d.max, 0.1, 1e-12);
  EXPECT_NEAR(d.percent(d.mean), 100 * 0.1 / a.bbox_diagonal(), 1e-9);
}

TEST(Compare, SeesAcrossTopologies) {
  // Two tessellations of one tube: close, but not equal (faceting differs),
  // and the finer one is closer to the coarse one than a shrunk tube is.
  TubeSpec fine;
  fine.around = 48;
  fine.along = 40;
  fine.triangulate = true;
  const SurfaceMesh a = make_surface_mesh(make_capped_tube({}), "a"), b = make_surface_mesh(make_capped_tube(fine), "b");
  TubeSpec shrunk;
  shrunk.radius = 0.9;
  const SurfaceMesh c = make_surface_mesh(make_capped_tube(shrunk), "c");
  const SurfaceDistance ab = surface_distance(a, b), ac = surface_distance(a, c);
  EXPECT_GT(ab.max, 0.0);
  EXPECT_LT(ab.max, 0.03);  // about the 16-gon's sagitta, 1 - cos(pi/16)
  EXPECT_GT(ac.mean, 0.05); // a 0.1 shrink shows
  EXPECT_GT(ac.max, ab.max);
}

// --- deformation quality (curvenet/quality.hpp) -----------------------------

namespace {

SurfaceMesh soup(const std::vector<Vec3>& pts, const std::vector<std::vector<int>>& faces) {
  RawMesh r;
  r.positions = pts;
  for (const auto& f : faces)
    r.add_face(f);
  return make_surface_mesh(r, "soup");
}

} // namespace

TEST(Quality, SelfIntersectingPairsAreCountedExactly) {
  // Two triangles: one crossing the other's interior, then moved clear, then
  // touching it exactly in one point of its plane (touching counts).
  const std::vector<Vec3> base{{0, 0, 0}, {2, 0, 0}, {0, 2, 0}};
  auto pair_with = [&](const std::array<Vec3, 3>& t) {
    std::vector<Vec3> pts = base;
    pts.insert(pts.end(), t.begin(), t.end());
    return soup(pts, {{0, 1, 2}, {3, 4, 5}});
  };
  const SurfaceMesh crossing = pair_with({Vec3(0.5, 0.5, -1), Vec3(0.5, 0.5, 1), Vec3(3, 3, 0.2)});
  EXPECT_EQ(self_intersecting_pairs(crossing, crossing.positions), 1);
  const SurfaceMesh clear = pair_with({Vec3(0.5, 0.5, 0.1), Vec3(0.5, 0.6, 1), Vec3(3, 3, 0.2)});
  EXPECT_EQ(self_intersecting_pairs(clear, clear.positions), 0);
  const SurfaceMesh touching = pair_with({Vec3(0.5, 0.5, 0), Vec3(0.5, 0.6, 1), Vec3(3, 3, 0.2)});
  EXPECT_EQ(self_intersecting_pairs(touching, touching.positions), 1);
  const SurfaceMesh coplanar = pair_with({Vec3(0.5, 0.5, 0), Vec3(3, 0.5, 0), Vec3(0.5, 3, 0)});
  EXPECT_EQ(self_intersecting_pairs(coplanar, coplanar.positions), 1);
  // A closed box has none; pushing a corner through the opposite face makes some.
  const SurfaceMesh box = make_surface_mesh(test::box(), "box");
  EXPECT_EQ(self_intersecting_pairs(box, box.positions), 0);
  std::vector<Vec3> pushed = box.positions;
  pushed[7] = Vec3(0.2, 0.3, -0.5); // corner (1, 1, 1) through the bottom face z = 0
  EXPECT_GT(self_intersecting_pairs(box, pushed), 0);
}

TEST(Quality, ASectionOfATubeIsItsPolygon) {
  const SurfaceMesh m = test::tube(24, 16, 4, true);
  const double want = 0.5 * 24 * std::sin(2 * std::numbers::pi / 24); // unit radius, 24 corners
  EXPECT_NEAR(section_area(m, m.positions, Vec3(0, 2.1, 0), Vec3::UnitY()), want, 1e-9);
  // A plane that misses the tube, and a point outside it, have no section around them.
  EXPECT_EQ(section_area(m, m.positions, Vec3(0, 9, 0), Vec3::UnitY()), 0.0);
  EXPECT_EQ(section_area(m, m.positions, Vec3(3, 2.1, 0), Vec3::UnitY()), 0.0);
}

TEST(Quality, MeasuresVolumeStretchGrowthAndTurnedTriangles) {
  const SurfaceMesh m = test::tube(24, 16, 4, true);
  const std::vector<Joint> joints = make_tube_skeleton({0.5, 2.0, 3.5});
  const std::vector<int> dominant(m.num_vertices(), 1);
  QualityOptions q;
  q.limbs = {{0, 1, 2}};
  // Rest: nothing changes.
  const std::vector<Mat4> rest(3, Mat4::Identity());
  auto d = measure_deformation(m, m.positions, joints, rest, dominant, q);
  EXPECT_EQ(d.volume_change, 0.0);
  EXPECT_NEAR(d.smallest_section, 1.0, 1e-12);
  EXPECT_EQ(d.bulge, 0.0);
  EXPECT_EQ(d.turned, 0);
  EXPECT_EQ(d.stretch_max, 0.0);
  // Every vertex pushed 0.1 away from the axis: the growth is 0.1 (over the
  // diagonal); the sections grow by (1.1)^2.
  std::vector<Vec3> fat = m.positions;
  for (auto& p : fat) {
    const Vec3 radial(p.x(), 0, p.z());
    if (radial.norm() > 1e-9)
      p += 0.1 * radial.normalized();
  }
  d = measure_deformation(m, fat, joints, rest, dominant, q);
  EXPECT_NEAR(d.bulge * m.bbox_diagonal(), 0.1, 1e-9);
  EXPECT_NEAR(d.smallest_section, 1.21, 1e-9);
  EXPECT_GT(d.volume_change, 0.15);
  // The whole tube scaled by 2: volume times 8, every edge twice as long.
  std::vector<Vec3> twice = m.positions;
  for (auto& p : twice)
    p *= 2;
  d = measure_deformation(m, twice, joints, std::vector<Mat4>(3, Mat4(Eigen::Affine3d(Eigen::Scaling(2.0)).matrix())),
                          dominant, q);
  EXPECT_NEAR(d.volume_change, 7.0, 1e-9);
  EXPECT_NEAR(d.stretch_mean, 1.0, 1e-12);
  EXPECT_NEAR(d.stretch_max, 1.0, 1e-12);
  EXPECT_EQ(d.turned, 0);
  // Turned against the dominant joint: the rest surface measured against a
  // joint turned half way round, every triangle's normal is more than 90
  // degrees off (but the ones whose normal is along the turn's axis).
  const Mat4 half = Eigen::Affine3d(Eigen::AngleAxisd(std::numbers::pi, Vec3::UnitX())).matrix();
  d = measure_deformation(m, m.positions, joints, std::vector<Mat4>(3, half), dominant, q);
  EXPECT_GT(d.turned, 0);
}
