// Stage "project and trace": placing points on the surface and walking it.

#include "core/polygon.hpp"
#include "curvenet/errors.hpp"
#include "helpers.hpp"
#include "trace/tracer.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdint>

using namespace curvenet;
using namespace curvenet::detail;
using Kind = SurfacePoint::Kind;

namespace {
struct Fixture {
  SurfaceMesh mesh;
  CutMesh cut;
  std::unique_ptr<TraceMesh> tm;
  explicit Fixture(RawMesh raw) : mesh(make_surface_mesh(raw, "fixture")), cut(CutMesh::from_surface(mesh)) {
    tm = std::make_unique<TraceMesh>(mesh, cut);
  }
  TracedProfile trace(Vec3 a, Vec3 b, int n = 40) {
    const Tolerances tol = Tolerances::for_model(mesh.bbox_diagonal());
    TraceInput in;
    in.profile_id = "p";
    for (int i = 0; i < n; ++i)
      in.samples.push_back(a + (b - a) * i / (n - 1));
    in.from = place_node(*tm, a, tol);
    in.to = place_node(*tm, b, tol);
    in.from_node = 0;
    in.to_node = 1;
    return trace_profile(*tm, in, mesh.mean_edge_length(), tol);
  }
};
} // namespace

TEST(Tracer, ClosestPointIsClassifiedExactly) {
  Fixture f(test::grid(2, 2, true));
  const Tolerances tol = Tolerances::for_model(f.mesh.bbox_diagonal());
  EXPECT_EQ(f.tm->closest_point({1, 1, 0.3}).kind, Kind::Vertex);
  EXPECT_EQ(f.tm->closest_point({1, 0.5, -0.2}).kind, Kind::Edge);
  EXPECT_EQ(f.tm->closest_point({0.8, 0.3, 0.1}).kind, Kind::Face);
  // A node a hair away from a vertex is placed on it.
  EXPECT_EQ(place_node(*f.tm, {1 + 1e-9, 1, 0}, tol).kind, Kind::Vertex);
  EXPECT_EQ(place_node(*f.tm, {1.003, 1.001, 0}, tol).kind, Kind::Face);
}

TEST(Tracer, CrossingsComeOutOrderedAlongTheProfile) {
  Fixture f(test::grid(4, 1));
  const auto t = f.trace({0.5, 0.5, 0}, {3.5, 0.4, 0});
  ASSERT_EQ(t.points.size(), 5u); // node, three crossings, node
  for (int i = 1; i <= 3; ++i) {
    ASSERT_EQ(t.points[i].at.kind, Kind::Edge);
    EXPECT_NEAR(t.points[i].at.pos.x(), i, 1e-12);
  }
  EXPECT_EQ(t.points.front().node, 0);
  EXPECT_EQ(t.points.back().node, 1);
}

TEST(Tracer, ACurveThroughAVertexHitsIt) {
  Fixture f(test::grid(2, 2));
  const auto t = f.trace({0.5, 0.5, 0}, {1.5, 1.5, 0});
  ASSERT_EQ(t.points.size(), 3u);
  EXPECT_EQ(t.points[1].at.kind, Kind::Vertex);
  EXPECT_EQ(t.points[1].at.vertex, 4);
}

TEST(Tracer, ACurveAlongEdgesVisitsTheirVertices) {
  Fixture f(test::grid(4, 2, true));
  const auto t = f.trace({0, 1, 0}, {4, 1, 0});
  // Nodes on boundary vertices 5 and 9; the path runs through 6, 7, 8 and
  // never leaves the line y = 1.
  std::vector<int> vertices;
  for (const auto& p : t.points) {
    EXPECT_EQ(p.at.pos.y(), 1.0);
    EXPECT_NE(p.at.kind, Kind::Face);
    if (p.at.kind == Kind::Vertex)
      vertices.push_back(p.at.vertex);
  }
  EXPECT_EQ(vertices, (std::vector<int>{5, 6, 7, 8, 9}));
}

TEST(TraceMesh, NearestIsTheClosestTriangleLowestFirstWhateverCameBefore) {
  // Every query against a search of every triangle: the nearest distance,
  // and among equally near triangles (points over grid vertices and edges
  // are near several) the lowest index. Queries run in an order that walks
  // and in one that jumps, since a query starts from the last one's answer.
  Fixture f(test::grid(30, 20, true));
  std::uint64_t state = 11;
  auto unit = [&]() {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) / 9007199254740992.0;
  };
  std::vector<Vec3> walk, jump;
  for (int k = 0; k < 600; ++k) {
    Vec3 p(unit() * 34 - 2, unit() * 24 - 2, unit() * 4 - 2);
    if (k % 3 == 0) // over a grid vertex, or the middle of an edge
      p.head<2>() = (p.head<2>() * 2).array().round() / 2;
    jump.push_back(p);
    walk.push_back(Vec3(30.0 * k / 600, 10 + 5 * std::sin(k / 30.0), 0.5 * std::cos(k / 7.0)));
  }
  for (const auto* queries : {&walk, &jump}) {
    for (const Vec3& q : *queries) {
      const TraceMesh::Nearest n = f.tm->nearest(q);
      int best = -1;
      double best_d = 0;
      for (int t = 0; t < f.tm->num_triangles(); ++t) {
        const auto& c = f.tm->tri(t);
        const double d = (closest_on_triangle(q, f.tm->position(c[0]), f.tm->position(c[1]), f.tm->position(c[2])).point - q).norm();
        if (best < 0 || d < best_d) {
          best = t;
          best_d = d;
        }
      }
      ASSERT_EQ(n.tri, best) << "query (" << q.transpose() << ")";
      EXPECT_NEAR((n.point - q).norm(), best_d, 1e-12);
    }
  }
}

