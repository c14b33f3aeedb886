// Transfer: one rig, authored once, on every mesh of the same shape.

#include "core/tolerances.hpp"
#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/transfer.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"
#include "trace/trace_mesh.hpp"
#include "transfer/cage_map.hpp"
#include "transfer_check.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <numbers>
#include <tuple>

using namespace curvenet;

namespace {

void expect_rows_pass(const std::vector<check::Row>& rows) {
  check::print_table(rows, stdout);
  for (const auto& r : rows) {
    EXPECT_TRUE(r.pass_mean()) << r.pair << " " << r.clip;
    EXPECT_TRUE(r.pass_max()) << r.pair << " " << r.clip;
    EXPECT_TRUE(r.pass_refined()) << r.pair << " " << r.clip << ": against the source posed on its refinement";
    EXPECT_GT(r.agreement, 0.95) << r.pair;
    EXPECT_GT(r.moved, 5.0) << r.pair << " " << r.clip << ": the pose hardly moves the mesh, so it proves nothing";
  }
}
/// Every target of the family is transferred (none refused), with `rows`
/// rows, all within the bound.
void expect_family_passes(const std::string& family, const std::vector<std::string>& clips, size_t rows) {
  std::vector<std::string> refusals;
  const auto got = check::run_family(family, CURVENET_DATA_DIR, clips, &refusals);
  EXPECT_TRUE(refusals.empty()) << refusals.front();
  EXPECT_EQ(got.size(), rows);
  expect_rows_pass(got);
}
} // namespace

TEST(Transfer, GivesTheSameRigAndReportOnAnyThreadCount) {
  // Large enough that the region agreement measures only a share of the
  // faces inside each region.
  const SurfaceMesh quads = test::tube(48, 48, 6, false), tris = test::tube(120, 110, 12, true);
  auto run = [&](int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    return transfer(make_tube_net(), quads, tris);
  };
  const TransferResult one = run(1), two = run(2);
  ASSERT_TRUE(one.report.ok);
  EXPECT_EQ(rig_to_json(one.rig), rig_to_json(two.rig));
  EXPECT_EQ(one.report.agreement, two.report.agreement);
  EXPECT_GT(one.report.agreement, 0.99);
  EXPECT_EQ(one.report.shape.mean, two.report.shape.mean);
  EXPECT_EQ(one.report.shape.max, two.report.shape.max);
  ASSERT_EQ(one.report.regions.size(), two.report.regions.size());
  for (size_t i = 0; i < one.report.regions.size(); ++i)
    EXPECT_EQ(one.report.regions[i].agree, two.report.regions[i].agree) << one.report.regions[i].key;
}

TEST(Transfer, TubeNetFromQuadsToTriangles) {
  const SurfaceMesh quads = test::tube(16, 16, 4, false), tris = test::tube(30, 24, 7, true);
  const TransferResult r = transfer(make_tube_net(), quads, tris);
  EXPECT_TRUE(r.report.ok);
  EXPECT_EQ(r.report.target.regions, 16);
  EXPECT_EQ(r.report.target.unmapped_faces, 0);
  EXPECT_EQ(r.rig.nodes.size(), 14u);
  EXPECT_EQ(r.rig.profiles.size(), 28u);
  EXPECT_EQ(r.report.regions.size(), 16u);
  EXPECT_GT(r.report.agreement, 0.99);
  for (const auto& g : r.report.regions)
    EXPECT_GT(g.agree, 0.95) << g.key;
  // The same cylinder, faceted differently: the surfaces lie close together.
  EXPECT_LT(r.report.shape.percent(r.report.shape.max), 2.0);
  EXPECT_GT(r.report.shape.max, 0.0);
  // Ids, skeleton and weights travel unchanged.
  const Rig src = make_tube_net();
  for (size_t i = 0; i < src.nodes.size(); ++i)
    EXPECT_EQ(r.rig.nodes[i].id, src.nodes[i].id);
  EXPECT_EQ(r.rig.joints.size(), src.joints.size());
}

TEST(Transfer, ATargetWoundInsideOutGetsTheSameRegions) {
  // The target's faces all wound inward, as a mirrored export leaves them:
  // every curve's left was its right, and no region agreed (a mirrored
  // horse's transfer was refused at its tail, an inside-out wolf's agreed
  // 0 %). The loader turns it outward, with a note.
  const SurfaceMesh inside_out =
      make_surface_mesh(test::reversed(make_capped_tube(TubeSpec{1.0, 4.0, 30, 24, 7, true})), "inside out");
  ASSERT_EQ(inside_out.notes.size(), 1u);
  EXPECT_NE(inside_out.notes[0].find("turned 1 closed part outward"), std::string::npos) << inside_out.notes[0];
  const TransferResult r = transfer(make_tube_net(), test::tube(16, 16, 4, false), inside_out);
  ASSERT_TRUE(r.report.ok) << (r.report.problems.empty() ? "" : r.report.problems.front());
  EXPECT_GT(r.report.agreement, 0.99);
  for (const auto& g : r.report.regions)
    EXPECT_GT(g.agree, 0.95) << g.key;
}

