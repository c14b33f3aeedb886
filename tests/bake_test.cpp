// Baking a binding to a linear-blend skin: the weights, fitted weights, LBS
// with them, the CSV, and the skinned glTF read back by our own reader.

#include "curvenet/bake.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/mesh_output.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

#include <span>
#include <tuple>
#include <tiny_gltf.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <sstream>

using namespace curvenet;

namespace {

Pose bend(double degrees) {
  Pose p;
  JointPose j;
  j.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(degrees * M_PI / 180, Eigen::Vector3d::UnitX()));
  p["mid"] = j;
  return p;
}

std::vector<Vec3> rest_of(const Binding& b) {
  std::vector<Vec3> rest(b.num_input_vertices());
  b.deform(std::vector<Mat4>(b.joints().size(), Mat4::Identity()), rest);
  return rest;
}

double max_distance(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  double d = 0;
  for (size_t i = 0; i < a.size(); ++i)
    d = std::max(d, (a[i] - b[i]).norm());
  return d;
}

std::string temp(const std::string& name) {
  return (std::filesystem::path(::testing::TempDir()) / name).string();
}

/// The scale keys (x, y, z per key, in place) of the node named `node` in
/// the first clip of a glTF model, one span per channel that keys it.
std::vector<std::span<float>> scale_keys(tinygltf::Model& model, const std::string& node) {
  std::vector<std::span<float>> out;
  const tinygltf::Animation& clip = model.animations.at(0);
  for (const auto& ch : clip.channels) {
    if (ch.target_path != "scale" || model.nodes.at(static_cast<size_t>(ch.target_node)).name != node)
      continue;
    const auto& acc = model.accessors.at(static_cast<size_t>(clip.samplers.at(static_cast<size_t>(ch.sampler)).output));
    const auto& view = model.bufferViews.at(static_cast<size_t>(acc.bufferView));
    auto* f = reinterpret_cast<float*>(model.buffers.at(0).data.data() + view.byteOffset + acc.byteOffset);
    out.emplace_back(f, 3 * acc.count);
  }
  return out;
}

} // namespace

TEST(Bake, TopKHarmonicWeightsAreSortedNormalisedAndExactForRigidPoses) {
  const SurfaceMesh m = test::tube(24, 16, 4, true);
  const Binding b = bind(m, make_tube_net());
  for (int k : {1, 2, 4, 8}) {
    const SkinWeights w = bake_weights(b, k);
    ASSERT_EQ(w.num_vertices(), b.num_input_vertices());
    ASSERT_EQ(w.joints.size(), b.joints().size());
    std::vector<std::pair<int, double>> s;
    for (int v = 0; v < w.num_vertices(); ++v) {
      double sum = 0, last = 2;
      for (int i = 0; i < k; ++i) {
        const int j = w.joint[v * k + i];
        const double x = w.weight[v * k + i];
        if (j < 0) {
          EXPECT_EQ(x, 0);
          continue;
        }
        EXPECT_GT(x, 0);
        EXPECT_LE(x, last); // largest first
        last = x;
        sum += x;
      }
      EXPECT_NEAR(sum, 1, 1e-12) << v;
      // All of a vertex's harmonic weights, when they fit in k.
      b.harmonic_weights(v, s);
      if (static_cast<int>(s.size()) <= k)
        EXPECT_EQ(w.joint[v * k + static_cast<int>(s.size()) - 1] >= 0, true);
    }
    // A rigid pose of the whole skeleton moves every vertex rigidly under LBS.
    Pose all;
    JointPose r;
    r.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
    r.translation = {0.5, -1, 2};
    all["root"] = r;
    const auto M = skinning_matrices(b.joints(), all);
    const auto rest = rest_of(b);
    const auto posed = skin_positions(w, rest, M);
    for (size_t v = 0; v < rest.size(); ++v)
      ASSERT_LT((posed[v] - (M[0] * rest[v].homogeneous()).head<3>()).norm(), 1e-9 * m.bbox_diagonal());
  }
  EXPECT_THROW(bake_weights(b, 0), InputError);
  EXPECT_THROW(bake_weights(b, 9), InputError);
}

TEST(Bake, FittedWeightsComeCloserToTheDeformationThanTheHarmonicOnes) {
  const SurfaceMesh m = test::tube(24, 20, 4, true);
  const Binding b = bind(m, make_tube_net());
  std::vector<std::vector<Mat4>> train, test;
  for (double a : {-80.0, -40.0, 20.0, 60.0, 90.0})
    train.push_back(skinning_matrices(b.joints(), bend(a)));
  for (double a : {-60.0, 45.0, 75.0})
    test.push_back(skinning_matrices(b.joints(), bend(a)));
  const auto rest = rest_of(b);
  const SkinWeights harmonic = bake_weights(b, 4), fitted = fit_weights(b, train, 4);
  double err_h = 0, err_f = 0;
  for (const auto& M : test) {
    std::vector<Vec3> full(rest.size());
    b.deform(M, full);
    err_h = std::max(err_h, max_distance(skin_positions(harmonic, rest, M), full));
    err_f = std::max(err_f, max_distance(skin_positions(fitted, rest, M), full));
  }
  EXPECT_LT(err_f, err_h) << "poses it was not fitted on";
  for (int v = 0; v < fitted.num_vertices(); ++v) {
    double sum = 0;
    for (int i = 0; i < 4; ++i) {
      EXPECT_GE(fitted.weight[v * 4 + i], 0);
      sum += fitted.weight[v * 4 + i];
    }
    EXPECT_NEAR(sum, 1, 1e-9);
  }
  // No poses: the harmonic weights.
  EXPECT_EQ(fit_weights(b, {}, 4).weight, harmonic.weight);
  std::vector<std::vector<Mat4>> short_pose{std::vector<Mat4>(1, Mat4::Identity())};
  EXPECT_THROW(fit_weights(b, short_pose, 4), InputError);
}

