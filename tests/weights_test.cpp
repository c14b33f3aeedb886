// Automatic weights: the two rules, and which one follows a real skin better.

#include "curvenet/deform.hpp"
#include "curvenet/io.hpp"
#include "curvenet/weights.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

#include <cstdio>

using namespace curvenet;

namespace {
/// A straight chain root -> a -> b -> tip along +x, 1 unit per bone.
std::vector<Joint> chain() {
  std::vector<Joint> j(4);
  const char* names[] = {"root", "a", "b", "tip"};
  for (int i = 0; i < 4; ++i) {
    j[i].name = names[i];
    if (i > 0)
      j[i].parent = names[i - 1];
    j[i].bind(0, 3) = i;
  }
  return j;
}
double weight_of(const std::vector<std::pair<int, double>>& w, int joint) {
  for (const auto& [j, v] : w)
    if (j == joint)
      return v;
  return 0;
}
} // namespace

TEST(Weights, SegmentRuleSplitsAlongTheBone) {
  AutoWeightOptions opt;
  opt.rule = WeightRule::Segment;
  const auto w = auto_weights(chain(), {1.5, 0.2, 0}, opt); // middle of bone a -> b
  EXPECT_NEAR(weight_of(w, 1), 0.5, 1e-12);
  EXPECT_NEAR(weight_of(w, 2), 0.5, 1e-12);
}

TEST(Weights, BlendZoneKeepsMidBoneRigidAndMeetsHalfWayAtJoints) {
  const auto joints = chain();
  EXPECT_NEAR(weight_of(auto_weights(joints, {1.5, 0.2, 0}), 1), 1.0, 1e-12); // mid-bone: its parent joint only
  const auto at_joint = auto_weights(joints, {2.0, 0.3, 0});                  // at joint b
  EXPECT_NEAR(weight_of(at_joint, 1), 0.5, 1e-12);
  EXPECT_NEAR(weight_of(at_joint, 2), 0.5, 1e-12);
  // Continuous across the joint, and monotone inside the zone.
  const double before = weight_of(auto_weights(joints, {1.9, 0, 0}), 2);
  const double after = weight_of(auto_weights(joints, {2.1, 0, 0}), 2);
  EXPECT_GT(before, 0.0);
  EXPECT_LT(before, 0.5);
  EXPECT_GT(after, 0.5);
  EXPECT_LT(after, 1.0);
  // Past the last joint, points follow it.
  EXPECT_NEAR(weight_of(auto_weights(joints, {3.0, 0.2, 0}), 3), 0.5, 1e-12);
  EXPECT_NEAR(weight_of(auto_weights(joints, {3.5, 0.1, 0}), 3), 1.0, 1e-12);
}

TEST(Weights, GivenBonesOnlyAPointFollowsThoseWhateverLiesNearer) {
  // Two chains side by side: root -> a -> b along x, and root -> c -> d
  // 0.1 above it. A point by bone c -> d, told to follow chain a -> b (a
  // ring around that limb), takes nothing from c or d.
  std::vector<Joint> j(5);
  const char* names[] = {"root", "a", "b", "c", "d"};
  const Vec3 at[] = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {1, 0.1, 0}, {2, 0.1, 0}};
  const char* parents[] = {nullptr, "root", "a", "root", "c"};
  for (int i = 0; i < 5; ++i) {
    j[i].name = names[i];
    if (parents[i])
      j[i].parent = parents[i];
    j[i].bind.block<3, 1>(0, 3) = at[i];
  }
  const Vec3 p(1.5, 0.12, 0);
  EXPECT_NEAR(weight_of(auto_weights(j, p), 3), 1.0, 1e-12); // nearest: c -> d
  const auto w = auto_weights(j, p, {}, {1, 2});             // bones root -> a, a -> b
  EXPECT_NEAR(weight_of(w, 1), 1.0, 1e-12);
  EXPECT_EQ(weight_of(w, 3) + weight_of(w, 4), 0.0);
  // No bones given: all of them.
  EXPECT_EQ(auto_weights(j, p, {}, {}), auto_weights(j, p));
}

TEST(Weights, AlwaysNormalisedAndNonNegative) {
  const auto joints = chain();
  for (const auto rule : {WeightRule::Segment, WeightRule::BlendZone})
    for (double x = -1; x <= 4; x += 0.05) {
      AutoWeightOptions opt;
      opt.rule = rule;
      double sum = 0;
      for (const auto& [j, v] : auto_weights(joints, {x, 0.4, -0.1}, opt)) {
        EXPECT_GT(v, 0.0);
        sum += v;
      }
      EXPECT_NEAR(sum, 1.0, 1e-12);
    }
  std::vector<Joint> one(1);
  one[0].name = "only";
  EXPECT_EQ(auto_weights(one, {5, 5, 5}).size(), 1u);
}

TEST(Weights, TheDefaultRuleFollowsTheHandsOwnSkinBetter) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string path = test::data("xr_tools_hand/hand_l_poses.glb");
  const SkinnedMesh skin = load_skinned_mesh(path);
  const RawMesh raw = read_raw_mesh(path);
  std::vector<std::vector<Mat4>> poses;
  for (int c = 0; c < skin.num_clips(); ++c)
    poses.push_back(skin.skinning_matrices(c, skin.clip_range(c).second));
  AutoWeightOptions segment;
  segment.rule = WeightRule::Segment;
  const SkinComparison s = compare_with_skin(skin, raw.positions, poses, segment);
  const SkinComparison b = compare_with_skin(skin, raw.positions, poses, AutoWeightOptions{});
  std::printf("hand, %d clips: mean distance from the skin: segment %.3g m, blend-zone %.3g m\n", skin.num_clips(),
              s.mean, b.mean);
  EXPECT_EQ(AutoWeightOptions{}.rule, WeightRule::BlendZone);
  EXPECT_LT(b.mean, 0.5 * s.mean);
}

TEST(Weights, GivenWeightsAreNormalisedWithoutOverflow) {
  Rig rig;
  rig.has_skeleton = true;
  rig.joints = make_tube_skeleton({1, 2});
  rig.nodes = {{"n", {0, 1, 0}}};
  rig.weights["n"] = {{rig.joints[0].name, 1e308}, {rig.joints[1].name, 1e308}};
  const Rig out = complete_weights(rig);
  EXPECT_DOUBLE_EQ(out.weights.at("n").at(rig.joints[0].name), 0.5);
  EXPECT_DOUBLE_EQ(out.weights.at("n").at(rig.joints[1].name), 0.5);
}