TEST(Transfer, APartOfTheTargetThatNoCurveTouchesIsNotedAndLeftOutOfTheComparison) {
  // An eye modelled apart, on the target and not on the source, is a region
  // without a boundary: the transfer was refused ("the region counts
  // differ"), with nothing on stderr, and the eye counted as disagreeing.
  const SurfaceMesh quads = test::tube(16, 16, 4, false), tris = test::tube(30, 24, 7, true);
  TubeSpec eye_spec;
  eye_spec.around = 8;
  eye_spec.along = 2;
  eye_spec.cap_rings = 2;
  TubeSpec limb;
  limb.around = 30;
  limb.along = 24;
  limb.cap_rings = 7;
  limb.triangulate = true;
  RawMesh raw = make_capped_tube(limb);
  test::add_part(raw, make_capped_tube(eye_spec), Vec3(3, 0, 0), 0.05); // small, beside the limb
  const SurfaceMesh with_eye = make_surface_mesh(raw, "tube with an eye");
  const TransferResult plain = transfer(make_tube_net(), quads, tris), r = transfer(make_tube_net(), quads, with_eye);
  ASSERT_TRUE(plain.report.ok);
  EXPECT_TRUE(r.report.ok) << (r.report.problems.empty() ? "" : r.report.problems.front());
  EXPECT_EQ(r.report.target.regions, plain.report.target.regions + 1);
  ASSERT_EQ(r.report.notes.size(), 1u);
  EXPECT_NE(r.report.notes[0].find("the target has 1 part that no curve touches"), std::string::npos)
      << r.report.notes[0];
  EXPECT_EQ(r.report.regions.size(), plain.report.regions.size()) << "the eye is not a region of the comparison";
  EXPECT_GT(r.report.agreement, 0.99);
  EXPECT_EQ(r.rig.nodes.size(), plain.rig.nodes.size());
  EXPECT_TRUE(plain.report.notes.empty());
  // The other way round, the source's eye is noted too.
  const TransferResult back = transfer(make_tube_net(), with_eye, tris);
  EXPECT_TRUE(back.report.ok);
  EXPECT_EQ(back.report.notes.size(), 1u);
}

TEST(Transfer, CurvesOnACoarseTargetFollowItsSurfaceAndKeepTheirAnglesAtARidge) {
  // Issue 21's decimated fox, rebuilt: a fine limb and a coarse pentagonal
  // prism of it, a node just beside one of the prism's ridges, two curves
  // leaving it 60 degrees apart by long straight stretches (a quarter of
  // the way round the limb), and an arc closing them. Placed by their own
  // points alone, the stretches ran up to 2 % of the diagonal inside the
  // prism, across its ridges; sampled as finely as its faces, each point
  // placed, they lie on it.
  TubeSpec fine_spec{0.8, 4.0, 96, 96, 8, true}, coarse_spec{0.8, 4.0, 5, 6, 2, true};
  const SurfaceMesh fine = make_surface_mesh(make_capped_tube(fine_spec), "fine limb"),
                    coarse = make_surface_mesh(make_capped_tube(coarse_spec), "coarse limb");
  const double ridge = std::atan2(coarse.positions[0].z(), coarse.positions[0].x());
  const double r = 0.8, a0 = ridge + 8 * std::numbers::pi / 180, half = std::numbers::pi / 6, travel = 1.45;
  const double da = travel * std::sin(half) / r, dy = travel * std::cos(half);
  auto on = [&](double a, double y) { return Vec3(r * std::cos(a), y, r * std::sin(a)); };
  Rig rig;
  rig.coverage = Coverage::Local;
  rig.nodes = {{"A", on(a0, 1.0)}, {"B", on(a0 + da, 1.0 + dy)}, {"C", on(a0 - da, 1.0 + dy)}};
  Profile ab{"AB", "A", "B", {}}, ac{"AC", "A", "C", {}}, bc{"BC", "B", "C", {}};
  ab.curve.points = {on(a0, 1.0), on(a0 + da, 1.0 + dy)};
  ac.curve.points = {on(a0, 1.0), on(a0 - da, 1.0 + dy)};
  for (int k = 0; k <= 24; ++k)
    bc.curve.points.push_back(on(a0 + da + (2 * std::numbers::pi - 2 * da) * k / 24, 1.0 + dy));
  rig.profiles = {ab, ac, bc};
  ASSERT_TRUE(embed(fine, rig).report().ok);
  const TransferResult t = transfer(rig, fine, coarse);
  ASSERT_TRUE(t.report.ok);
  // Every placed curve within the embedding's fidelity tolerance of the
  // prism, its chords included.
  const detail::TraceMesh tm(coarse, detail::CutMesh::from_surface(coarse));
  const double diag = coarse.bbox_diagonal();
  double worst = 0;
  for (const Profile& p : t.rig.profiles)
    for (size_t i = 0; i + 1 < p.curve.points.size(); ++i)
      for (int k = 0; k <= 8; ++k) {
        const Vec3 q = p.curve.points[i] + (p.curve.points[i + 1] - p.curve.points[i]) * (k / 8.0);
        worst = std::max(worst, tm.nearest(q).distance(q) / diag);
      }
  EXPECT_LT(worst, detail::Tolerances::fidelity_rel) << 100 * worst << "% of the diagonal";
  // At A the two stretches still part by more than half their angle on the limb.
  auto leaving = [&](const Profile& p) {
    for (const Vec3& q : p.curve.points)
      if ((q - p.curve.points.front()).norm() > 0.2)
        return Vec3((q - p.curve.points.front()).normalized());
    return Vec3(Vec3::Zero());
  };
  auto angle = [](const Vec3& u, const Vec3& v) { return std::acos(std::clamp(u.dot(v), -1.0, 1.0)); };
  const double before = angle(leaving(rig.profiles[0]), leaving(rig.profiles[1]));
  const double after = angle(leaving(t.rig.profiles[0]), leaving(t.rig.profiles[1]));
  EXPECT_GT(after, 0.5 * before) << after * 180 / std::numbers::pi << " degrees, " << before * 180 / std::numbers::pi
                                 << " on the limb";
}