TEST(Bake, TheCsvHasOneRowPerVertexWithJointNames) {
  const SurfaceMesh m = test::tube(12, 8, 3, true);
  const Binding b = bind(m, make_tube_net());
  const SkinWeights w = bake_weights(b, 2);
  std::istringstream in(weights_csv(w));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "vertex,joint_0,weight_0,joint_1,weight_1");
  int rows = 0;
  while (std::getline(in, line)) {
    std::stringstream cells(line);
    std::string vertex, j0, w0;
    std::getline(cells, vertex, ',');
    std::getline(cells, j0, ',');
    std::getline(cells, w0, ',');
    EXPECT_EQ(std::stoi(vertex), rows);
    EXPECT_EQ(j0, w.joints[w.joint[rows * 2]]);
    EXPECT_EQ(std::stod(w0), w.weight[rows * 2]); // 17 digits read back exactly
    ++rows;
  }
  EXPECT_EQ(rows, w.num_vertices());
}

TEST(Bake, TheGlbReadsBackWithTheSkeletonWeightsAndClipsItWasGiven) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string mesh_file = test::data("xr_tools_hand/hand_l.gltf");
  const SurfaceMesh m = load_mesh(mesh_file);
  const Rig rig = read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json"));
  const Binding b = bind(m, rig);
  const SkinnedMesh clips = load_skinned_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  GltfBakeOptions opt;
  opt.clips = {"Grip", "Cup"};
  const SkinWeights w = bake_weights(b, 4);
  const std::string path = temp("hand_baked.glb");
  write_file_atomic(path, skinned_glb(mesh_file, b.joints(), w, &clips, opt));
  const SkinnedMesh back = load_skinned_mesh(path);
  // The skeleton: same joints, same parents, same rest transforms.
  ASSERT_EQ(back.joints.size(), b.joints().size());
  for (size_t j = 0; j < back.joints.size(); ++j) {
    EXPECT_EQ(back.joints[j].name, b.joints()[j].name);
    EXPECT_EQ(back.joints[j].parent, b.joints()[j].parent);
    EXPECT_LT((back.joints[j].bind - b.joints()[j].bind).cwiseAbs().maxCoeff(), 1e-5) << back.joints[j].name;
  }
  // The weights, per vertex, in the file's own vertex order (a glTF source has no splits).
  const InputTopology topo = read_input_topology(mesh_file);
  ASSERT_EQ(back.vertex_weight.size(), topo.faces.positions.size());
  for (size_t v = 0; v < back.vertex_weight.size(); ++v)
    for (int i = 0; i < 4; ++i) {
      const int j = w.joint[v * 4 + i];
      EXPECT_EQ(back.vertex_joint[v][i], j) << v;
      EXPECT_NEAR(back.vertex_weight[v][i], j >= 0 ? w.weight[v * 4 + i] : 0.0, 2e-7) << v;
    }
  // The clips, by name; posed by the file's own skin they match our LBS of
  // the same weights with the source clip's pose, at every key.
  ASSERT_EQ(back.clip_names, (std::vector<std::string>{"Cup", "Grip"}));
  const int grip = back.find_clip("Grip"), src_grip = clips.find_clip("Grip");
  const auto [t0, t1] = back.clip_range(grip);
  for (double t : {t0, 0.5 * (t0 + t1), t1}) {
    const auto key = std::round((t - t0) * opt.fps) / opt.fps + t0; // a key of the baked clip
    const auto ours = skin_positions(w, topo.faces.positions, clip_skinning_matrices(b.joints(), clips, src_grip, key));
    const auto theirs = skin_positions(back, topo.faces.positions, back.skinning_matrices(grip, key));
    EXPECT_LT(max_distance(ours, theirs), 1e-5 * m.bbox_diagonal()) << "t = " << key;
  }
  // Wrong sizes are refused.
  SkinWeights fewer = w;
  fewer.joint.resize(fewer.joint.size() - 4);
  fewer.weight.resize(fewer.weight.size() - 4);
  EXPECT_THROW(skinned_glb(mesh_file, b.joints(), fewer), InputError);
  opt.clips = {"NoSuchClip"};
  EXPECT_THROW(skinned_glb(mesh_file, b.joints(), w, &clips, opt), InputError);
}

TEST(Bake, AGlbOfManyMaterialsReadsBackWithTheSourcesVerticesOnce) {
  // The T-rex has five primitives (materials); the baked file writes them
  // over one vertex buffer, and reading it back gives each vertex once, in
  // the source's order, so the baked file poses like the source.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string source = test::data("quaternius/Trex.glb");
  const SurfaceMesh m = load_mesh(source);
  const Binding b = bind(m, test::skinned_starter(source));
  const SkinWeights w = bake_weights(b, 4);
  const std::string path = temp("trex_baked.glb");
  write_file_atomic(path, skinned_glb(source, b.joints(), w));
  const SurfaceMesh back = load_mesh(path);
  const InputTopology topo = read_input_topology(source), back_topo = read_input_topology(path);
  ASSERT_GT(topo.faces.face_offsets.size(), 2u);
  EXPECT_EQ(back.input_to_welded.size(), m.input_to_welded.size());
  EXPECT_EQ(back.num_vertices(), m.num_vertices());
  EXPECT_EQ(back.num_faces(), m.num_faces());
  ASSERT_EQ(back_topo.faces.positions.size(), topo.faces.positions.size());
  double apart = 0;
  for (size_t v = 0; v < topo.faces.positions.size(); ++v)
    apart = std::max(apart, (back_topo.faces.positions[v] - topo.faces.positions[v]).norm());
  EXPECT_LT(apart, 1e-6 * m.bbox_diagonal()) << "the source's vertex order";
  EXPECT_EQ(load_skinned_mesh(path).vertex_joint.size(), topo.faces.positions.size());
}

