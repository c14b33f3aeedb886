// Fidelity: the cut follows the curves the rigger drew, on any tessellation.
// Every test measures the chains against the curves itself (the dense curve,
// each point moved to its closest surface point, against the chain's
// polyline, both ways), so it does not take the report's word for it.

#include "core/plane_section.hpp"
#include "core/polyline_distance.hpp"
#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/transfer.hpp"
#include "embed/embedding_impl.hpp"
#include "helpers.hpp"
#include "sample/sampling.hpp"
#include "trace/trace_mesh.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

using namespace curvenet;
using detail::Vec3;

namespace {

Profile profile(std::string id, std::string from, std::string to, std::vector<Vec3> pts,
                Curve::Kind kind = Curve::Kind::Polyline) {
  Profile p;
  p.id = std::move(id);
  p.from = std::move(from);
  p.to = std::move(to);
  p.curve.kind = kind;
  p.curve.points = std::move(pts);
  return p;
}

/// How far each chain strays from its curve placed on the surface: the
/// symmetric Hausdorff distance between the chain's polyline and the dense
/// curve (ends on the nodes, as the embedding moves them), every point
/// moved to its closest surface point. Brute force.
std::vector<double> measured_fidelity(const SurfaceMesh& mesh, const Rig& rig, const Embedding& e) {
  const detail::CutMesh fresh = detail::CutMesh::from_surface(mesh);
  const detail::TraceMesh tm(mesh, fresh);
  const auto& impl = e.impl();
  std::vector<double> out;
  for (size_t p = 0; p < rig.profiles.size(); ++p) {
    const auto& pr = rig.profiles[p];
    const Vec3 from = impl.input.node_points[rig.node_index(pr.from)].pos;
    const Vec3 to = impl.input.node_points[rig.node_index(pr.to)].pos;
    const detail::ProfileCurve curve(pr.curve, from, to);
    std::vector<Vec3> placed;
    constexpr int n = 2000;
    for (int i = 0; i <= n; ++i)
      placed.push_back(tm.nearest(curve.at(static_cast<double>(i) / n)).point);
    std::vector<Vec3> chain;
    for (auto v : impl.result.chains[p].vertices)
      chain.push_back(impl.cut.position(v));
    out.push_back(detail::hausdorff(chain, placed));
  }
  return out;
}

/// The embedding is ok with the Euler count, and every chain stays within
/// the tolerance of its curve, by our own measure and by the report's.
void expect_faithful(const SurfaceMesh& mesh, const Rig& rig, const Embedding& e, int regions) {
  const EmbedReport& r = e.report();
  EXPECT_TRUE(r.ok) << (r.problems.empty() ? "" : r.problems[0]);
  EXPECT_EQ(r.regions, regions);
  ASSERT_TRUE(r.expected_regions.has_value());
  EXPECT_EQ(*r.expected_regions, regions);
  const double tol = 1e-3 * mesh.bbox_diagonal();
  const auto measured = measured_fidelity(mesh, rig, e);
  ASSERT_EQ(r.fidelity.size(), rig.profiles.size());
  for (size_t p = 0; p < measured.size(); ++p) {
    EXPECT_LE(measured[p], tol) << "profile '" << rig.profiles[p].id << "'";
    EXPECT_LE(r.fidelity[p].second, tol) << "profile '" << rig.profiles[p].id << "'";
    EXPECT_EQ(r.fidelity[p].first, rig.profiles[p].id);
  }
  EXPECT_LE(r.fidelity_max, r.fidelity_tolerance);
}

/// The point at angle a (radians) and height y on the faceted side of a
/// capped tube (generate/tube.hpp): on the flat face between two columns.
Vec3 on_facets(const TubeSpec& s, double a, double y) {
  const double step = 2 * std::numbers::pi / s.around;
  a = std::fmod(std::fmod(a, 2 * std::numbers::pi) + 2 * std::numbers::pi, 2 * std::numbers::pi);
  const int i = static_cast<int>(std::floor(a / step));
  const double f = a / step - i;
  const Vec3 c0(s.radius * std::cos(step * i), y, s.radius * std::sin(step * i));
  const Vec3 c1(s.radius * std::cos(step * (i + 1)), y, s.radius * std::sin(step * (i + 1)));
  // The point of the chord c0-c1 on the ray at angle a.
  const Vec3 d(std::cos(a), 0, std::sin(a));
  const Vec3 e = c1 - c0;
  const double t = (c0.x() * d.z() - c0.z() * d.x()) / (e.z() * d.x() - e.x() * d.z());
  (void)f;
  return c0 + t * e;
}

/// A cubic Bezier through p0 and p3 that leaves along t0 and arrives along t3.
std::vector<Vec3> bezier(const Vec3& p0, const Vec3& t0, const Vec3& p3, const Vec3& t3) {
  return {p0, p0 + t0, p3 - t3, p3};
}

} // namespace