TEST(Transfer, ATargetMovedInItsSceneWorksThroughItsFrame) {
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  t.translate(Vec3(5, -2, 1));
  t.rotate(Eigen::AngleAxisd(0.7, Vec3(1, 1, 0).normalized()));
  t.scale(2.5);
  const Mat4 frame = t.matrix();
  const SurfaceMesh quads = test::tube(16, 16, 4, false), moved = test::tube(24, 20, 6, true, frame.inverse());
  // The moved tube's own space reaches the world through `frame`.
  TransferOptions opt;
  opt.target_frame = frame;
  const TransferResult r = transfer(make_tube_net(), quads, moved, opt);
  EXPECT_TRUE(r.report.ok);
  EXPECT_EQ(r.report.target.regions, 16);
  EXPECT_GT(r.report.agreement, 0.99);
  // The skeleton went through the same mapping.
  const Vec3 tip = r.rig.joints[2].bind.block<3, 1>(0, 3);
  EXPECT_LT((tip - (frame.inverse() * Vec3(0, 4, 0).homogeneous()).head<3>()).norm(), 1e-9);
  // Without the frame the rig lies off the target, and the refusal names a node.
  try {
    transfer(make_tube_net(), quads, moved);
    FAIL() << "accepted a target that does not line up";
  } catch (const EmbedError& e) {
    EXPECT_NE(std::string(e.what()).find("node '"), std::string::npos) << e.what();
  }
  // Frames that carry the source a thousand times from the target, or to a
  // thousandth or a thousand times its size, are said to line nothing up
  // (at 1e300 the closest-point queries overflowed, and said only that).
  for (const double s : {1e-300, 1e-4, 1e4, 1e300})
    for (const bool shift : {false, true}) {
      if (shift && s < 1)
        continue;
      TransferOptions far;
      far.source_frame = Mat4::Identity();
      if (shift)
        far.source_frame(0, 3) = 10 * s; // the tube is about 10 across
      else
        far.source_frame.topLeftCorner<3, 3>() *= s;
      try {
        (void)transfer(make_tube_net(), quads, quads, far);
        ADD_FAILURE() << "frames at " << s << " were taken";
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("they do not line the meshes up"), std::string::npos) << e.what();
      }
    }
}

namespace {
/// A small branching skeleton: a chain up the y axis and an arm to the side.
std::vector<Joint> branching_skeleton() {
  std::vector<Joint> joints;
  for (const auto& [name, parent, at] :
       std::vector<std::tuple<std::string, std::string, Vec3>>{{"root", "", Vec3(0, 0, 0)},
                                                               {"spine", "root", Vec3(0, 2, 0)},
                                                               {"head", "spine", Vec3(0, 4, 0)},
                                                               {"arm", "spine", Vec3(1.5, 2.5, 0.2)},
                                                               {"hand", "arm", Vec3(3, 2.2, 0.5)}}) {
    Joint j{name, parent.empty() ? std::nullopt : std::optional<std::string>(parent), Mat4::Identity()};
    j.bind.block<3, 1>(0, 3) = at;
    joints.push_back(j);
  }
  return joints;
}
/// The joints with their bind matrices carried by `m`.
std::vector<Joint> carried(std::vector<Joint> joints, const Mat4& m) {
  for (Joint& j : joints)
    j.bind = m * j.bind;
  return joints;
}
/// A Blender export: Y up (a quarter turn about x), a scale of 100, moved.
Mat4 other_axes_and_units() {
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  t.translate(Vec3(30, -7, 12));
  t.rotate(Eigen::AngleAxisd(-std::numbers::pi / 2, Vec3::UnitX()));
  t.scale(100);
  return t.matrix();
}
} // namespace

