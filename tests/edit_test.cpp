// The net editor's operations (edit.hpp), on the thesis's tube net: after
// every edit the rig validates, the input is unchanged, the net embeds on
// the tube with the region count Euler's formula gives, and an edit that
// should not change the deformation (a split) does not.

#include "curvenet/edit.hpp"

#include "curvenet/deform.hpp"
#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"
#include "sample/sampling.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

using namespace curvenet;

namespace {

const SurfaceMesh& tube_mesh() {
  static const SurfaceMesh m = test::tube(24, 24, 5, false);
  return m;
}

/// The invariants after every edit: the rig validates, and it embeds on the
/// closed tube with F = 2 - V + E regions.
void expect_valid_net(const Rig& rig) {
  ASSERT_NO_THROW(validate_rig(rig, "edited"));
  const Embedding e = embed(tube_mesh(), rig);
  const auto& r = e.report();
  EXPECT_TRUE(r.ok) << (r.problems.empty() ? "" : r.problems.front());
  const int V = static_cast<int>(rig.nodes.size()), E = static_cast<int>(rig.profiles.size());
  EXPECT_EQ(r.regions, 2 - V + E);
}

const Profile& profile(const Rig& rig, const std::string& id) {
  for (const auto& p : rig.profiles)
    if (p.id == id)
      return p;
  throw std::runtime_error("no profile " + id);
}

bool has_profile(const Rig& rig, const std::string& id) {
  return std::any_of(rig.profiles.begin(), rig.profiles.end(), [&](const Profile& p) { return p.id == id; });
}

Vec3 on_cylinder(double degrees, double y) {
  const double a = degrees * std::numbers::pi / 180;
  return {std::cos(a), y, std::sin(a)};
}

std::vector<Vec3> deform_with(const Rig& rig, double degrees) {
  const Binding b = bind(tube_mesh(), rig);
  Pose pose;
  JointPose j;
  j.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(degrees * std::numbers::pi / 180, Vec3::UnitZ()));
  pose["mid"] = j;
  const auto M = skinning_matrices(b.joints(), pose);
  std::vector<Vec3> out(static_cast<size_t>(b.num_input_vertices()));
  b.deform(M, out);
  return out;
}

} // namespace

TEST(Edit, TheTubeNetIsValidBeforeAnyEdit) {
  expect_valid_net(make_tube_net());
}

TEST(Edit, RemovingANodeRemovesItsProfilesAndWeights) {
  Rig rig = make_tube_net();
  rig.weights["cap_top"] = {{"tip", 1.0}};
  const Rig before = rig;
  const Rig out = remove_nodes(rig, {"cap_top"});
  EXPECT_EQ(rig.nodes.size(), before.nodes.size()); // the input is untouched
  EXPECT_EQ(out.nodes.size(), rig.nodes.size() - 1);
  EXPECT_EQ(out.profiles.size(), rig.profiles.size() - 4); // its four spokes
  EXPECT_FALSE(out.weights.count("cap_top"));
  for (const auto& p : out.profiles)
    EXPECT_TRUE(p.from != "cap_top" && p.to != "cap_top") << p.id;
  // The top cap is then one region with the last ring's band: V 13, E 24, F 13.
  expect_valid_net(out);
}

TEST(Edit, RemovingAProfileRemovesOnlyTheNodesItLeavesAlone) {
  const Rig rig = make_tube_net();
  // A spoke: both its ends keep other profiles.
  const Rig one = remove_profiles(rig, {"spoke_top_0"});
  EXPECT_EQ(one.nodes.size(), rig.nodes.size());
  expect_valid_net(one);
  // Every spoke of the top cap: its centre node is on none, and goes.
  const Rig all = remove_profiles(rig, {"spoke_top_0", "spoke_top_1", "spoke_top_2", "spoke_top_3"});
  EXPECT_EQ(all.nodes.size(), rig.nodes.size() - 1);
  EXPECT_LT(all.node_index("cap_top"), 0);
  expect_valid_net(all);
}

TEST(Edit, AnUnknownIdIsRefusedNamingItAndTheRigIsUnchanged) {
  const Rig rig = make_tube_net();
  for (const auto& call : std::vector<std::function<void()>>{
           [&] { (void)remove_nodes(rig, {"nope"}, "fox"); },
           [&] { (void)remove_profiles(rig, {"nope"}, "fox"); },
           [&] { (void)move_node(rig, "nope", Vec3::Zero(), "fox"); },
           [&] { (void)split_profile(rig, "nope", 0.5, "fox"); },
           [&] { (void)merge_nodes(rig, "ring0_0", "nope", "fox"); },
           [&] { (void)reroute_profile(rig, "nope", {}, "fox"); },
           [&] { (void)set_joint_weight(rig, {"nope"}, "mid", 0.5, "fox"); },
       }) {
    try {
      call();
      ADD_FAILURE() << "not refused";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "fox");
      EXPECT_EQ(e.element(), "nope");
    }
  }
  EXPECT_THROW((void)split_profile(rig, "side01_0", 0.0), InputError);
  EXPECT_THROW((void)split_profile(rig, "side01_0", 1.0), InputError);
  EXPECT_THROW((void)split_profile(rig, "side01_0", std::nan("")), InputError);
  EXPECT_THROW((void)merge_nodes(rig, "ring0_0", "ring0_0"), InputError);
  EXPECT_THROW((void)move_node(rig, "ring0_0", Vec3(std::nan(""), 0, 0)), InputError);
  EXPECT_THROW((void)set_joint_weight(rig, {"ring0_0"}, "nope", 0.5), InputError);
  EXPECT_THROW((void)set_joint_weight(rig, {"ring0_0"}, "mid", 1.5), InputError);
}

