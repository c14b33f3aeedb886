// Symmetric surface distance, point to surface; and the measures of a
// deformation's quality (curvenet/quality.hpp).

#include "curvenet/compare.hpp"
#include "curvenet/io.hpp"
#include "curvenet/quality.hpp"
#include "curvenet/skin.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

#include <array>
#include <algorithm>
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
  const SurfaceMesh a = make_surface_mesh(make_capped_tube({}), "a"),
                    b = make_surface_mesh(make_capped_tube(fine), "b");
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

TEST(Quality, TheMeanCurvatureNormalOfASphereIsOneOverItsRadiusAndDetailChangeIgnoresTheJointsRotation) {
  // A UV sphere of radius 2.
  RawMesh raw;
  const int rings = 48, around = 96;
  raw.positions.push_back(Vec3(0, 2, 0));
  for (int i = 1; i < rings; ++i)
    for (int k = 0; k < around; ++k) {
      const double t = std::numbers::pi * i / rings, p = 2 * std::numbers::pi * k / around;
      raw.positions.push_back(2 * Vec3(std::sin(t) * std::cos(p), std::cos(t), std::sin(t) * std::sin(p)));
    }
  raw.positions.push_back(Vec3(0, -2, 0));
  auto at = [&](int i, int k) { return 1 + (i - 1) * around + (k % around); };
  const int bottom = static_cast<int>(raw.positions.size()) - 1;
  for (int k = 0; k < around; ++k) {
    raw.add_face(std::array<int, 3>{0, at(1, k + 1), at(1, k)});
    for (int i = 1; i + 1 < rings; ++i)
      raw.add_face(std::array<int, 4>{at(i, k), at(i, k + 1), at(i + 1, k + 1), at(i + 1, k)});
    raw.add_face(std::array<int, 3>{bottom, at(rings - 1, k), at(rings - 1, k + 1)});
  }
  const SurfaceMesh m = make_surface_mesh(raw, "sphere");
  const std::vector<Vec3> h = mean_curvature_normals(m, m.positions);
  double worst = 0;
  for (int v = 0; v < m.num_vertices(); ++v)
    if (std::abs(m.positions[v].y()) < 1.5) // away from the poles' slivers
      worst = std::max(worst, (h[v] - m.positions[v] / 4).norm() / 0.5);
  EXPECT_LT(worst, 0.01) << "H n = n / r, pointing away from the centre";

  const std::vector<Joint> joints = make_tube_skeleton({0.0, 1.0});
  const std::vector<int> dominant(m.num_vertices(), 1);
  auto detail = [&](const std::vector<Vec3>& posed, const Mat4& M) {
    return measure_deformation(m, posed, joints, std::vector<Mat4>(2, M), dominant).detail_change;
  };
  EXPECT_EQ(detail(m.positions, Mat4::Identity()), 0.0);
  // Turned with its joint: no change. Turned without: the normals are off.
  const Eigen::Affine3d turn(Eigen::AngleAxisd(1.0, Vec3(1, 2, 3).normalized()));
  std::vector<Vec3> turned = m.positions;
  for (auto& p : turned)
    p = turn * p;
  EXPECT_LT(detail(turned, turn.matrix()), 1e-9);
  EXPECT_GT(detail(turned, Mat4::Identity()), 0.5);
  // Twice as large: the curvature halves, whatever the joint's scale.
  std::vector<Vec3> twice = m.positions;
  for (auto& p : twice)
    p *= 2;
  EXPECT_NEAR(detail(twice, Mat4(Eigen::Affine3d(Eigen::Scaling(2.0)).matrix())), 0.5, 1e-9);
  // A bump on one vertex changes the detail there, and nowhere else counts
  // when only the far side is measured.
  std::vector<Vec3> bumped = m.positions;
  bumped[m.input_to_welded[at(24, 0)]] *= 1.05;
  EXPECT_GT(detail(bumped, Mat4::Identity()), 0.0);
  QualityOptions far;
  far.detail_vertices.assign(m.num_vertices(), 0);
  for (int v = 0; v < m.num_vertices(); ++v)
    far.detail_vertices[v] = m.positions[v].x() < -1;
  EXPECT_EQ(measure_deformation(m, bumped, joints, std::vector<Mat4>(2, Mat4::Identity()), dominant, far)
                .detail_change,
            0.0);
}