TEST(SkeletonFit, RecoversTheSimilarityBetweenTwoExportsOfOneSkeleton) {
  const Mat4 m = other_axes_and_units();
  std::vector<Joint> target = carried(branching_skeleton(), m);
  std::reverse(target.begin(), target.end());                           // matched by name, not by order
  target.push_back(Joint{"ik_target", std::nullopt, Mat4::Identity()}); // only in one of them
  std::string why;
  const auto fit = fit_skeletons(branching_skeleton(), target, 500.0, &why);
  ASSERT_TRUE(fit) << why;
  EXPECT_EQ(fit->joints, 5);
  EXPECT_NEAR(fit->scale, 100, 1e-9);
  EXPECT_LT((fit->source_to_target - m).norm(), 1e-9 * m.norm());
  EXPECT_LT(fit->worst, 1e-12);
}

TEST(SkeletonFit, RefusesTooFewJointsJointsOnALineAndAnotherBindPose) {
  const Mat4 m = other_axes_and_units();
  std::string why;
  // Two joints in common: no rotation is determined.
  std::vector<Joint> two = branching_skeleton();
  two.resize(2);
  EXPECT_FALSE(fit_skeletons(two, carried(branching_skeleton(), m), 500, &why));
  EXPECT_NE(why.find("2 joints match by name"), std::string::npos) << why;
  // The chain up the y axis alone: a turn about it is not determined.
  std::vector<Joint> chain = branching_skeleton();
  chain.resize(3);
  EXPECT_FALSE(fit_skeletons(chain, carried(chain, m), 500, &why));
  EXPECT_NE(why.find("lie on one line"), std::string::npos) << why;
  // The hand raised in the target: another bind pose, which no similarity explains.
  std::vector<Joint> raised = carried(branching_skeleton(), m);
  raised[4].bind.block<3, 1>(0, 3) += Vec3(0, 0, 60); // 0.6 units before the scale of 100
  EXPECT_FALSE(fit_skeletons(branching_skeleton(), raised, 500, &why));
  EXPECT_NE(why.find("another bind pose"), std::string::npos) << why;
  // A joint that is not a number.
  std::vector<Joint> broken = branching_skeleton();
  broken[1].bind(0, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(fit_skeletons(broken, carried(branching_skeleton(), m), 500, &why));
  EXPECT_NE(why.find("not finite"), std::string::npos) << why;
}

TEST(Transfer, ATargetInOtherAxesAndUnitsLinesUpByItsSkeleton) {
  const Mat4 m = other_axes_and_units();
  const SurfaceMesh quads = test::tube(16, 16, 4, false), exported = test::tube(24, 20, 6, true, m);
  TransferOptions opt;
  opt.alignment = Alignment::Auto;
  opt.source_skeleton = branching_skeleton();
  opt.target_skeleton = carried(branching_skeleton(), m);
  const TransferResult r = transfer(make_tube_net(), quads, exported, opt);
  EXPECT_TRUE(r.report.ok);
  EXPECT_EQ(r.report.target.regions, 16);
  EXPECT_GT(r.report.agreement, 0.99);
  ASSERT_TRUE(r.report.skeleton_fit);
  EXPECT_EQ(r.report.alignment.rfind("skeletons: 5 joints matched, scale 100", 0), 0u) << r.report.alignment;
  EXPECT_NE(transfer_report_json(r.report).find("\"skeleton_fit\""), std::string::npos);
  // The rig's skeleton lands on the target's.
  const Vec3 tip = r.rig.joints[2].bind.block<3, 1>(0, 3);
  EXPECT_LT((tip - (m * Vec3(0, 4, 0).homogeneous()).head<3>()).norm(), 1e-9 * 100);
  // Frames given win under auto, and here they are wrong: the refusal names a node.
  TransferOptions framed = opt;
  framed.target_frame = Mat4::Identity();
  framed.target_frame(0, 3) = 1;
  EXPECT_THROW(transfer(make_tube_net(), quads, exported, framed), EmbedError);
  // Asked for skeletons that do not fit, it refuses, naming both meshes.
  TransferOptions off = opt;
  off.alignment = Alignment::Skeletons;
  off.target_skeleton.resize(2);
  try {
    transfer(make_tube_net(), quads, exported, off);
    FAIL() << "lined up by two joints";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot line the meshes up: 2 joints match"), std::string::npos) << e.what();
  }
  // Under auto, skeletons that do not fit leave the frames, and the report says why.
  off.alignment = Alignment::Auto;
  off.target_skeleton = carried(branching_skeleton(), Mat4::Identity());
  off.target_skeleton[4].bind(2, 3) += 1;
  const TransferResult same = transfer(make_tube_net(), quads, quads, off);
  EXPECT_FALSE(same.report.skeleton_fit);
  EXPECT_EQ(same.report.alignment.rfind("frames (not the skeletons: after the best fit", 0), 0u)
      << same.report.alignment;
  // And where the frames then fail, the refusal says why the skeletons were not used.
  off.target_skeleton = opt.target_skeleton;
  off.target_skeleton[4].bind(2, 3) += 60; // the hand raised: another bind pose
  try {
    transfer(make_tube_net(), quads, exported, off);
    FAIL() << "a target in other axes was taken by the frames";
  } catch (const EmbedError& e) {
    EXPECT_NE(std::string(e.what()).find("lined up by frames (not the skeletons: after the best fit"),
              std::string::npos)
        << e.what();
  }
  // With no skeleton at all, auto is the frames, with nothing to say.
  EXPECT_EQ(transfer(make_tube_net(), quads, quads).report.alignment, "frames");
  EXPECT_EQ(parse_alignment("skeletons", "--align"), Alignment::Skeletons);
  EXPECT_THROW(parse_alignment("bones", "--align"), InputError);
}

TEST(Transfer, GameAnimalsGoToTheirLODsExportedInOtherAxesAndUnits) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // Blender's decimations (tests/data/quaternius): half the faces, and a
  // fifth (286 to 436 triangles), Y up, the armature's scale of 100. Lined
  // up by the frames (none) they lie far off. The nets are the starter's
  // from each file's skin, middle nodes and all, as `curvenet starter`
  // makes them; the T-rex's forearm, a few faces across on its
  // decimation, takes the plane sections of the last re-placement. On its
  // fifth (364 triangles) the claws of its feet are gone, and the profiles
  // over them are placed by their ends alone; there a little more of the
  // area (98.6 %) agrees.
  for (const std::string name : {"Horse", "Wolf", "Apatosaurus", "Trex"}) {
    const std::string from = test::data("quaternius/" + name + ".glb");
    const SurfaceMesh source_mesh = load_mesh(from);
    const SkinnedMesh source = load_skinned_mesh(from);
    const Rig rig = test::skinned_starter(from);
    for (const std::string lod : {"_decimated", "_decimated_20"}) {
      SCOPED_TRACE(name + lod);
      const std::string to = std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/" + name + lod + ".glb";
      const SurfaceMesh target_mesh = load_mesh(to);
      const SkinnedMesh target = load_skinned_mesh(to);
      TransferOptions opt;
      opt.alignment = Alignment::Auto;
      opt.source_skeleton = source.joints;
      opt.target_skeleton = target.joints;
      const TransferResult r = transfer(rig, source_mesh, target_mesh, opt);
      EXPECT_TRUE(r.report.ok) << (r.report.problems.empty() ? "" : r.report.problems[0]);
      EXPECT_EQ(r.report.target.regions, r.report.source.regions);
      EXPECT_GT(r.report.agreement, name == "Trex" && lod == "_decimated_20" ? 0.98 : 0.99);
      ASSERT_TRUE(r.report.skeleton_fit) << r.report.alignment;
      EXPECT_NEAR(r.report.skeleton_fit->scale, 100, 1e-3);
      // The rig's joints land on the target skin's own.
      std::map<std::string, Vec3> at;
      for (const Joint& j : target.joints)
        at[j.name] = j.bind.block<3, 1>(0, 3);
      const double diagonal = target_mesh.bbox_diagonal();
      for (const Joint& j : r.rig.joints)
        EXPECT_LT((j.bind.block<3, 1>(0, 3) - at.at(j.name)).norm(), 1e-5 * diagonal) << j.name;
      opt.alignment = Alignment::Frames;
      EXPECT_THROW(transfer(rig, source_mesh, target_mesh, opt), Error);
    }
  }
}