TEST(Bake, AGlbRestsWhereItsSourceShowsTheSkinAndItsRootKeysHoldNoArmatureScale) {
  // Blender's exports put the skeleton under an armature node scaled by 100
  // and turned to Y-up. The horse's inverse bind matrices leave that node
  // out, so its skin shows at 100 times its vertices' size; a Blender
  // re-export of it (Horse_decimated.glb) puts it in them, so its skin shows
  // at its vertices' size. Either way the bake rests where the source shows
  // its skin, under a node that is the source's armature, and the walk's
  // root keys are the clip's own, with no scale of 100 in them. Each animal
  // has five roots: its body, and four IK roots that hold its feet. The
  // wolf's rest a third of a degree off its body's (the horse's agree to a
  // thousandth), and its bake had no armature and rested at a hundredth of
  // its size, on its back.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  for (const std::string& mesh_file :
       {test::data("quaternius/Horse.glb"), std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/Horse_decimated.glb",
        test::data("quaternius/Wolf.glb")}) {
    const SkinnedMesh source = load_skinned_mesh(mesh_file);
    SkinWeights w; // the file's own skin
    for (const Joint& j : source.joints)
      w.joints.push_back(j.name);
    for (size_t v = 0; v < source.vertex_joint.size(); ++v)
      for (int k = 0; k < 4; ++k) {
        w.joint.push_back(source.vertex_joint[v][static_cast<size_t>(k)]);
        w.weight.push_back(source.vertex_joint[v][static_cast<size_t>(k)] >= 0 ? source.vertex_weight[v][static_cast<size_t>(k)] : 0);
      }
    const size_t root = 0; // parents first: the first joint is a root
    ASSERT_FALSE(source.joints[root].parent.has_value());
    const Mat4 armature = source.armature();
    const double volume_scale = armature.topLeftCorner<3, 3>().determinant();
    EXPECT_NEAR(volume_scale, 1e6, 1e2) << mesh_file << ": scaled by 100";
    EXPECT_EQ(std::count_if(source.joints.begin(), source.joints.end(), [](const Joint& j) { return !j.parent; }), 5);
    GltfBakeOptions opt;
    opt.clips = {"Walk"};
    for (const SkinnedMesh* clips : {static_cast<const SkinnedMesh*>(nullptr), &source}) {
      const std::string path = temp("horse_placed.glb");
      write_file_atomic(path, skinned_glb(mesh_file, source.joints, w, clips, opt));
      const SkinnedMesh back = load_skinned_mesh(path);
      const double size = 100 * source.joints[root].bind.block<3, 1>(0, 3).norm() + 1;
      EXPECT_LT((back.armature() - armature).cwiseAbs().maxCoeff(), 1e-5 * armature.cwiseAbs().maxCoeff()) << mesh_file;
      for (size_t r = 0; r < source.joints.size(); ++r)
        if (!source.joints[r].parent)
          EXPECT_LT((back.skinning_matrices(-1, 0)[r] - source.skinning_matrices(-1, 0)[r]).cwiseAbs().maxCoeff(),
                    1e-5 * size)
              << mesh_file << ": root " << source.joints[r].name << " rests where the source's skin puts it";
      if (!clips)
        continue;
      const int walk = back.find_clip("Walk"), theirs = source.find_clip("Walk");
      ASSERT_GE(walk, 0);
      for (const double t : {0.0, 0.4}) {
        const Mat4 ours = back.joint_world(walk, t)[root] * back.inverse_bind[root];
        const Mat4 want = source.joint_world(theirs, t)[root] * source.inverse_bind[root];
        EXPECT_LT((ours - want).cwiseAbs().maxCoeff(), 1e-4 * size) << mesh_file << " at " << t;
      }
      tinygltf::Model model;
      tinygltf::TinyGLTF io;
      std::string err, warn;
      ASSERT_TRUE(io.LoadBinaryFromFile(&model, &err, &warn, path)) << err;
      // No skeleton root below the armature: Blender's importer takes the
      // rest from that node down, and a bake of the re-export rested turned
      // by the armature's quarter turn.
      ASSERT_EQ(model.skins.size(), 1u);
      EXPECT_EQ(model.skins[0].skeleton, -1) << mesh_file;
      const auto keys = scale_keys(model, source.joints[root].name);
      ASSERT_EQ(keys.size(), 1u);
      EXPECT_FALSE(keys[0].empty());
      for (const float x : keys[0])
        EXPECT_NEAR(x, 1.0, 1e-3) << mesh_file << ": the armature's scale stays in its node";
    }
    // Not placed, as before, where it would not be one placing the clips
    // keep: with --up z (which turns the source itself), and where a root of
    // the rig is not a root of the source (its keys would not carry it).
    std::vector<Joint> renamed = source.joints;
    for (Joint& j : renamed)
      if (j.parent && *j.parent == renamed[root].name)
        j.parent = "elsewhere";
    renamed[root].name = "elsewhere";
    SkinWeights w2 = w;
    w2.joints[root] = "elsewhere";
    GltfBakeOptions up_z;
    up_z.up = GltfBakeOptions::Up::Z;
    for (const auto& [joints, weights, o] : {std::tuple{source.joints, w, up_z}, std::tuple{renamed, w2, opt}}) {
      const std::string path = temp("horse_not_placed.glb");
      write_file_atomic(path, skinned_glb(mesh_file, joints, weights, nullptr, o));
      const SkinnedMesh back = load_skinned_mesh(path);
      EXPECT_TRUE(back.armature().isIdentity(1e-12)) << mesh_file;
      EXPECT_TRUE(back.skinning_matrices(-1, 0)[root].isIdentity(1e-5)) << mesh_file;
    }
  }
}

