// Procedural data: the capped tube and the tube net.

#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

using namespace curvenet;

TEST(Tube, IsClosedGenusZeroAndOutward) {
  for (const bool tri : {false, true}) {
    TubeSpec spec;
    spec.triangulate = tri;
    const SurfaceMesh m = make_surface_mesh(make_capped_tube(spec), "tube");
    EXPECT_TRUE(m.notes.empty()); // nothing to weld or repair
    const auto comps = mesh_components(m);
    ASSERT_EQ(comps.size(), 1u);
    EXPECT_TRUE(comps[0].closed);
    EXPECT_EQ(comps[0].genus(), 0);
    double volume = 0; // divergence theorem: positive when faces point outward
    for (int f = 0; f < m.num_faces(); ++f) {
      const auto c = m.face(f);
      for (size_t k = 1; k + 1 < c.size(); ++k)
        volume += m.positions[c[0]].dot(m.positions[c[k]].cross(m.positions[c[k + 1]])) / 6;
    }
    // pi r^2 L = 12.57 for the exact cylinder; the 16-gon holds a little less.
    EXPECT_GT(volume, 12.0);
    EXPECT_LT(volume, 4 * 3.14159266);
  }
}

TEST(Tube, NetCountsFollowTheSpec) {
  const Rig thesis = make_tube_net();
  EXPECT_EQ(thesis.nodes.size(), 14u);
  EXPECT_EQ(thesis.profiles.size(), 28u);
  TubeNetSpec spec;
  spec.ring_heights = {1, 2, 3, 3.5};
  spec.nodes_per_ring = 6;
  const Rig dense = make_tube_net(spec);
  EXPECT_EQ(dense.nodes.size(), 4u * 6 + 2);
  EXPECT_EQ(dense.profiles.size(), 4u * 6 + 3 * 6 + 2 * 6);
  // Every profile starts and ends at its nodes.
  for (const auto& p : dense.profiles) {
    EXPECT_EQ(p.curve.points.front(), dense.nodes[dense.node_index(p.from)].position) << p.id;
    EXPECT_EQ(p.curve.points.back(), dense.nodes[dense.node_index(p.to)].position) << p.id;
  }
}
