// Stage "regions": barrier flood fill, the outside of a local net, colours.

#include "cut/cut_mesh.hpp"
#include "helpers.hpp"
#include "regions/regions.hpp"

#include <gtest/gtest.h>

using namespace curvenet;
using namespace curvenet::detail;

TEST(Regions, ColouringSeparatesNeighbours) {
  // A wheel: a hub joined to a 5-cycle (needs 4 colours).
  std::vector<std::vector<int>> adj(6);
  auto link = [&](int a, int b) {
    adj[a].push_back(b);
    adj[b].push_back(a);
  };
  for (int i = 1; i <= 5; ++i) {
    link(0, i);
    link(i, i % 5 + 1);
  }
  const auto c = colour_graph(adj);
  for (int a = 0; a < 6; ++a)
    for (int b : adj[a]) EXPECT_NE(c[a], c[b]);
  EXPECT_NE(palette_colour(0), palette_colour(1));
  EXPECT_NE(palette_colour(12), palette_colour(13));
}

TEST(Regions, FloodFillStopsAtCurveEdgesOnly) {
  // A 3x1 strip of quads; tag the edge between quads 0 and 1 as a curve.
  const SurfaceMesh s = make_surface_mesh(test::grid(3, 1), "strip");
  CutMesh m = CutMesh::from_surface(s);
  for (int h = 0; h < m.num_halfedges(); ++h) {
    const Halfedge he(h);
    if (m.from(he).idx == 1 && m.to(he).idx == 5) m.set_tag(he, {0, true});
  }
  std::vector<int> component(s.num_faces(), 0);
  const RegionResult full = find_regions(m, {"wall"}, Coverage::Full, component);
  ASSERT_EQ(full.regions.size(), 2u);
  EXPECT_EQ(full.face_region[0], 0);
  EXPECT_EQ(full.face_region[1], full.face_region[2]);
  EXPECT_NE(full.face_region[0], full.face_region[1]);
  // Each side of the wall knows which side of the profile it is on.
  EXPECT_EQ(full.regions[0].boundary.size(), 1u);
  EXPECT_NE(full.regions[0].boundary[0].second, full.regions[1].boundary[0].second);
  EXPECT_NE(full.regions[0].colour, full.regions[1].colour);
  // With local coverage both pieces reach the mesh boundary: both are outside.
  const RegionResult local = find_regions(m, {"wall"}, Coverage::Local, component);
  EXPECT_EQ(local.regions.size(), 0u);
  EXPECT_EQ(local.outside_faces, 3);
}