TEST(Bake, AnObjKeepsItsVertexOrderAndSplitsOnlyWhereItsCornersDiffer) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string mesh_file = test::data("xr_tools_hand/hand_l_quads.obj");
  const SurfaceMesh m = load_mesh(mesh_file);
  const Binding b = bind(m, read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json")));
  const SkinWeights w = bake_weights(b, 4);
  for (auto up : {GltfBakeOptions::Up::Y, GltfBakeOptions::Up::Z}) {
    GltfBakeOptions opt;
    opt.up = up;
    const std::string path = temp("quads.glb");
    write_file_atomic(path, skinned_glb(mesh_file, b.joints(), w, nullptr, opt));
    const RawMesh raw = read_raw_mesh(path);
    const InputTopology topo = read_input_topology(mesh_file);
    ASSERT_GE(raw.positions.size(), topo.faces.positions.size());
    for (size_t v = 0; v < topo.faces.positions.size(); ++v) {
      const Vec3 p = topo.faces.positions[v];
      const Vec3 want = up == GltfBakeOptions::Up::Y ? p : Vec3(p.x(), p.z(), -p.y());
      ASSERT_LT((raw.positions[v] - want).norm(), 1e-6 * m.bbox_diagonal()) << v;
    }
    // A polygon of n corners becomes n - 2 triangles.
    int triangles = 0;
    for (size_t f = 0; f + 1 < topo.faces.face_offsets.size(); ++f)
      triangles += topo.faces.face_offsets[f + 1] - topo.faces.face_offsets[f] - 2;
    EXPECT_EQ(static_cast<int>(raw.face_offsets.size()) - 1, triangles);
  }
}

TEST(Bake, TrainingPosesOfAThousandsOfJointsSkeletonAreRefusedBeforeTheyFillTheMemory) {
  // Ten poses per joint, each a matrix per joint: 2,000 joints came to 5 GB
  // and std::bad_alloc on a machine with less. Past the memory budget (half
  // the machine's, at least 4 GB; 20,000 joints would take 512 GB) it is
  // refused up front, in one line, saying what to do.
  std::vector<Joint> chain(20000);
  for (size_t j = 0; j < chain.size(); ++j) {
    chain[j].name = "j" + std::to_string(j);
    if (j > 0)
      chain[j].parent = chain[j - 1].name;
    chain[j].bind = Mat4::Identity();
    chain[j].bind(1, 3) = static_cast<double>(j);
  }
  try {
    (void)training_poses(chain);
    ADD_FAILURE() << "200,048 poses of 20,000 joints were made";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--weights harmonic"), std::string::npos) << e.what();
  }
  chain.resize(200); // 2,048 poses of 200 joints: 52 MB
  EXPECT_EQ(training_poses(chain).size(), 2048u);
}

TEST(Bake, TrainingPosesBendAndTwistEachJointAboutItsRestPositionThenAllAtOnce) {
  const std::vector<Joint> joints = make_tube_net().joints; // root, mid, tip along +y
  TrainingPoses opt;
  const auto poses = training_poses(joints, opt);
  const size_t per_joint = 2 * 2 * opt.bends.size() + 2;
  ASSERT_EQ(poses.size(), joints.size() * per_joint + static_cast<size_t>(opt.random_poses));
  for (const auto& M : poses) {
    ASSERT_EQ(M.size(), joints.size());
    for (const Mat4& m : M) {
      const Eigen::Matrix3d R = m.block<3, 3>(0, 0);
      EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-12); // rigid
      EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
      EXPECT_EQ(m.row(3), Eigen::RowVector4d(0, 0, 0, 1));
    }
  }
  // The mid joint alone: the root stays, the mid joint's rest position stays
  // put, and the tip joint moves with it, rigidly.
  const auto& bent = poses[per_joint]; // the mid joint's first bend
  EXPECT_TRUE(bent[0].isIdentity(0));
  const Vec3 mid = joints[1].bind.block<3, 1>(0, 3), tip = joints[2].bind.block<3, 1>(0, 3);
  EXPECT_LT((bent[1] * mid.homogeneous() - mid.homogeneous()).norm(), 1e-12);
  EXPECT_TRUE(bent[2].isApprox(bent[1], 1e-12));
  const double angle = std::acos(std::clamp(((bent[1] * tip.homogeneous()).head<3>() - mid).normalized().dot(
                                                (tip - mid).normalized()),
                                            -1.0, 1.0));
  EXPECT_NEAR(angle * 180 / std::numbers::pi, opt.bends[0], 1e-9); // a bend across the bone
  // The same every run.
  EXPECT_TRUE(training_poses(joints, opt).back().back().isApprox(poses.back().back(), 0));
  Joint bad = joints[0];
  bad.bind(0, 0) = std::nan("");
  EXPECT_THROW(training_poses({bad}), InputError);
  TrainingPoses odd;
  odd.bends = {10, std::nan("")};
  EXPECT_THROW(training_poses(joints, odd), InputError);
  odd = {};
  odd.random_twist = INFINITY;
  EXPECT_THROW(training_poses(joints, odd), InputError);
  odd = {};
  odd.random_poses = -1;
  EXPECT_THROW(training_poses(joints, odd), InputError);
}

namespace {

/// How far two skins play the hand's 35 clips from the rig (each clip's
/// first key; per vertex, over the diagonal): mean and largest of each.
struct ClipGaps {
  double mean_h = 0, mean_f = 0, max_h = 0, max_f = 0;
};
ClipGaps clip_gaps(const Binding& b, const SurfaceMesh& m, const SkinWeights& harmonic, const SkinWeights& fitted) {
  const SkinnedMesh clips = load_skinned_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  const auto rest = rest_of(b);
  const double diag = m.bbox_diagonal();
  ClipGaps g;
  std::vector<Vec3> rig(rest.size());
  for (int c = 0; c < clips.num_clips(); ++c) {
    const auto M = clip_skinning_matrices(b.joints(), clips, c, clips.clip_range(c).first);
    b.deform(M, rig);
    const auto h = skin_positions(harmonic, rest, M), f = skin_positions(fitted, rest, M);
    for (size_t v = 0; v < rest.size(); ++v) {
      const double dh = (h[v] - rig[v]).norm() / diag, df = (f[v] - rig[v]).norm() / diag;
      g.mean_h += dh;
      g.mean_f += df;
      g.max_h = std::max(g.max_h, dh);
      g.max_f = std::max(g.max_f, df);
    }
  }
  const double n = static_cast<double>(rest.size()) * clips.num_clips();
  g.mean_h /= n;
  g.mean_f /= n;
  std::printf("held-out clips, %% of the diagonal: harmonic mean %.3f max %.2f; fitted mean %.3f max %.2f\n",
              100 * g.mean_h, 100 * g.max_h, 100 * g.mean_f, 100 * g.max_f);
  return g;
}

} // namespace