namespace {

/// The shared animal `name`'s rig transferred to its decimation
/// tests/data/quaternius/`file`, lined up by the two files' skeletons.
TransferResult transfer_to_decimation(const Rig& rig, const std::string& name, const std::string& file) {
  const std::string from = test::data("quaternius/" + name + ".glb");
  const std::string to = std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/" + file;
  TransferOptions opt;
  opt.alignment = Alignment::Auto;
  opt.source_skeleton = load_skinned_mesh(from).joints;
  opt.target_skeleton = load_skinned_mesh(to).joints;
  return transfer(rig, load_mesh(from), load_mesh(to), opt);
}

/// Every region found on the target, and most of its area agreeing.
void expect_transferred(const TransferResult& r) {
  EXPECT_TRUE(r.report.ok) << (r.report.problems.empty() ? "" : r.report.problems[0]);
  EXPECT_EQ(r.report.target.regions, r.report.source.regions);
  EXPECT_GT(r.report.agreement, 0.99);
}

} // namespace

TEST(Transfer, ANodeMovedToItsClosestPointGoesBackWhereItsCurvesKeepTheirAngles) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // The wolf at a quarter and a ninth of its faces (490 and 214
  // triangles): its ear tip is a few faces round. Placed along the
  // normals, a ring's arc there strays, and goes to the target's closest
  // points with its end nodes; one of them lands past the ring's next
  // node, so the ring's nodes no longer run in order and a line into the
  // ring crosses it (490), or the neck's ring and the line to the head meet
  // (214). Such a node goes back along the normal where its curves keep
  // their angles better there, and both transfer.
  const Rig rig = test::skinned_starter(test::data("quaternius/Wolf.glb"));
  for (const std::string lod : {"_decimated_25", "_decimated_11"}) {
    SCOPED_TRACE(lod);
    try {
      expect_transferred(transfer_to_decimation(rig, "Wolf", "Wolf" + lod + ".glb"));
    } catch (const EmbedError& e) {
      ADD_FAILURE() << e.what();
    }
  }
}