TEST(TraceMesh, LeavesTheProcessThreadCountAlone) {
  // Embree on TBB turns a device's "threads=N" into a process-wide
  // tbb::global_control: every parallel loop of an embed, bind or transfer
  // ran on one thread while its trace mesh lived.
  using tbb::global_control;
  const size_t before = global_control::active_value(global_control::max_allowed_parallelism);
  Fixture f(test::grid(10, 10, true));
  EXPECT_EQ(global_control::active_value(global_control::max_allowed_parallelism), before);
  {
    const global_control two(global_control::max_allowed_parallelism, 2);
    Fixture g(test::grid(10, 10, true));
    EXPECT_EQ(global_control::active_value(global_control::max_allowed_parallelism), 2u);
  }
}

TEST(TraceMesh, ARayLandsOnTheFirstSideFacingTheRightWay) {
  Fixture f(test::box(0.05));
  const Vec3 up(0, 0, 1), from(0.3, 0.4, 1.0);
  // Down onto the top, which faces up.
  const auto top = f.tm->ray_hit(from, -up, 10, up);
  ASSERT_TRUE(top.has_value());
  EXPECT_NEAR(top->point.z(), 0.05, 1e-15);
  EXPECT_NEAR(top->point.x(), 0.3, 1e-12);
  EXPECT_NEAR(top->point.y(), 0.4, 1e-12);
  // Asked for a side facing down, the ray passes the top and lands on the
  // bottom: never on the far side of a thin fin by mistake.
  const auto bottom = f.tm->ray_hit(from, -up, 10, -up);
  ASSERT_TRUE(bottom.has_value());
  EXPECT_NEAR(bottom->point.z(), 0.0, 1e-15);
  // Out of reach, or pointing away: nothing.
  EXPECT_FALSE(f.tm->ray_hit(from, -up, 0.5, up).has_value());
  EXPECT_FALSE(f.tm->ray_hit(from, up, 10, up).has_value());
}

TEST(SmoothNormals, AverageTheFacesAroundACornerByAngle) {
  Fixture f(test::box());
  const SmoothNormals normals(*f.tm);
  // At a corner of the cube, the normal points out along the diagonal; in
  // the middle of a face, it is the face's normal blended toward its corners'.
  for (int t = 0; t < f.tm->num_triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      std::array<double, 3> at{0, 0, 0};
      at[k] = 1;
      const Vec3 p = f.tm->position(f.tm->tri(t)[k]);
      const Vec3 expect = (p - Vec3(0.5, 0.5, 0.5)).normalized();
      EXPECT_LT((normals.at(t, at) - expect).norm(), 1e-12);
    }
}

TEST(Tracer, AFailedBackwardWalkLeavesThePathAsItWas) {
  // A strip with a hole across the middle of the profile's way: the walk
  // from either end runs into the hole's rim. Whatever the recovery does,
  // the path must still start and end at the profile's nodes.
  RawMesh g = test::grid(10, 3);
  RawMesh holed;
  holed.positions = g.positions;
  for (int f = 0; f + 1 < static_cast<int>(g.face_offsets.size()); ++f) {
    const std::span<const int> c(g.face_vertices.data() + g.face_offsets[f], 4);
    const Vec3 centre = (g.positions[c[0]] + g.positions[c[2]]) / 2;
    if (!(centre.x() > 4 && centre.x() < 6 && centre.y() > 1 && centre.y() < 2))
      holed.add_face(c);
  }
  Fixture f(holed);
  // Three samples: the one in the middle lands on the hole's rim, and the
  // walks toward it fail both ways before the segment is halved.
  const auto t = f.trace({0.5, 1.5, 0}, {9.5, 1.5, 0}, 3);
  ASSERT_GE(t.points.size(), 2u);
  EXPECT_EQ(t.points.front().node, 0);
  EXPECT_EQ(t.points.front().at.pos, Vec3(0.5, 1.5, 0));
  EXPECT_EQ(t.points.back().node, 1);
  for (size_t i = 1; i + 1 < t.points.size(); ++i)
    EXPECT_LT(t.points[i].node, 0) << i;
}
