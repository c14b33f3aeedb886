// Refinement: Catmull-Clark of control cages (counts, shape, and that a
// cage's limit surface is the surface its remeshes stand for), and midpoint
// refinement, which keeps a triangle mesh's surface.

#include "curvenet/compare.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/subdivide.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

using namespace curvenet;

namespace {
SurfaceMesh cube() {
  return make_surface_mesh(test::box(), "cube");
}
} // namespace

TEST(Subdivide, ACubeRefinesIntoQuadsThatStayClosedAndSymmetric) {
  const SurfaceMesh c = cube();
  for (int level = 1; level <= 3; ++level) {
    const SurfaceMesh s = catmull_clark(c, level);
    const int faces = 6 << (2 * level);
    EXPECT_EQ(s.num_faces(), faces);
    EXPECT_EQ(s.num_vertices(), faces + 2); // closed, genus 0: V - E + F = 2 with E = 2F
    for (int f = 0; f < s.num_faces(); ++f)
      EXPECT_EQ(s.face(f).size(), 4u);
    const auto comps = mesh_components(s);
    ASSERT_EQ(comps.size(), 1u);
    EXPECT_TRUE(comps[0].closed);
    EXPECT_EQ(comps[0].euler, 2);
    // Inside the cage, pulled away from its corners, and centred.
    Vec3 mean = Vec3::Zero();
    for (const auto& p : s.positions) {
      EXPECT_TRUE((p.array() >= 0).all() && (p.array() <= 1).all()) << p.transpose();
      EXPECT_FALSE(((p.array() == 0) || (p.array() == 1)).all()) << "a vertex stayed on a corner: " << p.transpose();
      mean += p;
    }
    EXPECT_LT((mean / s.num_vertices() - Vec3(0.5, 0.5, 0.5)).norm(), 1e-12);
  }
}

TEST(Subdivide, AFlatGridStaysFlat) {
  const SurfaceMesh g = make_surface_mesh(test::grid(3, 2), "grid");
  const SurfaceMesh s = catmull_clark(g, 2);
  EXPECT_EQ(s.num_faces(), 6 * 16);
  for (const auto& p : s.positions)
    EXPECT_EQ(p.z(), 0.0);
}

TEST(Subdivide, LevelsOutOfRangeAreRefused) {
  EXPECT_THROW(catmull_clark(cube(), 0), InputError);
  EXPECT_THROW(catmull_clark(cube(), 7), InputError);
}

TEST(Subdivide, ACageRefinedMeetsItsRemesh) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // Spot's and Blub's triangle meshes are remeshes of their cages' limit
  // surfaces: the bare cage lies far off them, the refined cage on them.
  for (const auto& [cage, remesh] : {std::pair{"spot/spot_control_mesh.obj", "spot/spot_triangulated.obj"},
                                     std::pair{"blub/fish_control_mesh.obj", "blub/fish_low_resolution.obj"}}) {
    const SurfaceMesh c = load_mesh(test::data(cage)), r = load_mesh(test::data(remesh));
    const SurfaceDistance bare = surface_distance(r, c), refined = surface_distance(r, catmull_clark(c, 3));
    std::printf("%s: bare cage mean %.3f%% max %.3f%%, refined (3 levels) mean %.3f%% max %.3f%%\n", cage,
                bare.percent(bare.mean), bare.percent(bare.max), refined.percent(refined.mean),
                refined.percent(refined.max));
    EXPECT_LT(refined.percent(refined.mean), 0.2) << cage;
    EXPECT_LT(refined.mean, bare.mean / 5) << cage;
    EXPECT_LT(refined.max, bare.max / 2) << cage;
  }
}

TEST(Subdivide, ARefinementPastItsFaceLimitIsRefusedBeforeItIsMade) {
  // A cube's 6 quads at 6 levels make 6 * 4^6 = 24,576 faces.
  EXPECT_EQ(catmull_clark(cube(), 6).num_faces(), 24576);
  try {
    catmull_clark(cube(), 6, 10000);
    FAIL() << "the limit was not kept";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("levels 6: would make 24576 faces"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--max-faces"), std::string::npos) << e.what();
  }
}

TEST(Subdivide, MidpointRefinementKeepsATriangleMeshsSurfaceExactly) {
  // Every refined vertex lies on the original surface (a triangle's
  // centroid and edge midpoints are on it), the original vertices stay
  // where they were, and each triangle becomes 3 quads, then 4 per level.
  const SurfaceMesh tris = test::tube(12, 6, 3, true);
  for (int levels : {1, 2}) {
    const SurfaceMesh fine = midpoint_subdivide(tris, levels);
    EXPECT_EQ(fine.num_faces(), 3 * tris.num_faces() * (levels == 1 ? 1 : 4));
    for (int f = 0; f < fine.num_faces(); ++f)
      EXPECT_EQ(fine.face(f).size(), 4u);
    for (int v = 0; v < tris.num_vertices(); ++v)
      EXPECT_EQ(fine.positions[v], tris.positions[v]);
    const SurfaceDistance d = surface_distance(fine, tris, 2);
    EXPECT_LT(d.max, 1e-12 * d.diagonal) << levels;
    EXPECT_NEAR(fine.enclosed_volume(fine.positions), tris.enclosed_volume(tris.positions),
                1e-12 * tris.enclosed_volume(tris.positions));
  }
  // A quad mesh's non-planar quads are refined on their bilinear patches:
  // close to the triangulated surface, not on it.
  const SurfaceMesh quads = test::tube(12, 6, 3, false);
  const SurfaceDistance dq = surface_distance(midpoint_subdivide(quads, 1), quads, 2);
  EXPECT_LT(dq.max, 0.01 * dq.diagonal);
}