TEST(Transfer, ARegionOfAThinPartIsLocatedOnItsOwnSide) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // The wolf at a ninth of its faces (214 triangles): its ear is a flat
  // blade a few faces round, thinner than the source's. A panel of the ear
  // tip, on the ear's front, lies nearer to the back of the source's ear
  // than to its front, and located by closest points alone it agreed 0 %.
  // Located on the side its faces face, every region of the transfer
  // agrees over most of its area.
  try {
    const TransferResult r = transfer_to_decimation(test::skinned_starter(test::data("quaternius/Wolf.glb")), "Wolf",
                                                    "Wolf_decimated_11.glb");
    expect_transferred(r);
    ASSERT_FALSE(r.report.regions.empty());
    for (const auto& region : r.report.regions)
      EXPECT_GT(region.agree, 0.5) << region.key;
  } catch (const EmbedError& e) {
    ADD_FAILURE() << e.what();
  }
}

TEST(Transfer, TwoCurvesThatMeetAwayFromTheirNodeOnACoarseTargetGetTheNodeAtAFacesCorner) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // The apatosaurus at a fifth of its faces (300 triangles): its tail is a
  // flat blade of long slivers, and a tail ring's node is placed a tenth of
  // an edge from the corner where the blade's edge runs. The ring's arc
  // and the line into that node both pass between the node and the corner,
  // and meet there however they are placed. Placed every other way, the
  // node goes to the corner, and the transfer succeeds.
  const SurfaceMesh target_mesh =
      load_mesh(std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/Apatosaurus_decimated_21.glb");
  try {
    const TransferResult r = transfer_to_decimation(test::skinned_starter(test::data("quaternius/Apatosaurus.glb")),
                                                    "Apatosaurus", "Apatosaurus_decimated_21.glb");
    expect_transferred(r);
    // The node is at a corner of the target.
    const Node* node = nullptr;
    for (const Node& n : r.rig.nodes)
      if (n.id == "Tail5_2")
        node = &n;
    ASSERT_NE(node, nullptr);
    double nearest = std::numeric_limits<double>::infinity();
    for (const Vec3& p : target_mesh.positions)
      nearest = std::min(nearest, (p - node->position).norm());
    EXPECT_LT(nearest, 1e-12 * target_mesh.bbox_diagonal());
  } catch (const EmbedError& e) {
    ADD_FAILURE() << e.what();
  }
}

