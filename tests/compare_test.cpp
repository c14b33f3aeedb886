// Symmetric surface distance, point to surface.

#include "curvenet/compare.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

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
