// The half-edge cut mesh: construction, mutations, and the validator after
// every mutation.

#include "curvenet/errors.hpp"
#include "cut/cut_mesh.hpp"
#include "helpers.hpp"
#include "trace/trace_mesh.hpp"

#include <gtest/gtest.h>

using namespace curvenet;
using namespace curvenet::detail;

namespace {
void expect_valid(const CutMesh& m) {
  const auto fault = m.validate();
  EXPECT_FALSE(fault.has_value()) << *fault;
}
} // namespace

TEST(CutMesh, FromSurfaceKeepsIdentities) {
  const SurfaceMesh s = make_surface_mesh(test::grid(2, 2), "grid");
  const CutMesh m = CutMesh::from_surface(s);
  expect_valid(m);
  EXPECT_EQ(m.num_vertices(), 9);
  EXPECT_EQ(m.num_faces(), 4);
  EXPECT_EQ(m.num_edges(), 12);
  for (int f = 0; f < 4; ++f) {
    const auto loop = m.face_loop(Face(f));
    ASSERT_EQ(loop.size(), 4u);
    for (size_t i = 0; i < 4; ++i)
      EXPECT_EQ(m.from(loop[i]).idx, s.face(f)[i]);
  }
  // The centre vertex has four outgoing half-edges, a corner two.
  EXPECT_EQ(m.outgoing(Vertex(4)).size(), 4u);
  EXPECT_EQ(m.outgoing(Vertex(0)).size(), 2u);
}

TEST(CutMesh, SplitEdgeKeepsBothFacesClosed) {
  const SurfaceMesh s = make_surface_mesh(test::grid(2, 1), "grid");
  CutMesh m = CutMesh::from_surface(s);
  // The interior edge 1-4 between the two quads.
  Halfedge h;
  for (int i = 0; i < m.num_halfedges(); ++i)
    if (m.from(Halfedge(i)).idx == 1 && m.to(Halfedge(i)).idx == 4)
      h = Halfedge(i);
  ASSERT_TRUE(h.is_valid());
  const Vertex v = m.split_edge(h, {1, 0.5, 0}, {VertexOrigin::Kind::OnEdge, h.idx / 2, 0.5});
  expect_valid(m);
  EXPECT_EQ(m.to(h), v);
  EXPECT_EQ(m.from(m.next(h)), v);
  EXPECT_EQ(m.face_loop(Face(0)).size(), 5u);
  EXPECT_EQ(m.face_loop(Face(1)).size(), 5u);
  const Vertex w = m.split_edge(m.next(h), {1, 0.75, 0}, {VertexOrigin::Kind::OnEdge, h.idx / 2, 0.75});
  expect_valid(m);
  EXPECT_EQ(m.face_loop(Face(0)).size(), 6u);
  EXPECT_EQ(m.outgoing(w).size(), 2u);
}

TEST(CutMesh, SubdivideFaceAlongAChordAcrossAPlanarQuad) {
  const SurfaceMesh s = make_surface_mesh(test::grid(1, 1), "quad");
  CutMesh m = CutMesh::from_surface(s);
  // Split the bottom (0-1) and top (2-3) edges, then connect them.
  const auto loop = m.face_loop(Face(0));
  const Vertex a = m.split_edge(loop[0], {0.5, 0, 0}, {});
  expect_valid(m);
  const Vertex b = m.split_edge(m.face_loop(Face(0))[3], {0.5, 1, 0}, {});
  expect_valid(m);
  const Chord chord{a, b, {0, true}};
  const auto hs = m.subdivide_face(Face(0), std::span<const Chord>(&chord, 1));
  expect_valid(m);
  ASSERT_EQ(hs.size(), 1u);
  EXPECT_EQ(m.num_faces(), 2);
  EXPECT_EQ(m.face_loop(Face(0)).size(), 4u);
  EXPECT_EQ(m.face_loop(Face(1)).size(), 4u);
  EXPECT_TRUE(m.tag(hs[0]).forward);
  EXPECT_FALSE(m.tag(CutMesh::twin(hs[0])).forward);
  EXPECT_NEAR(m.face_area(Face(0)) + m.face_area(Face(1)), 1.0, 1e-15);
}