TEST(Fidelity, ARingRoundAThinLimbWhoseTrianglesAreLongerThanItIsRound) {
  // A limb 0.1 thick and 3 long, one row of sliver triangles: each is ten
  // times longer than the ring is round. The ring is two Bezier arcs between
  // two nodes, so its only samples are its ends: a walk from one node to
  // the other goes the short way, and both arcs would take it. The tracer
  // sees the walk leave the curve (its midpoint lies on the far side) and
  // walks through the midpoint instead.
  TubeSpec ts;
  ts.radius = 0.05;
  ts.length = 3;
  ts.around = 5;
  ts.along = 1;
  ts.cap_rings = 2;
  ts.triangulate = true;
  const SurfaceMesh m = make_surface_mesh(make_capped_tube(ts), "thin limb");
  Rig rig;
  const double r = ts.radius, k = 4.0 / 3.0 * std::tan(std::numbers::pi / 4); // a half circle in one cubic, near enough
  for (const double y : {1.0, 2.0}) {
    const std::string ring = y < 1.5 ? "lower" : "upper";
    const Vec3 a(r, y, 0), b(-r, y, 0);
    rig.nodes.push_back({ring + "_a", on_facets(ts, 0.0, y)});
    rig.nodes.push_back({ring + "_b", on_facets(ts, std::numbers::pi, y)});
    rig.profiles.push_back(profile(ring + "_front", ring + "_a", ring + "_b",
                                   bezier(a, Vec3(0, 0, k * r), b, Vec3(0, 0, -k * r)), Curve::Kind::Bezier));
    rig.profiles.push_back(profile(ring + "_back", ring + "_b", ring + "_a",
                                   bezier(b, Vec3(0, 0, -k * r), a, Vec3(0, 0, k * r)), Curve::Kind::Bezier));
  }
  // Two lines along the limb join the rings: V = 4, E = 6, F = 2 - 4 + 6 = 4.
  for (const char* end : {"a", "b"}) {
    const double angle = end[0] == 'a' ? 0.0 : std::numbers::pi;
    std::vector<Vec3> line;
    for (int i = 0; i <= 8; ++i)
      line.push_back(on_facets(ts, angle, 1.0 + i / 8.0));
    rig.profiles.push_back(
        profile(std::string("line_") + end, std::string("lower_") + end, std::string("upper_") + end, line));
  }
  const Embedding e = embed(m, rig);
  expect_faithful(m, rig, e, 4);
  EXPECT_GT(e.report().refinements, 0);
}

namespace {
/// Two closed rings, sections of parallel tilted planes `gap` apart, on a
/// coarse tube of sliver triangles.
std::pair<SurfaceMesh, Rig> two_close_rings(double gap_in_edges) {
  TubeSpec ts;
  ts.around = 6;
  ts.along = 2;
  ts.cap_rings = 2;
  ts.triangulate = true;
  SurfaceMesh m = make_surface_mesh(make_capped_tube(ts), "coarse tube");
  const detail::SectionMesh sections(m);
  const Vec3 normal = Vec3(0.45, 1, 0.3).normalized();
  Rig rig;
  for (int k = 0; k < 2; ++k) {
    const std::string id = k == 0 ? "near" : "far";
    const auto loops =
        detail::plane_sections(sections, Vec3(0, 2, 0) + k * gap_in_edges * m.mean_edge_length() * normal, normal);
    std::vector<Vec3> loop = loops.at(0).points;
    loop.push_back(loop.front());
    rig.nodes.push_back({id, loop.front()});
    rig.profiles.push_back(profile(id, id, id, loop));
  }
  return {std::move(m), std::move(rig)};
}
} // namespace

TEST(Fidelity, TwoRingsTenTimesTheFloorApartAreBothCut) {
  // 1e-5 of the diagonal apart: the chains must stay within a quarter of
  // that of their curves near each other, so the two are traced again there.
  const auto [m0, r0] = two_close_rings(1.0);
  const double edges = 1e-5 * m0.bbox_diagonal() / m0.mean_edge_length();
  const auto [m, rig] = two_close_rings(edges);
  const Embedding e = embed(m, rig);
  expect_faithful(m, rig, e, 3);
}

TEST(Fidelity, TwoRingsAHundredthOfAnEdgeApartAreBothCut) {
  // Straight chords between their edge crossings would cross (they stray
  // five times the tolerance); the rings do not, so both are cut: three
  // regions.
  const auto [m, rig] = two_close_rings(0.01);
  const Embedding e = embed(m, rig);
  expect_faithful(m, rig, e, 3);
}

