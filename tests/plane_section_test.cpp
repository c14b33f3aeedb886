// Plane sections of a surface: the polylines where a plane cuts it, paths
// along them, and the distances between polylines they are checked with.

#include "core/plane_section.hpp"
#include "core/polyline_distance.hpp"
#include "core/predicates.hpp"
#include "curvenet/io.hpp"
#include "curvenet/surface_mesh.hpp"
#include "generate/tube.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

using namespace curvenet;

namespace {

SurfaceMesh tube() {
  return make_surface_mesh(make_capped_tube(TubeSpec{}), "tube");
}

} // namespace

TEST(PlaneSection, CutsATubeIntoOneClosedPolygon) {
  const SurfaceMesh m = tube();
  const detail::SectionMesh sm(m);
  const auto sections = detail::plane_sections(sm, {0, 2.05, 0}, {0, 1, 0});
  ASSERT_EQ(sections.size(), 1u);
  EXPECT_TRUE(sections[0].closed);
  EXPECT_NEAR(sections[0].length(), 16 * 2 * std::sin(std::numbers::pi / 16), 1e-12); // the 16-gon
  EXPECT_EQ(detail::winding_number(sections[0].points, {0, 2.05, 0}, {0, 2.05, 0}, {0, 1, 0}) != 0, true);
  EXPECT_EQ(detail::winding_number(sections[0].points, {3, 2.05, 0}, {0, 2.05, 0}, {0, 1, 0}), 0);
  // A plane through a ring of vertices still gives one closed loop.
  EXPECT_EQ(detail::plane_sections(sm, {0, 2.0, 0}, {0, 1, 0}).size(), 1u);
  // A plane along the axis cuts the tube in one loop too (side, caps, side, caps).
  const auto along = detail::plane_sections(sm, {0, 2, 0}, {0, 0, 1});
  ASSERT_EQ(along.size(), 1u);
  EXPECT_NEAR(along[0].length(), 2 * 4 + 4 * 1.0, 1e-9);
}

TEST(PlaneSection, CutsTheSameLoopAtAnyScale) {
  // The plane was set by the origin and unit steps from it: at 1e17 a unit
  // step rounds back onto the origin, the three points were one, and the
  // plane cut nothing (the starter found no ring at a scale of 1e19).
  for (const double scale : {1e-30, 1.0, 1e17, 1e19, 1e30}) {
    RawMesh raw = make_capped_tube(TubeSpec{});
    const Vec3 away(3, 0, 5); // off the axes, so that the plane's points need all their digits
    for (Vec3& p : raw.positions)
      p = (p + away) * scale;
    const SurfaceMesh m = make_surface_mesh(raw, "tube");
    const detail::SectionMesh sm(m);
    const Vec3 at = Vec3(away.x(), 2.05, away.z()) * scale;
    const auto sections = detail::plane_sections(sm, at, {0, 1, 0});
    ASSERT_EQ(sections.size(), 1u) << scale;
    EXPECT_NEAR(sections[0].length() / scale, 16 * 2 * std::sin(std::numbers::pi / 16), 1e-9) << scale;
    EXPECT_NE(detail::winding_number(sections[0].points, at, at, {0, 1, 0}), 0) << scale;
  }
}

TEST(PlaneSection, APathThroughThreePointsFollowsTheSectionTheyLieOnThroughTheMiddleOne) {
  const SurfaceMesh m = tube();
  const detail::SectionMesh sm(m);
  const auto ring = detail::plane_sections(sm, {0, 2.05, 0}, {0, 1, 0})[0].points;
  const size_t n = ring.size();
  ASSERT_EQ(n % 4, 0u);
  const Vec3 a = ring[0], b = ring[n / 2];
  auto length = [](const std::vector<Vec3>& p) {
    double l = 0;
    for (size_t k = 1; k < p.size(); ++k)
      l += (p[k] - p[k - 1]).norm();
    return l;
  };
  const double half = 8 * 2 * std::sin(std::numbers::pi / 16); // half the 16-gon
  for (const size_t through : {n / 4, 3 * n / 4}) {
    const auto path = detail::section_path_through(sm, a, ring[through], b, 1e-9);
    ASSERT_TRUE(path.has_value()) << through;
    EXPECT_EQ(path->front(), a);
    EXPECT_EQ(path->back(), b);
    EXPECT_NEAR(length(*path), half, 1e-12) << through;
    EXPECT_TRUE(
        std::any_of(path->begin(), path->end(), [&](const Vec3& q) { return (q - ring[through]).norm() < 1e-12; }))
        << "the path passes through the middle point " << through;
    for (const Vec3& q : *path)
      EXPECT_NEAR(q.y(), 2.05, 1e-12);
  }
  // A quarter: from a to the point a quarter round, through the one between.
  const auto quarter = detail::section_path_through(sm, a, ring[n / 8], ring[n / 4], 1e-9);
  ASSERT_TRUE(quarter.has_value());
  EXPECT_NEAR(length(*quarter), half / 2, 1e-12);
  // Collinear points make no plane; a point off the surface lies on no section.
  EXPECT_FALSE(detail::section_path_through(sm, a, (a + b) / 2, b, 1e-9).has_value());
  EXPECT_FALSE(detail::section_path_through(sm, a, ring[n / 4] * 0.5 + Vec3(0, 1.0, 0), b, 1e-9).has_value());
}