TEST(Bake, WeightsFittedOverTheSkeletonsOwnPosesPlayClipsTheyNeverSawCloser) {
  // The harmonic mode: the rig's deformation is a blend of the joints' matrices
  // with per-vertex detail, which a fitted linear skin can follow.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SurfaceMesh m = load_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  BindOptions opt;
  opt.method = DeformMethod::Harmonic;
  const Binding b = bind(m, read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json")), opt);
  const ClipGaps g = clip_gaps(b, m, bake_weights(b, 4), fit_weights(b, training_poses(b.joints()), 4));
  EXPECT_LT(g.mean_f, 0.7 * g.mean_h);
  EXPECT_LT(g.max_f, 0.8 * g.max_h);
}

TEST(Bake, FittingADualQuaternionRigOverTheSkeletonsPosesCostsNothingOnClipsItNeverSaw) {
  // The default mode blends the joints as dual quaternions, which a linear
  // skin follows to first order only: fitted over poses that bend each joint
  // by 90 degrees, the weights bent towards a compromise and played the
  // hand's clips twice as far from the rig at the worst vertex (5.1 % against
  // 2.3 % of the diagonal). Over moderate poses they play them as the
  // harmonic weights do.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SurfaceMesh m = load_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  const SkinnedMesh skin = load_skinned_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  StarterOptions so;
  so.deforming = weighted_joints(skin);
  so.skin = &skin;
  const Binding b = bind(m, make_starter(m, skin.joints, so).rig);
  const ClipGaps g = clip_gaps(b, m, bake_weights(b, 4), fit_weights(b, training_poses(b.joints()), 4));
  EXPECT_LT(g.mean_f, 1.1 * g.mean_h);
  EXPECT_LT(g.max_f, 1.1 * g.max_h);
}

TEST(Bake, ARigThatIsItselfALinearSkinIsFittedBackToItsOwnWeights) {
  // The fit's deformation is a linear skin with known weights (two or three
  // of each vertex's harmonic joints, unevenly): over the skeleton's training
  // poses the fit finds those weights again, to the pull's size.
  const SurfaceMesh m = test::tube(24, 16, 4, true);
  const Binding b = bind(m, make_tube_net());
  const int n = b.num_input_vertices();
  std::vector<std::vector<std::pair<int, double>>> truth(n);
  for (int v = 0; v < n; ++v) {
    b.harmonic_weights(v, truth[v]);
    std::sort(truth[v].begin(), truth[v].end(), [](const auto& a, const auto& c) { return a.second > c.second; });
    truth[v].resize(std::min<size_t>(truth[v].size(), 2 + v % 2));
    double sum = 0;
    for (size_t i = 0; i < truth[v].size(); ++i)
      sum += truth[v][i].second *= 1 + 0.5 * static_cast<double>(i); // not the harmonic proportions
    for (auto& [j, x] : truth[v])
      x /= sum;
  }
  const auto rest = rest_of(b);
  auto skin = [&](std::span<const Mat4> M, std::span<Vec3> out) {
    const size_t nj = b.joints().size();
    for (size_t f = 0; f * nj < M.size(); ++f)
      for (int v = 0; v < n; ++v) {
        Eigen::Vector4d x = Eigen::Vector4d::Zero();
        for (const auto& [j, w] : truth[v])
          x += w * (M[f * nj + j] * rest[v].homogeneous());
        out[f * n + v] = x.head<3>();
      }
  };
  const auto poses = training_poses(b.joints());
  const SkinWeights fitted = fit_weights(b, poses, 4, skin, nullptr);
  const double diag = m.bbox_diagonal();
  int told_apart = 0;
  for (int v = 0; v < n; ++v) {
    std::map<int, double> got;
    for (int i = 0; i < 4; ++i)
      if (fitted.joint[v * 4 + i] >= 0)
        got[fitted.joint[v * 4 + i]] = fitted.weight[v * 4 + i];
    // Over the poses, the fitted skin puts the vertex where its own skin does.
    double apart = std::numeric_limits<double>::infinity(), gap = 0;
    for (const auto& M : poses) {
      Eigen::Vector4d want = Eigen::Vector4d::Zero(), have = Eigen::Vector4d::Zero();
      for (const auto& [j, w] : truth[v])
        want += w * (M[j] * rest[v].homogeneous());
      for (const auto& [j, w] : got)
        have += w * (M[j] * rest[v].homogeneous());
      gap = std::max(gap, (want - have).norm());
    }
    EXPECT_LT(gap, 1e-4 * diag) << "vertex " << v;
    // Where the poses move its joints apart at the vertex, with its own weights
    // (a vertex at a joint's centre is moved alike by the joint and its parent).
    for (size_t a = 0; a < truth[v].size(); ++a)
      for (size_t c = a + 1; c < truth[v].size(); ++c) {
        double d = 0;
        for (const auto& M : poses)
          d = std::max(d, ((M[truth[v][a].first] - M[truth[v][c].first]) * rest[v].homogeneous()).norm());
        apart = std::min(apart, d);
      }
    if (apart < 1e-2 * diag)
      continue;
    ++told_apart;
    for (const auto& [j, w] : truth[v]) {
      EXPECT_NEAR(got[j], w, 1e-4) << "vertex " << v << " joint " << j;
      got.erase(j);
    }
    for (const auto& [j, w] : got)
      EXPECT_LT(w, 1e-4) << "vertex " << v << " joint " << j << " is not in its skin";
  }
  EXPECT_GT(told_apart, n / 2);
}

TEST(Bake, WhereMoreJointsMoveAVertexThanItMayKeepTheFitIsNoWorseThanTheHarmonicTopK) {
  // With more joints at a vertex than k, the fit is redone on the k largest
  // of its own weights and on the k largest harmonic weights, and keeps the
  // one with the smaller objective (the residual over the poses plus the
  // pull towards the harmonic weights). So at every vertex that objective is
  // no more than the harmonic top k's own, renormalised: a refit that
  // dropped the harmonic subset, or kept the worse of the two, fails here.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SurfaceMesh m = load_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  const Binding b = bind(m, read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json")));
  const auto poses = training_poses(b.joints());
  const int k = 2; // most of the hand's vertices have more
  const SkinWeights fitted = fit_weights(b, poses, k), top = bake_weights(b, k);
  const auto rest = rest_of(b);
  const int n = b.num_input_vertices();
  std::vector<Vec3> target(poses.size() * static_cast<size_t>(n));
  std::vector<Mat4> all;
  for (const auto& p : poses)
    all.insert(all.end(), p.begin(), p.end());
  b.deform_frames(all, target);
  double scale = 0;
  for (const Vec3& x : rest)
    scale = std::max(scale, x.norm());
  const double pull = 1e-3 * scale; // as fit_weights pulls
  auto objective = [&](int v, const SkinWeights& w) {
    std::vector<std::pair<int, double>> s;
    b.harmonic_weights(v, s);
    std::map<int, double> given(s.begin(), s.end()), mine;
    for (int i = 0; i < w.influences; ++i)
      if (w.joint[static_cast<size_t>(v * w.influences + i)] >= 0)
        mine[w.joint[static_cast<size_t>(v * w.influences + i)]] = w.weight[static_cast<size_t>(v * w.influences + i)];
    double e = 0;
    for (size_t p = 0; p < poses.size(); ++p) {
      Eigen::Vector4d x = Eigen::Vector4d::Zero();
      for (const auto& [j, a] : mine)
        x += a * (poses[p][static_cast<size_t>(j)] * rest[static_cast<size_t>(v)].homogeneous());
      e += (x.head<3>() - target[p * static_cast<size_t>(n) + static_cast<size_t>(v)]).squaredNorm();
    }
    for (const auto& [j, a] : given) {
      const auto it = mine.find(j);
      e += pull * pull * std::pow((it == mine.end() ? 0.0 : it->second) - a, 2);
    }
    return e;
  };
  int refitted = 0, better = 0;
  for (int v = 0; v < n; ++v) {
    std::vector<std::pair<int, double>> s;
    b.harmonic_weights(v, s);
    if (static_cast<int>(s.size()) <= k)
      continue;
    ++refitted;
    const double mine = objective(v, fitted), theirs = objective(v, top);
    EXPECT_LE(mine, theirs * (1 + 1e-9) + 1e-24) << "vertex " << v;
    better += mine < 0.99 * theirs;
  }
  EXPECT_GT(refitted, n / 4);
  EXPECT_GT(better, refitted / 2) << "the fit moves most of them";
}

TEST(Bake, AHelperJointIsTheDualQuaternionMeanOfItsTwoJoints) {
  const Vec3 centre(0.3, -1, 2);
  auto turn = [&](double radians, const Vec3& axis) {
    Eigen::Affine3d a = Eigen::Translation3d(centre) * Eigen::AngleAxisd(radians, axis.normalized()) *
                        Eigen::Translation3d(-centre);
    return Mat4(a.matrix());
  };
  const Mat4 I = Mat4::Identity();
  EXPECT_LT((helper_matrix(I, I) - I).cwiseAbs().maxCoeff(), 1e-15);
  // Half way round a bend about a point: half the turn about that point.
  const Vec3 axis(1, 2, -0.5);
  for (const double theta : {0.3, 1.5, 2.4}) {
    const Mat4 h = helper_matrix(turn(theta, axis), I);
    EXPECT_LT((h - turn(theta / 2, axis)).cwiseAbs().maxCoeff(), 1e-12) << theta;
    EXPECT_LT((helper_matrix(I, turn(theta, axis)) - h).cwiseAbs().maxCoeff(), 1e-12) << "either order";
    // Between two turns about the same axis: the mean turn.
    EXPECT_LT((helper_matrix(turn(theta, axis), turn(-0.4, axis)) - turn((theta - 0.4) / 2, axis)).cwiseAbs().maxCoeff(),
              1e-12);
    // Rigid: a rotation and a translation.
    const Eigen::Matrix3d R = h.topLeftCorner<3, 3>();
    EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_NEAR(R.determinant(), 1, 1e-12);
  }
  // Half a translation; and a rigid motion of both carries the helper along.
  Mat4 T = I;
  T.block<3, 1>(0, 3) = Vec3(2, -4, 6);
  EXPECT_LT((helper_matrix(T, I).block<3, 1>(0, 3) - Vec3(1, -2, 3)).norm(), 1e-12);
  const Mat4 N = turn(0.9, Vec3(0, 1, 1)) * T;
  const Mat4 a = turn(1.1, Vec3(1, 0, 0)), b = turn(-0.2, Vec3(0, 0, 1));
  EXPECT_LT((helper_matrix(N * a, N * b) - N * helper_matrix(a, b)).cwiseAbs().maxCoeff(), 1e-12);
  // with_helpers appends one matrix per helper, after the rig's.
  SkinWeights w;
  w.joints = {"a", "b", "a~b"};
  w.helpers = {{0, 1}};
  const std::vector<Mat4> rig{a, b};
  const auto all = with_helpers(w, rig);
  ASSERT_EQ(all.size(), 3u);
  EXPECT_EQ(all[2], helper_matrix(a, b));
  EXPECT_THROW(with_helpers(w, std::vector<Mat4>{a}), Error);
}

namespace {

/// The T-rex with its starter net: the bench's case whose feet no linear skin
/// of its joints can follow (shin and foot turn up to 138 degrees against each
/// other in the walk; docs/bake.md).
struct Trex {
  SurfaceMesh mesh;
  SkinnedMesh file;
  Rig rig;
  Trex()
      : mesh(load_mesh(test::data("quaternius/Trex.glb"))), file(load_skinned_mesh(test::data("quaternius/Trex.glb"))) {
    StarterOptions so;
    so.deforming = weighted_joints(file);
    so.skin = &file;
    rig = make_starter(mesh, file.joints, so).rig;
  }
};

/// The joint a helper's node is under: the deeper of its two.
int helper_parent(const std::vector<Joint>& joints, const std::array<int, 2>& pair) {
  auto depth = [&](int j) {
    int d = 0;
    for (auto p = joints[static_cast<size_t>(j)].parent; p; ++d)
      p = std::find_if(joints.begin(), joints.end(), [&](const Joint& q) { return q.name == *p; })->parent;
    return d;
  };
  return depth(pair[1]) > depth(pair[0]) ? pair[1] : pair[0];
}

/// Mean and worst vertex of a skin against the rig over every frame (24 fps)
/// of a clip, as fractions of the diagonal at the pose's scale.
std::pair<double, double> clip_gap(const Binding& b, const SurfaceMesh& m, const SkinWeights& w,
                                   const SkinnedMesh& clips, int clip) {
  const auto rest = rest_of(b);
  std::vector<Vec3> rig(rest.size());
  double mean = 0, worst = 0;
  const auto [first, last] = clip_frames(clips, clip, 24);
  for (int f = first; f <= last; ++f) {
    const auto M = clip_skinning_matrices(b.joints(), clips, clip, f / 24.0);
    const double scale = std::cbrt(std::abs(M[0].topLeftCorner<3, 3>().determinant()));
    b.deform(M, rig);
    const auto x = skin_positions(w, rest, M);
    for (size_t v = 0; v < rest.size(); ++v) {
      const double d = (x[v] - rig[v]).norm() / (scale * m.bbox_diagonal());
      mean += d / static_cast<double>(rest.size() * static_cast<size_t>(last - first + 1));
      worst = std::max(worst, d);
    }
  }
  return {mean, worst};
}

} // namespace

TEST(Bake, HelperJointsCarryTheTrexsFeetRoundTheBendThatNoSkinOfItsJointsFollows) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const Trex t;
  const Binding b = bind(t.mesh, t.rig); // the default dq deformation
  const auto poses = training_poses(b.joints());
  const SkinWeights plain = fit_weights(b, poses, 4), helped = fit_weights(b, poses, 4, 16);
  // No helpers asked for: the plain fit, to the bit.
  const SkinWeights none = fit_weights(b, poses, 4, 0);
  EXPECT_EQ(none.joint, plain.joint);
  EXPECT_EQ(none.weight, plain.weight);
  EXPECT_TRUE(none.helpers.empty());
  EXPECT_THROW(fit_weights(b, poses, 4, -1), InputError);
  // At most the budget, each between two distinct rig joints, named after
  // both, listed after the rig's joints, and used by some vertex.
  const int nj = static_cast<int>(b.joints().size());
  ASSERT_GT(helped.helpers.size(), 0u);
  ASSERT_LE(helped.helpers.size(), 16u);
  EXPECT_EQ(helped.rig_joints(), nj);
  ASSERT_EQ(helped.joints.size(), static_cast<size_t>(nj) + helped.helpers.size());
  std::vector<int> uses(helped.joints.size(), 0);
  for (size_t i = 0; i < helped.joint.size(); ++i)
    if (helped.joint[i] >= 0)
      ++uses[static_cast<size_t>(helped.joint[i])];
  for (size_t h = 0; h < helped.helpers.size(); ++h) {
    const auto [a, c] = helped.helpers[h];
    EXPECT_TRUE(a >= 0 && c >= 0 && a < nj && c < nj && a != c);
    EXPECT_EQ(helped.joints[static_cast<size_t>(nj) + h].rfind(helped.joints[static_cast<size_t>(a)] + "~", 0), 0u);
    EXPECT_GT(uses[static_cast<size_t>(nj) + h], 0) << helped.joints[static_cast<size_t>(nj) + h];
  }
  // On the walk, which the fit never saw: the worst vertex (a foot) comes
  // less than half as far from the rig (3.9 % of the diagonal to 1.5 %), and
  // the mean does not get worse.
  const int walk = t.file.find_clip("Armature|TRex_Walk");
  ASSERT_GE(walk, 0);
  const auto [mean0, max0] = clip_gap(b, t.mesh, plain, t.file, walk);
  const auto [mean1, max1] = clip_gap(b, t.mesh, helped, t.file, walk);
  std::printf("T-rex walk, %% of the diagonal: plain fit mean %.3f max %.2f; with %zu helpers mean %.3f max %.2f\n",
              100 * mean0, 100 * max0, helped.helpers.size(), 100 * mean1, 100 * max1);
  EXPECT_GT(max0, 0.03);
  EXPECT_LT(max1, 0.5 * max0);
  EXPECT_LT(mean1, mean0);
}