TEST(Fidelity, SixteenProfilesMeetAtAPole) {
  // Sixteen meridians of a coarse tube's cap meet at the cap's centre node
  // and end on a ring: V = 17, E = 16 + 16 = 32 (the ring's arcs), F = 17.
  TubeSpec ts;
  ts.around = 10;
  ts.along = 4;
  ts.cap_rings = 2;
  ts.triangulate = true;
  const SurfaceMesh m = make_surface_mesh(make_capped_tube(ts), "tube");
  Rig rig;
  const Vec3 pole(0, ts.length, 0);
  rig.nodes.push_back({"pole", pole});
  const int n = 16;
  const double y = 3.0;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * std::numbers::pi * (i + 0.3) / n;
    rig.nodes.push_back({"r" + std::to_string(i), on_facets(ts, a, y)});
  }
  for (int i = 0; i < n; ++i) {
    const double a = 2 * std::numbers::pi * (i + 0.3) / n;
    // On the cap: straight out from the pole (the cap is flat), then down the side.
    std::vector<Vec3> meridian;
    const Vec3 rim = on_facets(ts, a, ts.length);
    for (int q = 0; q <= 8; ++q)
      meridian.push_back(pole + (rim - pole) * q / 8);
    for (int q = 1; q <= 8; ++q)
      meridian.push_back(on_facets(ts, a, ts.length + (y - ts.length) * q / 8));
    rig.profiles.push_back(profile("m" + std::to_string(i), "pole", "r" + std::to_string(i), meridian));
    std::vector<Vec3> arc;
    const double b = 2 * std::numbers::pi * (i + 1.3) / n;
    for (int q = 0; q <= 8; ++q)
      arc.push_back(on_facets(ts, a + (b - a) * q / 8, y));
    rig.profiles.push_back(
        profile("arc" + std::to_string(i), "r" + std::to_string(i), "r" + std::to_string((i + 1) % n), arc));
  }
  const Embedding e = embed(m, rig);
  expect_faithful(m, rig, e, 17);
}

TEST(Fidelity, ProfilesCloserThanTheFloorAreRefusedAsTouchingNotCrossing) {
  TubeSpec ts;
  ts.around = 12;
  ts.along = 8;
  ts.cap_rings = 2;
  const SurfaceMesh m = make_surface_mesh(make_capped_tube(ts), "tube");
  Rig rig;
  for (int k = 0; k < 2; ++k) {
    const std::string id = k == 0 ? "one" : "two";
    std::vector<Vec3> loop;
    for (int i = 0; i <= 96; ++i) {
      const double a = 2 * std::numbers::pi * i / 96;
      loop.push_back(on_facets(ts, a, 2.0 + 0.3 * std::cos(a) + k * 1e-8));
    }
    rig.nodes.push_back({id, loop.front()});
    rig.profiles.push_back(profile(id, id, id, loop));
  }
  try {
    embed(m, rig);
    FAIL() << "two profiles 1e-8 apart were cut";
  } catch (const EmbedError& err) {
    const std::string what = err.what();
    EXPECT_NE(what.find("'one'"), std::string::npos) << what;
    EXPECT_NE(what.find("'two'"), std::string::npos) << what;
    EXPECT_NE(what.find("closer than"), std::string::npos) << what;
    EXPECT_EQ(what.find("cross"), std::string::npos) << what;
  }
}