TEST(Transfer, ACoarseTargetWhoseThinPartCannotHoldTheCurvesIsRefusedWithWhatToDo) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // The T-rex at an eighth of its faces (226 triangles): its forearm is a
  // few faces round, and the rings of the upper and lower arm cross
  // however they are placed. The refusal names the target and the curves,
  // says that placing again did not help, and what does: the target's own
  // net, which embeds there.
  const std::string from = test::data("quaternius/Trex.glb");
  const std::string to = std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/Trex_decimated_12.glb";
  try {
    (void)transfer_to_decimation(test::skinned_starter(from), "Trex", "Trex_decimated_12.glb");
    ADD_FAILURE() << "the transfer onto the 226-triangle T-rex is not refused";
  } catch (const EmbedError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("Trex_decimated_12.glb"), std::string::npos) << what;
    EXPECT_NE(what.find("FrontUpLeg.R_arc"), std::string::npos) << what;
    EXPECT_NE(what.find("the curves it names still do not fit"), std::string::npos) << what;
    EXPECT_NE(what.find("too few faces there"), std::string::npos) << what << ": a coarser target";
    EXPECT_NE(what.find("curvenet starter"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  const Rig own = test::skinned_starter(to);
  EXPECT_TRUE(embed(load_mesh(to), own).report().ok);
}

TEST(Transfer, HandAuthoredOnceAgreesWhenPosedOnEveryTessellation) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  expect_family_passes("hand", {"Grip", "Peace", "Thumb", "Sign 3", "Cup", "Hold"}, 3u * 6u);
}

TEST(Transfer, HandNetGoesFromEveryTessellationToEveryOther) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // The starter net made on each closed tessellation, transferred to each
  // of the others: coarse to fine, fine to coarse, triangles to quads and back.
  const std::string d = test::data("xr_tools_hand/");
  const auto joints = load_skinned_mesh(d + "hand_l.gltf").joints;
  const std::vector<std::string> files = {"hand_l.gltf", "Hand_low_L.gltf", "hand_l_quads.obj", "hand_low_l_quads.obj"};
  for (const auto& from : files) {
    const SurfaceMesh source = load_mesh(d + from);
    const Rig rig = make_starter(source, joints).rig;
    for (const auto& to : files) {
      if (to == from)
        continue;
      SCOPED_TRACE(from + " -> " + to);
      const TransferResult r = transfer(rig, source, load_mesh(d + to));
      EXPECT_TRUE(r.report.ok) << (r.report.problems.empty() ? "" : r.report.problems[0]);
      EXPECT_EQ(r.report.target.regions, r.report.source.regions);
      EXPECT_GT(r.report.agreement, 0.99);
    }
  }
}

TEST(Transfer, ARigThatDoesNotLieOnTheSourceIsRefusedForTheSource) {
  // The source's embedding runs beside the shape distance: its refusal
  // still reaches the caller as an EmbedError naming what failed.
  SurfaceMesh moved = test::tube(16, 16, 4, false);
  for (Vec3& p : moved.positions)
    p += Vec3(10, 0, 0);
  const SurfaceMesh tris = test::tube(30, 24, 7, true);
  try {
    transfer(make_tube_net(), moved, tris);
    FAIL() << "accepted a rig that does not lie on its source";
  } catch (const EmbedError& e) {
    EXPECT_NE(std::string(e.what()).find("node '"), std::string::npos) << e.what();
  }
}

TEST(Transfer, NailedHandIsRefusedCleanly) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string d = test::data("xr_tools_hand/");
  const SurfaceMesh source = load_mesh(d + "hand_l.gltf");
  const Rig rig = make_starter(source, load_skinned_mesh(d + "hand_l.gltf").joints).rig;
  // The nails are open shells: the hand's full net is refused before the
  // work, saying why and what to do.
  try {
    transfer(rig, source, load_mesh(d + "Hand_Nails_L.gltf"));
    FAIL() << "a full net was transferred onto an open mesh";
  } catch (const EmbedError& e) {
    EXPECT_NE(std::string(e.what()).find("Hand_Nails_L.gltf is open ("), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("curvenet starter"), std::string::npos) << e.what();
  }
}

TEST(Transfer, AFullNetIsRefusedOnAnOpenTargetSayingWhatToDo) {
  // The tube without its top cap: the thesis's full net cannot cover it.
  TubeSpec spec;
  spec.triangulate = true;
  const RawMesh closed = make_capped_tube(spec);
  const SurfaceMesh source = test::tube(16, 16, 4, false);
  try {
    transfer(make_tube_net(), source, make_surface_mesh(test::without_top_cap(closed, spec), "open_tube.obj"));
    FAIL() << "a full net was transferred onto an open mesh";
  } catch (const EmbedError& e) {
    EXPECT_NE(std::string(e.what()).find(
                  "the target open_tube.obj is open (it has a boundary) where the source tube is closed"),
              std::string::npos)
        << e.what();
  }
  // Onto the closed tube it goes.
  EXPECT_TRUE(transfer(make_tube_net(), source, make_surface_mesh(closed, "tube.obj")).report.ok);
}