TEST(Edit, AMovedNodeCarriesItsCurvesEndsAndTheDisplacementFades) {
  const Rig rig = make_tube_net();
  // Slide ring 1's node 0 round the cylinder, from 30 to 45 degrees.
  const Vec3 to = on_cylinder(45, 2.1);
  const Rig out = move_node(rig, "ring1_0", to);
  EXPECT_EQ(out.nodes[out.node_index("ring1_0")].position, to);
  int touched = 0;
  for (const auto& p : out.profiles) {
    const Profile& old = profile(rig, p.id);
    if (p.from != "ring1_0" && p.to != "ring1_0") {
      EXPECT_EQ(p.curve.points, old.curve.points) << p.id; // the others are untouched
      continue;
    }
    ++touched;
    const Vec3& end = p.from == "ring1_0" ? p.curve.points.front() : p.curve.points.back();
    EXPECT_LT((end - to).norm(), 1e-12) << p.id;
    // The far end does not move; the point halfway along moves by about half.
    const Vec3& far = p.from == "ring1_0" ? p.curve.points.back() : p.curve.points.front();
    const Vec3& far_old = p.from == "ring1_0" ? old.curve.points.back() : old.curve.points.front();
    EXPECT_LT((far - far_old).norm(), 1e-12) << p.id;
    const size_t mid = p.curve.points.size() / 2;
    const double moved = (p.curve.points[mid] - old.curve.points[mid]).norm();
    const double full = (to - rig.nodes[rig.node_index("ring1_0")].position).norm();
    EXPECT_NEAR(moved, 0.5 * full, 0.1 * full) << p.id;
  }
  EXPECT_EQ(touched, 4); // two ring arcs and two sides
  expect_valid_net(out);
}

TEST(Edit, ASplitAddsANodeOnTheCurveAndKeepsItsShape) {
  const Rig rig = make_tube_net();
  const SplitResult s = split_profile(rig, "side12_2", 0.25);
  EXPECT_EQ(s.rig.nodes.size(), rig.nodes.size() + 1);
  EXPECT_EQ(s.rig.profiles.size(), rig.profiles.size() + 1);
  const Profile& head = profile(s.rig, "side12_2");
  const Profile& tail = profile(s.rig, s.profile);
  EXPECT_EQ(head.from, "ring1_2");
  EXPECT_EQ(head.to, s.node);
  EXPECT_EQ(tail.from, s.node);
  EXPECT_EQ(tail.to, "ring2_2");
  // The new node is a quarter of the way along: the side runs from y 2.1 to 3.4.
  const Vec3 at = s.rig.nodes[s.rig.node_index(s.node)].position;
  EXPECT_NEAR(at.y(), 2.1 + 0.25 * 1.3, 1e-9);
  EXPECT_NEAR(std::hypot(at.x(), at.z()), 1.0, 1e-9);
  // Both halves lie on the old curve, and together they are as long.
  const auto whole = detail::ProfileCurve(profile(rig, "side12_2").curve, rig.nodes[rig.node_index("ring1_2")].position,
                                          rig.nodes[rig.node_index("ring2_2")].position);
  const auto a = detail::ProfileCurve(head.curve, head.curve.points.front(), head.curve.points.back());
  const auto b = detail::ProfileCurve(tail.curve, tail.curve.points.front(), tail.curve.points.back());
  EXPECT_NEAR(a.length() + b.length(), whole.length(), 1e-9);
  EXPECT_NEAR(a.length() / whole.length(), 0.25, 1e-9);
  // One more node and one more profile: the same regions.
  expect_valid_net(s.rig);
}