namespace {

/// The T-rex bound, its weights fitted with up to eight helpers.
struct TrexWithHelpers {
  Trex t;
  Binding b;
  SkinWeights w;
  std::string mesh_file = test::data("quaternius/Trex.glb");
  TrexWithHelpers() : b(bind(t.mesh, t.rig)), w(fit_weights(b, training_poses(b.joints()), 4, 8)) {}
};

/// How far the baked file `back`, posed by its own skin at keys of its one
/// clip (at these fractions of it), is from the fitted skin posed by the
/// source clip `src` of `clips`: the worst vertex, as a fraction of the
/// diagonal at the pose's scale (infinite where the file poses a vertex to
/// no finite place).
double file_against_fit(const TrexWithHelpers& x, const SkinnedMesh& clips, int src, const SkinnedMesh& back,
                        std::initializer_list<double> fractions, double fps) {
  const InputTopology topo = read_input_topology(x.mesh_file);
  const auto [t0, t1] = back.clip_range(0);
  double worst = 0;
  for (const double f : fractions) {
    const double key = std::round(f * (t1 - t0) * fps) / fps + t0;
    const auto M = clip_skinning_matrices(x.b.joints(), clips, src, key);
    const double scale = std::cbrt(std::abs(M[0].topLeftCorner<3, 3>().determinant()));
    const auto ours = skin_positions(x.w, topo.faces.positions, M);
    const auto theirs = skin_positions(back, topo.faces.positions, back.skinning_matrices(0, key));
    for (const auto& p : theirs)
      if (!p.allFinite())
        return std::numeric_limits<double>::infinity();
    worst = std::max(worst, max_distance(ours, theirs) / (scale * x.t.mesh.bbox_diagonal()));
  }
  return worst;
}

} // namespace