TEST(CutMesh, InteriorVertexOfDegreeOneIsACrack) {
  const SurfaceMesh s = make_surface_mesh(test::grid(1, 1), "quad");
  CutMesh m = CutMesh::from_surface(s);
  const Vertex c = m.add_isolated_vertex({0.5, 0.5, 0}, {VertexOrigin::Kind::InFace, 0, 0});
  const Chord chord{Vertex(0), c, {0, true}};
  m.subdivide_face(Face(0), std::span<const Chord>(&chord, 1));
  expect_valid(m);
  EXPECT_EQ(m.num_faces(), 1);
  EXPECT_EQ(m.face_loop(Face(0)).size(), 6u); // the crack is walked on both sides
}

TEST(CutMesh, InteriorStarSplitsTheFaceIntoFans) {
  const SurfaceMesh s = make_surface_mesh(test::grid(1, 1), "quad");
  CutMesh m = CutMesh::from_surface(s);
  const Vertex c = m.add_isolated_vertex({0.4, 0.6, 0}, {VertexOrigin::Kind::InFace, 0, 0});
  std::vector<Chord> chords;
  for (int v = 0; v < 4; ++v)
    chords.push_back({Vertex(v), c, {v, true}});
  m.subdivide_face(Face(0), chords);
  expect_valid(m);
  EXPECT_EQ(m.num_faces(), 4);
  for (int f = 0; f < 4; ++f)
    EXPECT_EQ(m.face_loop(Face(f)).size(), 3u);
}

TEST(CutMesh, AChordOutsideItsFaceIsRefused) {
  // An L-shaped hexagon: the chord between the two arm tips leaves it.
  RawMesh r;
  r.positions = {{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {1, 2, 0}, {0, 2, 0}};
  r.add_face(std::vector<int>{0, 1, 2, 3, 4, 5});
  const SurfaceMesh s = make_surface_mesh(r, "L");
  CutMesh m = CutMesh::from_surface(s);
  const Chord chord{Vertex(2), Vertex(4), {0, true}};
  EXPECT_THROW(m.subdivide_face(Face(0), std::span<const Chord>(&chord, 1)), EmbedError);
}

TEST(CutMesh, AFoldedQuadIsLaidOutUnfoldedAndSplitsCleanly) {
  // A unit square folded 150 degrees about its diagonal 0-2: seen along its
  // average normal it overlaps itself, yet it is a fine piece of surface.
  RawMesh r;
  const Vec3 d = Eigen::AngleAxisd(150 * EIGEN_PI / 180, Vec3(1, 1, 0).normalized()) * Vec3(0, 1, 0);
  r.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, d};
  r.add_face(std::vector<int>{0, 1, 2, 3});
  const SurfaceMesh s = make_surface_mesh(r, "folded");
  CutMesh m = CutMesh::from_surface(s);
  // The layout keeps every side's length.
  for (int i = 0; i < 4; ++i) {
    const Vertex a(i), b((i + 1) % 4);
    EXPECT_NEAR((m.to_face_plane(Face(0), a) - m.to_face_plane(Face(0), b)).norm(),
                (m.position(a) - m.position(b)).norm(), 1e-12);
  }
  // A chord from the middle of side 0-1 to the middle of side 2-3.
  const auto loop = m.face_loop(Face(0));
  const Vertex a = m.split_edge(loop[0], (s.positions[0] + s.positions[1]) / 2, {VertexOrigin::Kind::OnEdge, 0, 0.5});
  expect_valid(m);
  const Vertex b = m.split_edge(m.face_loop(Face(0))[3], (s.positions[2] + s.positions[3]) / 2,
                                {VertexOrigin::Kind::OnEdge, m.edge_origin(m.face_loop(Face(0))[3]), 0.5});
  expect_valid(m);
  const Chord chord{a, b, {0, true}};
  m.subdivide_face(Face(0), std::span<const Chord>(&chord, 1));
  expect_valid(m);
  EXPECT_EQ(m.num_faces(), 2);
}