TEST(Edit, ASplitOfAWeightedProfileInterpolatesTheWeightsSoTheDeformationStays) {
  Rig rig = make_tube_net();
  for (int k = 0; k < 4; ++k) {
    rig.weights["ring1_" + std::to_string(k)] = {{"mid", 1.0}};
    rig.weights["ring2_" + std::to_string(k)] = {{"mid", 0.2}, {"tip", 0.8}};
  }
  const SplitResult s = split_profile(rig, "side12_1", 0.5);
  const auto& w = s.rig.weights.at(s.node);
  EXPECT_NEAR(w.at("mid"), 0.6, 1e-12);
  EXPECT_NEAR(w.at("tip"), 0.4, 1e-12);
  // The binding interpolates along a profile by arc length: the split's two
  // halves give the same constraints, so the bent tube is the same shape up
  // to where the samples fall.
  const auto before = deform_with(rig, 60), after = deform_with(s.rig, 60);
  const double diag = tube_mesh().bbox_diagonal();
  double worst = 0;
  for (size_t i = 0; i < before.size(); ++i)
    worst = std::max(worst, (before[i] - after[i]).norm());
  std::printf("split: the bent tube moves by at most %.2e of the diagonal\n", worst / diag);
  EXPECT_LT(worst, 2e-3 * diag);
  // The control: other weights on the new node would bend it elsewhere.
  Rig wrong = s.rig;
  wrong.weights[s.node] = {{"root", 1.0}};
  const auto moved = deform_with(wrong, 60);
  double apart = 0;
  for (size_t i = 0; i < before.size(); ++i)
    apart = std::max(apart, (before[i] - moved[i]).norm());
  EXPECT_GT(apart, 1e-2 * diag);
}

TEST(Edit, NearestParameterFindsTheClosestPointOfTheCurve) {
  const Rig rig = make_tube_net();
  EXPECT_NEAR(nearest_parameter(rig, "side01_0", on_cylinder(30, 0.6 + 0.75 * 1.5) + Vec3(0.1, 0, 0)), 0.75, 1e-9);
  EXPECT_NEAR(nearest_parameter(rig, "side01_0", Vec3(0, -5, 0)), 0.0, 1e-12);
}

TEST(Edit, MergingTwoNodesJoinsTheirProfilesAndDropsTheOneBetween) {
  Rig rig = make_tube_net();
  rig.weights["ring2_1"] = {{"tip", 1.0}};
  // Split a side near its top end, then merge the new node back into that end.
  const SplitResult s = split_profile(rig, "side12_1", 0.9);
  const Rig out = merge_nodes(s.rig, "ring2_1", s.node);
  EXPECT_EQ(out.nodes.size(), rig.nodes.size());
  EXPECT_EQ(out.profiles.size(), rig.profiles.size());
  EXPECT_FALSE(has_profile(out, s.profile)); // the short piece between them
  const Profile& side = profile(out, "side12_1");
  EXPECT_EQ(side.to, "ring2_1");
  EXPECT_LT((side.curve.points.back() - rig.nodes[rig.node_index("ring2_1")].position).norm(), 1e-12);
  EXPECT_EQ(out.weights.at("ring2_1").at("tip"), 1.0);
  EXPECT_FALSE(out.weights.count(s.node));
  expect_valid_net(out);
  // Two neighbours on a ring: their arc goes, the ring closes through the kept one.
  const Rig ring = merge_nodes(rig, "ring0_0", "ring0_1");
  EXPECT_FALSE(has_profile(ring, "ring0_arc01"));
  EXPECT_EQ(profile(ring, "ring0_arc12").from, "ring0_0");
  EXPECT_EQ(profile(ring, "side01_1").from, "ring0_0");
  ASSERT_NO_THROW(validate_rig(ring, "merged"));
}

TEST(Edit, ARerouteReplacesTheCurveBetweenTheSameNodes) {
  const Rig rig = make_tube_net();
  const std::vector<Vec3> via{on_cylinder(40, 1.0), on_cylinder(45, 1.35), on_cylinder(40, 1.7)};
  const Rig out = reroute_profile(rig, "side01_0", via);
  const Profile& p = profile(out, "side01_0");
  ASSERT_EQ(p.curve.points.size(), 5u);
  EXPECT_EQ(p.curve.points.front(), rig.nodes[rig.node_index("ring0_0")].position);
  EXPECT_EQ(p.curve.points[2], via[1]);
  EXPECT_EQ(p.curve.points.back(), rig.nodes[rig.node_index("ring1_0")].position);
  expect_valid_net(out);
}

TEST(Edit, AJointWeightIsSetAndTheOthersShareTheRestInTheirRatio) {
  Rig rig = make_tube_net();
  rig.weights["ring1_0"] = {{"root", 0.25}, {"mid", 0.75}};
  const Rig out = set_joint_weight(rig, {"ring1_0", "ring1_1"}, "tip", 0.5);
  const auto& w = out.weights.at("ring1_0");
  EXPECT_NEAR(w.at("tip"), 0.5, 1e-12);
  EXPECT_NEAR(w.at("root"), 0.125, 1e-12);
  EXPECT_NEAR(w.at("mid"), 0.375, 1e-12);
  // A node without weights starts from its automatic ones; they sum to 1.
  double total = 0;
  for (const auto& [j, x] : out.weights.at("ring1_1"))
    total += x;
  EXPECT_NEAR(total, 1.0, 1e-12);
  EXPECT_NEAR(out.weights.at("ring1_1").at("tip"), 0.5, 1e-12);
  // Zero takes the joint off.
  const Rig off = set_joint_weight(out, {"ring1_0"}, "tip", 0.0);
  EXPECT_FALSE(off.weights.at("ring1_0").count("tip"));
  expect_valid_net(off);
}