TEST(Bake, AGlbWithHelperJointsKeysThemSoTheFilePlaysAsTheSkinWasFitted) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const TrexWithHelpers x;
  const auto& [t, b, w, mesh_file] = x;
  ASSERT_FALSE(w.helpers.empty());
  GltfBakeOptions opt;
  opt.clips = {"Armature|TRex_Walk"};
  const std::string bytes = skinned_glb(mesh_file, b.joints(), w, &t.file, opt);
  EXPECT_NE(bytes.find("\"curvenet_helper\""), std::string::npos) << "the helpers' extras name their joints";
  const std::string path = temp("trex_helpers.glb");
  write_file_atomic(path, bytes);
  const SkinnedMesh back = load_skinned_mesh(path);
  // The rig's joints, then each helper under the deeper of its two joints,
  // at that joint's rest frame.
  const size_t nj = b.joints().size();
  ASSERT_EQ(back.joints.size(), w.joints.size());
  for (size_t h = 0; h < w.helpers.size(); ++h) {
    const Joint& j = back.joints[nj + h];
    const int parent = helper_parent(b.joints(), w.helpers[h]);
    EXPECT_EQ(j.name, w.joints[nj + h]);
    ASSERT_TRUE(j.parent.has_value());
    EXPECT_EQ(*j.parent, b.joints()[static_cast<size_t>(parent)].name);
    EXPECT_LT((j.bind - b.joints()[static_cast<size_t>(parent)].bind).cwiseAbs().maxCoeff(), 1e-5);
  }
  // Posed by the file's own skin at its keys, it is our skin with the
  // helpers' matrices: the file carries the helpers' keys right.
  ASSERT_EQ(back.clip_names, opt.clips);
  EXPECT_LT(file_against_fit(x, t.file, t.file.find_clip("Armature|TRex_Walk"), back, {0, 0.7, 1}, opt.fps), 1e-5);
  // A skeleton that is not the weights' is refused.
  std::vector<Joint> fewer(b.joints().begin(), b.joints().end() - 1);
  EXPECT_THROW(skinned_glb(mesh_file, fewer, w), InputError);
}