TEST(CutMesh, ALayoutFollowsTheTracersTrianglesAfterTheLoopStartMoves) {
  // A quad folded so far that neither diagonal splits it cleanly seen along
  // its average normal (a face of Blub's cage): how it is triangulated then
  // depends on its first corner. Splitting its first edge from the
  // neighbour's side moves the start of its loop; its layout must still be
  // the unfolding of the triangles the tracer walks.
  RawMesh r;
  r.positions = {{0.357342, 0.328408, -0.355631},
                 {0.20055, 0.268675, -0.675},
                 {0.257589, 0.182798, -0.649506},
                 {0.0254884, 0.458356, -0.369115},
                 {0.35, 0.05, -0.6}};
  r.add_face(std::vector<int>{0, 1, 2, 3});
  r.add_face(std::vector<int>{1, 0, 4});
  const SurfaceMesh s = make_surface_mesh(r, "folded");
  CutMesh m = CutMesh::from_surface(s);
  const TraceMesh tm(s, m); // the tracer's triangles, from the fresh mesh
  Halfedge across;          // 1 -> 0, in the triangle
  for (Halfedge h : m.face_loop(Face(1)))
    if (m.from(h).idx == 1 && m.to(h).idx == 0)
      across = h;
  ASSERT_TRUE(across.is_valid());
  m.split_edge(across, (s.positions[0] + s.positions[1]) / 2, {VertexOrigin::Kind::OnEdge, across.idx / 2, 0.5});
  expect_valid(m);
  ASSERT_NE(m.from(m.halfedge(Face(0))).idx, 0) << "the quad's loop should now start at the split";
  // Within each of the tracer's triangles the layout is an isometry.
  for (int t = 0; t < tm.num_triangles(); ++t) {
    if (tm.tri_face(t) != 0)
      continue;
    const auto& c = tm.tri(t);
    const Vec3 centre = (tm.position(c[0]) + tm.position(c[1]) + tm.position(c[2])) / 3;
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR((m.to_face_plane(Face(0), centre) - m.to_face_plane(Face(0), Vertex(c[k]))).norm(),
                  (centre - tm.position(c[k])).norm(), 1e-12)
          << "triangle " << t << " corner " << c[k];
  }
}

TEST(CutMesh, InputComponentsAgreeWithTheMeshsOwn) {
  // Two boxes apart, a grid (open) and a tube: counts, closedness, Euler
  // characteristic and the face numbering, against mesh_components().
  RawMesh two = test::box();
  const RawMesh other = test::box(2);
  const int offset = static_cast<int>(two.positions.size());
  for (const auto& p : other.positions)
    two.positions.push_back(p + Eigen::Vector3d(5, 0, 0));
  for (int f = 0; f + 1 < static_cast<int>(other.face_offsets.size()); ++f) {
    std::vector<int> c;
    for (int k = other.face_offsets[f]; k < other.face_offsets[f + 1]; ++k)
      c.push_back(other.face_vertices[k] + offset);
    two.add_face(c);
  }
  for (const SurfaceMesh& m : {make_surface_mesh(two, "two boxes"), make_surface_mesh(test::grid(3, 2, true), "grid"),
                               test::tube(12, 6, 3, false)}) {
    std::vector<int> mine, theirs;
    const auto a = detail::input_components(detail::CutMesh::from_surface(m), mine);
    const auto b = mesh_components(m, &theirs);
    ASSERT_EQ(a.size(), b.size()) << m.source;
    for (size_t c = 0; c < a.size(); ++c) {
      EXPECT_EQ(a[c].faces, b[c].faces);
      EXPECT_EQ(a[c].closed, b[c].closed);
      EXPECT_EQ(a[c].euler, b[c].euler);
    }
    EXPECT_EQ(mine, theirs);
  }
}