TEST(Fidelity, RandomNetsOfDisjointRingsAreNeverRefused) {
  // Seeded nets of rings on coarse and fine meshes: parallel plane
  // sections, some a tiny fraction of an edge apart, each loop cut into
  // arcs between one to three nodes. Parallel planes never meet, so the
  // rings are disjoint by construction, at least their planes' distance
  // apart; every net must embed with the Euler count, every chain within
  // the tolerance. (Triangle meshes and flat quads, so that a section lies
  // on the very surface the embedding sees: on a quad that is not flat, a
  // curve on one of its two triangulations lies off the other.)
  std::vector<std::pair<std::string, SurfaceMesh>> meshes;
  for (const auto& [around, along, tri] :
       std::vector<std::tuple<int, int, bool>>{{6, 2, true}, {9, 3, false}, {40, 30, true}}) {
    TubeSpec ts;
    ts.around = around;
    ts.along = along;
    ts.cap_rings = 3;
    ts.triangulate = tri;
    meshes.emplace_back("tube " + std::to_string(around) + "x" + std::to_string(along),
                        make_surface_mesh(make_capped_tube(ts), "tube"));
  }
  if (test::have_data())
    for (const char* f : {"cesium_man/variants/cesium_man_e_decimated_326.obj",
                          "cesium_man/variants/cesium_man_c_decimated.obj", "xr_tools_hand/Hand_low_L.gltf"})
      meshes.emplace_back(f, load_mesh(test::data(f)));
  std::mt19937 rng(20261201);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int nets = 0;
  for (const auto& [name, mesh] : meshes) {
    const detail::SectionMesh sections(mesh);
    Eigen::Vector3d lo = mesh.positions[0], hi = lo;
    for (const auto& p : mesh.positions) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const double h = mesh.mean_edge_length();
    for (int trial = 0; trial < 70; ++trial) {
      Vec3 normal(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5);
      if (trial % 3 == 0)
        normal = Vec3(0.05 * (unit(rng) - 0.5), 1, 0.05 * (unit(rng) - 0.5)); // along a limb or the tube
      normal.normalize();
      const double span_lo = std::min({lo.dot(normal), hi.dot(normal), Vec3(lo.x(), hi.y(), lo.z()).dot(normal)});
      (void)span_lo;
      // Planes through random points of the box, some pairs a tiny gap apart.
      std::vector<double> offsets;
      const int planes = 1 + static_cast<int>(unit(rng) * 4);
      for (int k = 0; k < planes; ++k) {
        const Vec3 at =
            lo + (hi - lo).cwiseProduct(Vec3(0.15 + 0.7 * unit(rng), 0.15 + 0.7 * unit(rng), 0.15 + 0.7 * unit(rng)));
        offsets.push_back(at.dot(normal));
        if (unit(rng) < 0.4)
          offsets.push_back(at.dot(normal) + h * std::pow(10.0, -1 - 2 * unit(rng))); // 0.1 to 0.001 edges apart
      }
      Rig rig;
      int loops = 0;
      for (size_t k = 0; k < offsets.size(); ++k)
        for (const auto& s : detail::plane_sections(sections, offsets[k] * normal, normal)) {
          if (!s.closed || s.points.size() < 6)
            continue;
          const int nodes = 1 + static_cast<int>(unit(rng) * 3);
          const std::string base = "p" + std::to_string(k) + "_" + std::to_string(loops++);
          std::vector<size_t> at;
          for (int q = 0; q < nodes; ++q)
            at.push_back(s.points.size() * q / nodes);
          for (int q = 0; q < nodes; ++q) {
            rig.nodes.push_back({base + "_n" + std::to_string(q), s.points[at[q]]});
          }
          for (int q = 0; q < nodes; ++q) {
            std::vector<Vec3> pts;
            const size_t end = q + 1 < nodes ? at[q + 1] : s.points.size();
            for (size_t i = at[q]; i <= end; ++i)
              pts.push_back(s.points[i % s.points.size()]);
            rig.profiles.push_back(profile(base + "_a" + std::to_string(q), base + "_n" + std::to_string(q),
                                           base + "_n" + std::to_string((q + 1) % nodes), pts));
          }
        }
      if (rig.profiles.empty())
        continue;
      ++nets;
      SCOPED_TRACE(name + ", trial " + std::to_string(trial) + ": " + std::to_string(rig.profiles.size()) +
                   " profiles");
      try {
        const Embedding e = embed(mesh, rig);
        // Each loop splits the closed surface once: F = loops + 1.
        expect_faithful(mesh, rig, e, loops + 1);
      } catch (const EmbedError& err) {
        ADD_FAILURE() << "refused: " << err.what();
      }
    }
  }
  // 70 trials per mesh, a few of which cut nothing: 3 tubes alone, 6 meshes with the shared data.
  EXPECT_GE(nets, test::have_data() ? 300 : 150);
  std::printf("%d random nets embedded\n", nets);
}

TEST(Fidelity, StarterNetsOnCesiumManVariantsEmbedAndTransferBetweenThem) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string d = test::data("cesium_man/variants/");
  const auto joints = load_skinned_mesh(test::data("cesium_man/CesiumMan.glb")).joints;
  const std::vector<std::string> variants = {"cesium_man_a_welded.obj", "cesium_man_c_decimated.obj",
                                             "cesium_man_e_decimated_326.obj"};
  for (const auto& from : variants) {
    const SurfaceMesh source = load_mesh(d + from);
    const Rig rig = make_starter(source, joints).rig;
    const Embedding e = embed(source, rig);
    SCOPED_TRACE(from);
    EXPECT_TRUE(e.report().ok);
    EXPECT_LE(e.report().fidelity_max, e.report().fidelity_tolerance);
    for (const auto& to : {"cesium_man_b_remesh.obj", "cesium_man_d_loop.obj", "cesium_man_e_decimated_326.obj"}) {
      if (from == to)
        continue;
      SCOPED_TRACE(std::string("to ") + to);
      const TransferResult t = transfer(rig, source, load_mesh(d + to));
      EXPECT_TRUE(t.report.ok);
      EXPECT_GE(t.report.agreement, 0.995);
      EXPECT_LE(t.report.target.fidelity_max, t.report.target.fidelity_tolerance);
    }
  }
}