TEST(PlaneSection, EverySectionOfAClosedMeshOfTwistedNgonsIsOneClosedLoop) {
  // The T-rex with random edges dissolved into 5- to 8-sided polygons, many
  // of them twisted and concave. Each polygon is cut as a fan of triangles;
  // its diagonals were keyed by their corners, so one polygon's diagonal
  // could be another's edge: an edge of three triangles, whose walk went
  // round a loop for ever (the starter and the transfer ran out of memory
  // at 4 GB). A closed surface's sections are closed loops.
  const SurfaceMesh m = load_mesh(std::string(CURVENET_SOURCE_DIR) + "/tests/data/ngons/Trex_ngons.obj");
  ASSERT_GT(m.num_faces(), 300);
  const detail::SectionMesh sm(m);
  int sections = 0;
  for (size_t v = 0; v < m.positions.size(); v += 5)
    for (const Vec3& n : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0.6, 0.8)}) {
      const Vec3 at = m.positions[v] + Vec3(1e-3, 2e-3, 3e-3); // off the vertices
      for (const auto& s : detail::plane_sections(sm, at, n)) {
        ++sections;
        EXPECT_TRUE(s.closed) << "vertex " << v << ", normal " << n.transpose();
        EXPECT_LE(s.points.size(), 2 * sm.num_edges());
      }
    }
  EXPECT_GT(sections, 100);
}

TEST(PlaneSection, PolylineDistancesSkipOnlyPairsThatCannotBeNearer) {
  // Random polylines, open and closed: the pruned distance is the smallest
  // over every pair of segments, and `polylines_within` agrees with it for
  // every threshold.
  std::mt19937 rng(20);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<Vec3> a(3 + trial % 7), b(2 + trial % 5);
    const Vec3 shift(u(rng), u(rng), u(rng));
    for (auto& p : a)
      p = Vec3(u(rng), u(rng), u(rng)) * 0.4;
    for (auto& p : b)
      p = Vec3(u(rng), u(rng), u(rng)) * 0.4 + 1.5 * shift;
    const bool ca = trial % 2 == 0, cb = trial % 3 == 0;
    double brute = INFINITY;
    for (size_t i = 0; i < (ca ? a.size() : a.size() - 1); ++i)
      for (size_t j = 0; j < (cb ? b.size() : b.size() - 1); ++j)
        brute = std::min(brute,
                         curvenet::detail::segment_distance(a[i], a[(i + 1) % a.size()], b[j], b[(j + 1) % b.size()]));
    const double d = curvenet::detail::polyline_distance(a, ca, b, cb);
    EXPECT_EQ(d, brute);
    for (const double f : {0.5, 0.99, 1.01, 2.0})
      EXPECT_EQ(curvenet::detail::polylines_within(a, ca, b, cb, f * brute), f * brute > brute) << trial << " " << f;
  }
}

TEST(PlaneSection, ASectionVisitsOnlyTheTrianglesNearItsPlaneAndEveryOneItCrosses) {
  // A starter on a dense mesh asks for thousands of sections, and each
  // decided the side of every vertex (33 s at 280k faces). The tree of
  // boxes passes over the triangles far from the plane; it must never pass
  // over one the plane crosses, not even through a vertex, at any scale.
  for (const double scale : {1e-30, 1.0, 1e17}) {
    RawMesh raw = make_capped_tube(TubeSpec{1.0, 4.0, 96, 192, 8, true});
    for (Vec3& p : raw.positions)
      p = (p + Vec3(3, 0, 5)) * scale;
    const SurfaceMesh m = make_surface_mesh(raw, "tube");
    const detail::SectionMesh sm(m);
    ASSERT_GT(sm.num_triangles(), 30000);
    std::mt19937 rng(7);
    std::uniform_int_distribution<size_t> vertex(0, m.positions.size() - 1);
    std::normal_distribution<double> gauss;
    std::vector<int> near;
    for (int k = 0; k < 60; ++k) {
      // Through a vertex (and so through whole rings when across the axis),
      // or through a point off every vertex; across the tube, or any way.
      const Vec3 at =
          k % 2 == 0 ? m.positions[vertex(rng)] : Vec3(m.positions[vertex(rng)] + scale * Vec3(1e-3, 2e-3, -3e-3));
      const Vec3 n = k % 3 == 0 ? Vec3(0, 1, 0) : Vec3(gauss(rng), gauss(rng), gauss(rng)).normalized();
      sm.triangles_near_plane(at, n, near);
      std::vector<char> in(sm.num_triangles(), 0);
      for (int t : near)
        in[t] = 1;
      // Sides as plane_sections decides them: exactly, a vertex on the plane above.
      const auto [u, v] = detail::plane_basis(n);
      const double step = std::max(1.0, at.cwiseAbs().maxCoeff());
      const Vec3 o1 = at + step * u, o2 = at + step * v;
      int crossed = 0;
      for (int t = 0; t < sm.num_triangles(); ++t) {
        int above = 0;
        for (int c : sm.tri(t))
          above += detail::orient3d(at, o1, o2, m.positions[c]) >= 0;
        if (above == 1 || above == 2) {
          ++crossed;
          EXPECT_TRUE(in[t]) << "scale " << scale << ", plane " << k << ": triangle " << t << " passed over";
        }
      }
      EXPECT_GT(crossed, 0);
      if (n == Vec3(0, 1, 0)) // a section across the tube: one ring of its triangles, a few more
        EXPECT_LT(near.size(), sm.num_triangles() / 20) << "plane " << k;
    }
  }
}