TEST(Quality, TurnedTrianglesAreThoseAJointsRotationDoesNotCarry) {
  const SurfaceMesh m = test::tube(24, 16, 4, true);
  const std::vector<int> dominant(m.num_vertices(), 0);
  // A rigid turn of the whole mesh, by the joint that carries it: nothing turned over.
  const Mat4 turn = Eigen::Affine3d(Eigen::AngleAxisd(2.0, Vec3(1, 2, 3).normalized())).matrix();
  std::vector<Vec3> turned_mesh = m.positions;
  for (auto& p : turned_mesh)
    p = (turn * p.homogeneous()).head<3>();
  EXPECT_EQ(turned_triangles(m, turned_mesh, std::vector<Mat4>{turn}, dominant), 0);
  // The same positions with the joint left at rest: every triangle whose
  // normal the turn moves by more than 90 degrees counts, and only those.
  int expected = 0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const auto c = m.face(f);
    for (size_t k = 1; k + 1 < c.size(); ++k) {
      const Vec3 n0 = (m.positions[c[k]] - m.positions[c[0]]).cross(m.positions[c[k + 1]] - m.positions[c[0]]);
      const Vec3 n1 = (turned_mesh[c[k]] - turned_mesh[c[0]]).cross(turned_mesh[c[k + 1]] - turned_mesh[c[0]]);
      expected += n0.norm() > 0 && n1.normalized().dot(n0.normalized()) < 0;
    }
  }
  EXPECT_GT(expected, 0);
  EXPECT_EQ(turned_triangles(m, turned_mesh, std::vector<Mat4>{Mat4::Identity()}, dominant), expected);
  // One triangle turned over in place (two corners swapped on the mesh's
  // own positions is the same as reflecting it): exactly one fan triangle
  // of a quad flips when one corner crosses the opposite diagonal.
  std::vector<Vec3> dented = m.positions;
  const auto c = m.face(0);
  const Vec3 centre = (m.positions[c[0]] + m.positions[c[2]]) / 2;
  dented[c[1]] = centre + 1.5 * (centre - m.positions[c[1]]);
  const int n = turned_triangles(m, dented, std::vector<Mat4>{Mat4::Identity()}, dominant);
  EXPECT_GE(n, 1);
  EXPECT_LE(n, 6); // the dented corner's own triangles at most
}

TEST(Quality, ADominantJointIsTheStrongestOfAWeldedVertex) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string path = test::data("quaternius/Trex.glb");
  const SurfaceMesh m = load_mesh(path);
  const SkinnedMesh s = load_skinned_mesh(path);
  const std::vector<int> d = dominant_joints(m, s);
  ASSERT_EQ(d.size(), static_cast<size_t>(m.num_vertices()));
  // No input vertex of a welded vertex weighs another joint more.
  std::vector<double> strongest(m.num_vertices(), 0);
  for (size_t i = 0; i < s.vertex_joint.size(); ++i)
    for (int k = 0; k < 4; ++k)
      if (s.vertex_joint[i][k] == d[m.input_to_welded[i]])
        strongest[m.input_to_welded[i]] = std::max(strongest[m.input_to_welded[i]], s.vertex_weight[i][k]);
  for (size_t i = 0; i < s.vertex_joint.size(); ++i)
    for (int k = 0; k < 4; ++k)
      if (s.vertex_joint[i][k] >= 0)
        EXPECT_LE(s.vertex_weight[i][k], strongest[m.input_to_welded[i]]) << "input vertex " << i;
  // The head's vertices: the Head joint, for the most part.
  int head = -1;
  for (size_t j = 0; j < s.joints.size(); ++j)
    if (s.joints[j].name == "Head")
      head = static_cast<int>(j);
  ASSERT_GE(head, 0);
  EXPECT_GT(std::count(d.begin(), d.end(), head), 100);
}