TEST(Bake, AHelperWhoseJointAClipScalesUnevenlyOrFlattensIsARootNodeThatStillPlaysExactly) {
  // Under a joint that a clip stretches unevenly, the helper's local
  // transform would need a shear, which a glTF node's translation, rotation
  // and scale cannot hold; under a joint scaled to nothing it has no local
  // transform at all. The bake then writes that helper as a root node, and
  // the file still plays the skin that was fitted.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const TrexWithHelpers x;
  const auto& [t, b, w, mesh_file] = x;
  ASSERT_FALSE(w.helpers.empty());
  const size_t nj = b.joints().size();
  const std::string parent = b.joints()[static_cast<size_t>(helper_parent(b.joints(), w.helpers[0]))].name;
  // A clip file of the same skeleton (a plain bake of the walk), its
  // helper's parent's scale keys overwritten.
  GltfBakeOptions opt;
  opt.clips = {"Armature|TRex_Walk"};
  const std::string plain = temp("trex_walk_plain.glb");
  write_file_atomic(plain, skinned_glb(mesh_file, b.joints(), fit_weights(b, training_poses(b.joints()), 4), &t.file, opt));
  for (const Vec3 scale : {Vec3(1.5, 0.6, 1.0), Vec3(0, 0, 0)}) {
    tinygltf::Model model;
    tinygltf::TinyGLTF io;
    std::string err, warn;
    ASSERT_TRUE(io.LoadBinaryFromFile(&model, &err, &warn, plain)) << err;
    const auto keys = scale_keys(model, parent);
    ASSERT_EQ(keys.size(), 1u) << "the walk keys " << parent;
    for (size_t k = 0; k < keys[0].size(); ++k)
      keys[0][k] = static_cast<float>(scale[static_cast<int>(k % 3)]);
    const std::string clip_file = temp("trex_walk_scaled.glb");
    ASSERT_TRUE(io.WriteGltfSceneToFile(&model, clip_file, true, true, false, true));
    const SkinnedMesh clips = load_skinned_mesh(clip_file);
    const std::string path = temp("trex_helpers_scaled.glb");
    write_file_atomic(path, skinned_glb(mesh_file, b.joints(), w, &clips, opt));
    const SkinnedMesh back = load_skinned_mesh(path);
    ASSERT_EQ(back.joints.size(), w.joints.size());
    EXPECT_FALSE(back.joints[nj].parent.has_value()) << "the helper under " << parent << " is a root node";
    ASSERT_EQ(back.clip_names, opt.clips);
    EXPECT_LT(file_against_fit(x, clips, 0, back, {0, 0.5, 1}, opt.fps), 1e-5) << "scale " << scale.transpose();
  }
}