TEST(Transfer, SpotQuadsToTrianglesAgreeWhenPosed) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // The bare cage lies up to 7.9 % of the diagonal off the surface. The
  // profiles placed on it sample by sample, as finely as its faces, follow
  // it (placed by their end points alone, they strayed 12 % of the diagonal
  // and the cage was refused); through its limit (--to-cage) it passes too.
  std::vector<std::string> refusals;
  const auto rows = check::run_family("spot", CURVENET_DATA_DIR, {}, &refusals);
  EXPECT_TRUE(refusals.empty()) << refusals.front();
  EXPECT_EQ(rows.size(), 4u * 3u);
  expect_rows_pass(rows);
}

TEST(Transfer, BlubLimitSurfaceToTrianglesAgreesWhenPosed) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  std::vector<std::string> refusals;
  const auto rows = check::run_family("blub", CURVENET_DATA_DIR, {}, &refusals);
  EXPECT_EQ(rows.size(), 2u * 3u); // fish_low_resolution.obj, and the cage through its limit
  expect_rows_pass(rows);
  // The bare cage (projected onto, 10 % off the surface) and fish.obj (Blub
  // in another pose) are refused, naming what could not be placed or cut
  // and how far apart the surfaces are.
  ASSERT_EQ(refusals.size(), 2u);
  EXPECT_EQ(refusals[0].rfind("fish_control_mesh.obj: ", 0), 0u) << refusals[0];
  EXPECT_EQ(refusals[1].rfind("fish.obj: ", 0), 0u) << refusals[1];
  // fish.obj's profile 'bend_1_arc2' jumps when projected along the normals;
  // it is placed again by closest points, and the refusal comes later, from
  // the cut (it had been refused at the placing).
  EXPECT_EQ(refusals[1].find("jump"), std::string::npos) << refusals[1];
  for (const auto& r : refusals) {
    std::printf("refused: %s\n", r.c_str());
    EXPECT_TRUE(r.find("profile '") != std::string::npos || r.find("profiles '") != std::string::npos ||
                r.find("node '") != std::string::npos)
        << r;
    EXPECT_NE(r.find("of the diagonal apart"), std::string::npos) << r;
  }
}

TEST(Transfer, PenguinTrianglesToItsCageRefinedAndBare) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  expect_family_passes("penguin", {}, 3u * 3u);
}

TEST(Transfer, ARigOnACageGoesThroughItsLimitSurface) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // The starter net drawn on the penguin's bare cage, transferred to the
  // triangle remesh of its limit surface: carried up to the limit first.
  const SurfaceMesh cage = load_mesh(test::data("penguin/penguin_control_mesh.obj"));
  const SurfaceMesh remesh = load_mesh(test::data("penguin/penguin.obj"));
  check::Family f;
  check::two_joint_family(remesh, f);
  const Rig rig = make_starter(cage, f.joints, f.starter).rig;
  TransferOptions opt;
  opt.source_cage_levels = 2;
  const TransferResult r = transfer(rig, cage, remesh, opt);
  EXPECT_TRUE(r.report.ok) << (r.report.problems.empty() ? "" : r.report.problems[0]);
  EXPECT_GT(r.report.agreement, 0.99);
  EXPECT_LT(r.report.shape.percent(r.report.shape.max), 1.0); // the limit, not the cage, against the remesh
  // Straight from the bare cage, for comparison.
  try {
    const TransferResult bare = transfer(rig, cage, remesh);
    std::printf("from the bare cage: %s, agreement %.4f\n", bare.report.ok ? "ok" : "not ok", bare.report.agreement);
  } catch (const EmbedError& e) {
    std::printf("from the bare cage: refused: %s\n", e.what());
    // A refusal where the placed rig does not embed names the target.
    EXPECT_EQ(std::string(e.what()).rfind(remesh.source + ": ", 0), 0u) << e.what();
  }
}

TEST(CageMap, CarriesTheLimitSurfaceOntoTheCageAndBack) {
  // A cube cage: its limit is a rounded box inside it. Every point of the
  // limit goes to a point of the cube's own faces, and back near itself.
  const SurfaceMesh cage = make_surface_mesh(test::box(), "cube");
  const detail::CageMap map(cage, 3);
  const SurfaceMesh& limit = map.limit();
  const double h = limit.mean_edge_length();
  double worst = 0;
  for (int f = 0; f < limit.num_faces(); ++f) {
    const auto c = limit.face(f);
    const Vec3 p = (limit.positions[c[0]] + limit.positions[c[1]] + limit.positions[c[2]]) / 3; // near the limit
    const Vec3 on_cage = map.to_cage(p);
    const double off_face = std::min({on_cage.cwiseAbs().minCoeff(), (on_cage - Vec3::Ones()).cwiseAbs().minCoeff()});
    EXPECT_LT(off_face, 1e-12) << on_cage.transpose();
    worst = std::max(worst, (map.to_limit(on_cage) - p).norm());
  }
  std::printf("round trip: largest move %.3g mean edge lengths\n", worst / h);
  EXPECT_LT(worst, 0.25 * h);
}
