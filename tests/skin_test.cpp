// Skins and clips from glTF: joints, inverse binds, skin weights, sampling.

#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/jobs.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"
#include "helpers.hpp"
#include "io/gltf_scene.hpp"

#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cmath>
#include <cstring>
#include <map>
#include <numbers>

using namespace curvenet;

TEST(Skin, HandSkeletonMatchesTheExampleRig) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SkinnedMesh skin = load_skinned_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  const Rig rig = read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json"));
  ASSERT_EQ(skin.joints.size(), 26u);
  ASSERT_EQ(rig.joints.size(), 26u);
  for (size_t j = 0; j < 26; ++j) {
    EXPECT_EQ(skin.joints[j].name, rig.joints[j].name);
    EXPECT_EQ(skin.joints[j].parent, rig.joints[j].parent);
    EXPECT_LT((skin.joints[j].bind - rig.joints[j].bind).cwiseAbs().maxCoeff(), 1e-6) << skin.joints[j].name;
  }
  // One influence set per file vertex, normalised.
  ASSERT_EQ(skin.vertex_joint.size(), 1764u);
  for (size_t v = 0; v < skin.vertex_weight.size(); ++v) {
    double sum = 0;
    for (double w : skin.vertex_weight[v])
      sum += w;
    EXPECT_NEAR(sum, 1.0, 1e-6) << v;
  }
}

TEST(Skin, TheAssimpPathReadsTheSameSkeleton) {
  // FBX skins go through assimp; the same code reads the glTF hand.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SkinnedMesh a = load_skinned_mesh_assimp(test::data("xr_tools_hand/hand_l.gltf"));
  const SkinnedMesh g = load_skinned_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  ASSERT_EQ(a.joints.size(), g.joints.size());
  for (const auto& j : g.joints) {
    const auto it = std::find_if(a.joints.begin(), a.joints.end(), [&](const Joint& x) { return x.name == j.name; });
    ASSERT_NE(it, a.joints.end()) << j.name;
    EXPECT_EQ(it->parent, j.parent) << j.name;
    EXPECT_LT((it->bind - j.bind).cwiseAbs().maxCoeff(), 1e-5) << j.name;
  }
  EXPECT_GT(a.vertex_weight.size(), 1000u);
  size_t skinned = 0;
  for (const auto& w : a.vertex_weight)
    skinned += w[0] > 0;
  EXPECT_EQ(skinned, a.vertex_weight.size());
}

TEST(Skin, ClipsMoveTheHandAndRestIsTheIdentity) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SkinnedMesh skin = load_skinned_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  EXPECT_EQ(skin.num_clips(), 35);
  const int grip = skin.find_clip("Grip");
  ASSERT_GE(grip, 0);
  EXPECT_EQ(skin.find_clip(std::to_string(grip)), grip);
  EXPECT_EQ(skin.find_clip("NoSuchClip"), -1);
  for (const Mat4& m : skin.skinning_matrices(-1, 0))
    EXPECT_LT((m - Mat4::Identity()).cwiseAbs().maxCoeff(), 1e-5);
  const RawMesh raw = read_raw_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  const auto posed = skin_positions(skin, raw.positions, skin.skinning_matrices(grip, skin.clip_range(grip).first));
  double moved = 0;
  for (size_t v = 0; v < posed.size(); ++v) {
    ASSERT_TRUE(posed[v].allFinite());
    moved = std::max(moved, (posed[v] - raw.positions[v]).norm());
  }
  EXPECT_GT(moved, 0.01); // the grip closes the fingers by centimetres
}

namespace {

/// A one-triangle glTF with one node animated by three samplers.
std::string write_animated_gltf(const std::filesystem::path& dir) {
  tinygltf::Model m;
  std::vector<float> data;
  auto add = [&](std::vector<float> values, int type, int count) {
    const size_t offset = data.size() * 4;
    data.insert(data.end(), values.begin(), values.end());
    tinygltf::BufferView view;
    view.buffer = 0;
    view.byteOffset = offset;
    view.byteLength = values.size() * 4;
    m.bufferViews.push_back(view);
    tinygltf::Accessor acc;
    acc.bufferView = static_cast<int>(m.bufferViews.size()) - 1;
    acc.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
    acc.count = count;
    acc.type = type;
    if (type == TINYGLTF_TYPE_SCALAR) {
      acc.minValues = {*std::min_element(values.begin(), values.end())};
      acc.maxValues = {*std::max_element(values.begin(), values.end())};
    }
    m.accessors.push_back(acc);
    return static_cast<int>(m.accessors.size()) - 1;
  };
  const int pos = add({0, 0, 0, 1, 0, 0, 0, 1, 0}, TINYGLTF_TYPE_VEC3, 3);
  m.accessors[pos].minValues = {0, 0, 0};
  m.accessors[pos].maxValues = {1, 1, 0};
  const int times = add({0, 1, 2}, TINYGLTF_TYPE_SCALAR, 3);
  const int trans = add({0, 0, 0, 2, 0, 0, 2, 4, 0}, TINYGLTF_TYPE_VEC3, 3);
  const float h = 0.70710678f;
  const int rot = add({0, 0, 0, 1, 0, 0, h, h, 0, 0, 1, 0}, TINYGLTF_TYPE_VEC4, 3);
  // Cubic: (in-tangent, value, out-tangent) per key; zero tangents.
  const int scl =
      add({0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0, 3, 3, 3, 0, 0, 0, 0, 0, 0, 3, 3, 3, 0, 0, 0}, TINYGLTF_TYPE_VEC3, 9);
  tinygltf::Buffer buffer;
  buffer.data.resize(data.size() * 4);
  std::memcpy(buffer.data.data(), data.data(), buffer.data.size());
  m.buffers.push_back(buffer);
  tinygltf::Primitive prim;
  prim.attributes["POSITION"] = pos;
  prim.mode = TINYGLTF_MODE_TRIANGLES;
  tinygltf::Mesh mesh;
  mesh.primitives.push_back(prim);
  m.meshes.push_back(mesh);
  tinygltf::Node node;
  node.mesh = 0;
  node.name = "n";
  m.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes = {0};
  m.scenes.push_back(scene);
  m.defaultScene = 0;
  tinygltf::Animation anim;
  anim.name = "move";
  auto sampler = [&](int out, const char* interp, const char* path) {
    tinygltf::AnimationSampler s;
    s.input = times;
    s.output = out;
    s.interpolation = interp;
    anim.samplers.push_back(s);
    tinygltf::AnimationChannel c;
    c.sampler = static_cast<int>(anim.samplers.size()) - 1;
    c.target_node = 0;
    c.target_path = path;
    anim.channels.push_back(c);
  };
  sampler(trans, "LINEAR", "translation");
  sampler(rot, "STEP", "rotation");
  sampler(scl, "CUBICSPLINE", "scale");
  m.animations.push_back(anim);
  m.asset.version = "2.0";
  const std::string path = (dir / "anim.gltf").string();
  tinygltf::TinyGLTF writer;
  EXPECT_TRUE(writer.WriteGltfSceneToFile(&m, path, true, true, true, false));
  return path;
}

} // namespace

TEST(Skin, ClipSamplingFollowsEachInterpolation) {
  const auto dir = test::temp_dir("anim");
  const detail::GltfScene scene = detail::read_gltf_scene(write_animated_gltf(dir));
  // t = 0.25: translation a quarter of the way (LINEAR), rotation still the
  // first key (STEP), scale by the Hermite basis with zero tangents:
  // 1 + 2 * (3 s^2 - 2 s^3) = 1.3125 (a linear blend would give 1.5).
  const Mat4 a = detail::node_world_matrices(scene, 0, 0.25)[0];
  EXPECT_NEAR(a(0, 3), 0.5, 1e-6);
  EXPECT_NEAR(a(1, 3), 0.0, 1e-6);
  EXPECT_NEAR(a(0, 0), 1.3125, 1e-6);
  EXPECT_NEAR(a(1, 0), 0.0, 1e-6);
  // t = 1.5: the rotation has stepped to 90 degrees about z.
  const Mat4 b = detail::node_world_matrices(scene, 0, 1.5)[0];
  EXPECT_NEAR(b(0, 3), 2.0, 1e-6);
  EXPECT_NEAR(b(1, 3), 2.0, 1e-6);
  EXPECT_NEAR(b(1, 0), 3.0, 1e-5); // R(90) * S(3): x goes to 3y
  // Past the end, every channel holds its last value; before the start, its first.
  const Mat4 c = detail::node_world_matrices(scene, 0, 10)[0];
  EXPECT_NEAR(c(1, 3), 4.0, 1e-6);
  const Mat4 d = detail::node_world_matrices(scene, 0, -1)[0];
  EXPECT_NEAR((d - Mat4::Identity()).cwiseAbs().maxCoeff(), 0.0, 1e-6);
}

TEST(Skin, AClipIsFoundByName_ByIndex_OrByItsNameAfterTheArmaturesBar) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SkinnedMesh horse = load_skinned_mesh(test::data("quaternius/Horse.glb"));
  const int walk = horse.find_clip("AnimalArmature|Walk");
  ASSERT_GE(walk, 0);
  EXPECT_EQ(horse.find_clip("Walk"), walk);
  EXPECT_EQ(horse.find_clip(std::to_string(walk)), walk);
  EXPECT_EQ(horse.clip_names[horse.find_clip("Idle")], "AnimalArmature|Idle"); // not Idle_2
  EXPECT_EQ(horse.find_clip("alk"), -1);
  EXPECT_EQ(horse.find_clip("Armature|Walk"), -1);
  EXPECT_EQ(horse.find_clip(""), -1);
}

TEST(Skin, FilesWithoutASkinAreRefused) {
  const auto dir = test::temp_dir("noskin");
  EXPECT_THROW(load_skinned_mesh(write_animated_gltf(dir)), InputError);
  EXPECT_THROW(load_skinned_mesh("/nonexistent.obj"), InputError);
}

TEST(Skin, ASkeletonFileReplacesARigsSkeletonByJointName) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string gltf = test::data("xr_tools_hand/hand_l.gltf");
  const std::string rig_file = test::data("xr_tools_hand/example/hand_l.cnrig.json");
  const auto from_gltf = load_skeleton(gltf);
  const auto from_rig = load_skeleton(rig_file);
  ASSERT_EQ(from_gltf.size(), from_rig.size());
  Rig rig = read_rig(rig_file);
  const Rig replaced = with_skeleton(rig, from_gltf, gltf);
  EXPECT_TRUE(replaced.has_skeleton);
  EXPECT_EQ(replaced.joints.size(), from_gltf.size());
  // Weights naming a joint the new skeleton lacks are refused, naming it.
  ASSERT_FALSE(rig.weights.empty());
  const std::string dropped = rig.weights.begin()->second.begin()->first;
  auto fewer = from_gltf;
  std::erase_if(fewer, [&](const Joint& j) { return j.name == dropped; });
  ASSERT_EQ(fewer.size() + 1, from_gltf.size());
  try {
    (void)with_skeleton(rig, fewer, "short.gltf");
    FAIL() << "a weight names a joint the skeleton lacks";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), "short.gltf");
    EXPECT_EQ(e.element(), dropped);
  }
  // A rig file without a skeleton is not a skeleton file.
  rig.has_skeleton = false;
  rig.joints.clear();
  const std::string bare = ::testing::TempDir() + "bare.cnrig.json";
  rig.weights.clear();
  write_rig(rig, bare);
  EXPECT_THROW((void)load_skeleton(bare), InputError);
}

TEST(Skin, ClipMatricesMatchJointsByNameAndFramesCoverTheClip) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SkinnedMesh clips = load_skinned_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  const Rig rig = read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json"));
  ASSERT_GT(clips.num_clips(), 0);
  const int clip = 0;
  const auto [t0, t1] = clips.clip_range(clip);
  const auto [first, last] = clip_frames(clips, clip, 24);
  EXPECT_LE(first / 24.0, t0 + 1e-9);
  EXPECT_GE(last / 24.0, t1 - 1e-9);
  EXPECT_LT(last - first, static_cast<int>(std::ceil((t1 - t0) * 24)) + 2);
  const double t = 0.5 * (t0 + t1);
  const auto M = clip_skinning_matrices(rig.joints, clips, clip, t);
  const auto expected = skinning_matrices(rig.joints, pose_from_clip(clips, clip, t));
  ASSERT_EQ(M.size(), expected.size());
  for (size_t j = 0; j < M.size(); ++j)
    EXPECT_EQ(M[j], expected[j]) << j;
  // A skeleton the clip does not know at all is refused, naming the clip file.
  auto strangers = rig.joints;
  for (auto& j : strangers) {
    j.name = "x_" + j.name;
    if (j.parent)
      j.parent = "x_" + *j.parent;
  }
  try {
    (void)clip_skinning_matrices(strangers, clips, clip, t);
    FAIL() << "no joint matches";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), clips.source);
  }
}

TEST(Skin, ARigPlacedByTheClipFilesArmatureTakesItsRootKeysOnce) {
  // A Blender export's armature scales its skeleton by 100 and turns it to
  // Y up, and its root keys carry that (the T-rex's root bind also has a
  // scale of 3 that its rest lacks). A rig whose skeleton is the file's as
  // its rest places it (a rig transferred to a Blender re-export, which
  // applies the armature to the mesh) was moved by the armature twice: the
  // walk made its mesh a hundred times too large, on its back. It now poses
  // where the file's own rig poses it, on all four animals.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  for (const char* name : {"Horse", "Wolf", "Trex", "Apatosaurus"}) {
    const SkinnedMesh file = load_skinned_mesh(test::data(std::string("quaternius/") + name + ".glb"));
    const std::vector<Mat4> placing = file.rest_placing();
    ASSERT_EQ(placing.size(), file.joints.size());
    ASSERT_GT((placing[0] - Mat4::Identity()).cwiseAbs().maxCoeff(), 1.0) << name;
    auto placed = file.joints;
    for (size_t j = 0; j < placed.size(); ++j)
      placed[j].bind = placing[j] * placed[j].bind;
    EXPECT_TRUE(placed_by_armature(placed, file)) << name;
    EXPECT_FALSE(placed_by_armature(file.joints, file)) << name;
    const std::string n = name;
    const int walk = file.find_clip(n == "Trex" ? "TRex_Walk" : n == "Apatosaurus" ? "Apatosaurus_Walk" : "Walk");
    ASSERT_GE(walk, 0) << name;
    const auto [t0, t1] = file.clip_range(walk);
    for (const double t : {t0, 0.5 * (t0 + t1)}) {
      const auto own = clip_skinning_matrices(file.joints, file, walk, t);
      const auto moved = clip_skinning_matrices(placed, file, walk, t);
      // A point p of the file's mesh bound to joint j is placing_j * p on
      // the placed mesh: posed, it lands where the file's own rig puts p.
      double worst = 0, size = 0;
      for (size_t j = 0; j < own.size(); ++j) {
        worst = std::max(worst, (moved[j] * placing[j] - own[j]).cwiseAbs().maxCoeff());
        size = std::max(size, own[j].cwiseAbs().maxCoeff());
      }
      EXPECT_LE(worst, 1e-6 * size) << name << " at " << t; // the clip's keys are floats
    }
    // Which the note about an armature applied twice no longer says.
    for (const std::string& note : clip_notes(placed, file))
      EXPECT_EQ(note.find("a second time"), std::string::npos) << name << ": " << note;
    // A re-export that also moves the placed skeleton and its mesh as a
    // whole (Blender lowers the Apatosaurus by twice its root's height) is
    // placed by that move: its mesh plays where the file's does.
    const Mat4 a = file.armature();
    Mat4 shift = Mat4::Identity();
    shift.block<3, 1>(0, 3) = 2 * Mat4(a * file.joints[0].bind).block<3, 1>(0, 3) + Eigen::Vector3d(0.3, -0.2, 0.1);
    const Mat4 g = shift * a;
    auto moved_rig = file.joints;
    for (Joint& j : moved_rig)
      j.bind = g * j.bind;
    EXPECT_TRUE(placed_by_armature(moved_rig, file)) << name;
    for (const double t : {t0, 0.5 * (t0 + t1)}) {
      const auto own = clip_skinning_matrices(file.joints, file, walk, t);
      const auto moved = clip_skinning_matrices(moved_rig, file, walk, t);
      double worst = 0, size = 0;
      for (size_t j = 0; j < own.size(); ++j) {
        worst = std::max(worst, (moved[j] * g - own[j]).cwiseAbs().maxCoeff());
        size = std::max(size, own[j].cwiseAbs().maxCoeff());
      }
      EXPECT_LE(worst, 1e-6 * size) << name << " moved, at " << t;
    }
    // A skeleton only moved, not at the scene's scale and turn, is the
    // user's own placing: its keys are taken as they are.
    auto only_moved = file.joints;
    for (Joint& j : only_moved)
      j.bind = shift * j.bind;
    EXPECT_FALSE(placed_by_armature(only_moved, file)) << name;
  }
  // A file that rests at its binds, to its floats (the hand's rest placing
  // is the identity within 4e-8), places nothing: a rig its user moved or
  // turned keeps its keys, and stays where it was put.
  const SkinnedMesh hand = load_skinned_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  EXPECT_TRUE(hand.scene_placings().empty());
  Mat4 moved_by_user = Mat4::Identity();
  moved_by_user.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  moved_by_user.block<3, 1>(0, 3) = Eigen::Vector3d(0.05, -0.02, 0.1);
  for (const Mat4& m : {moved_by_user, Mat4(Eigen::Affine3d(Eigen::Translation3d(0.05, -0.02, 0.1)).matrix())}) {
    auto rig = hand.joints;
    for (Joint& j : rig)
      j.bind = m * j.bind;
    EXPECT_FALSE(placed_by_armature(rig, hand));
  }
  // A Blender re-export's skeleton is the horse's placed, to its float
  // export, with other bone axes: its root moves as the horse's does (to
  // the pose format's translation, rotation and scale per axis, which a
  // root scaled unevenly and turned to other axes bends a little).
  const SkinnedMesh horse = load_skinned_mesh(test::data("quaternius/Horse.glb"));
  const auto again = load_skinned_mesh(std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/Horse_decimated.glb");
  EXPECT_TRUE(placed_by_armature(again.joints, horse));
  ASSERT_EQ(again.joints[0].name, horse.joints[0].name);
  ASSERT_FALSE(horse.joints[0].parent);
  const Mat4 p0 = horse.rest_placing()[0];
  for (const double t : {0.0, 0.4}) {
    const auto own = clip_skinning_matrices(horse.joints, horse, horse.find_clip("Walk"), t);
    const auto its = clip_skinning_matrices(again.joints, horse, horse.find_clip("Walk"), t);
    EXPECT_LE((its[0] * p0 - own[0]).cwiseAbs().maxCoeff(), 1e-3 * own[0].cwiseAbs().maxCoeff()) << t;
  }
}

TEST(Skin, AClipPoserGivesTheClipsMatricesAtEveryFrameWithThePlacingFoundOnce) {
  // The jobs pose frame after frame through a ClipPoser, which works out
  // once how the file places the rig: its matrices are exactly
  // clip_skinning_matrices' at every frame of every clip, for a rig the
  // file's armature places (the horse's skeleton placed) and one it does
  // not (the file's own, and the hand's).
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SkinnedMesh horse = load_skinned_mesh(test::data("quaternius/Horse.glb"));
  const SkinnedMesh hand = load_skinned_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  auto placed = horse.joints;
  const std::vector<Mat4> placing = horse.rest_placing();
  for (size_t j = 0; j < placed.size(); ++j)
    placed[j].bind = placing[j] * placed[j].bind;
  ASSERT_TRUE(placed_by_armature(placed, horse));
  struct Case {
    const std::vector<Joint>* joints;
    const SkinnedMesh* clips;
  };
  for (const Case& c : {Case{&placed, &horse}, Case{&horse.joints, &horse}, Case{&hand.joints, &hand}}) {
    const ClipPoser poser(*c.joints, *c.clips);
    int frames = 0;
    for (int clip = 0; clip < c.clips->num_clips(); ++clip) {
      const auto [first, last] = clip_frames(*c.clips, clip, 24);
      for (int f = first; f <= last; f += 3, ++frames) {
        const auto expected = clip_skinning_matrices(*c.joints, *c.clips, clip, f / 24.0);
        const auto got = poser(clip, f / 24.0);
        ASSERT_EQ(got.size(), expected.size());
        for (size_t j = 0; j < got.size(); ++j)
          ASSERT_EQ(got[j], expected[j]) << c.clips->source << " clip " << clip << " frame " << f << " joint " << j;
      }
    }
    EXPECT_GT(frames, 10) << c.clips->source;
  }
  // And it refuses a skeleton the clips do not name, as each call does.
  std::vector<Joint> strangers = hand.joints;
  for (Joint& j : strangers)
    j.name = "not_" + j.name;
  EXPECT_THROW((void)ClipPoser(strangers, hand)(0, 0.0), InputError);
}

TEST(Skin, ASkeletonFileIsPlacedByItsArmatureForAMeshInTheScenesSpace) {
  // An OBJ exported from Blender is in the scene's space, where the horse's
  // armature puts its skeleton (100 times the skin's size, Y up); the
  // horse's joints as bound span a hundredth of it, and the starter refused
  // every such OBJ with --skeleton Horse.glb ("lies outside the mesh"). The
  // joints are taken as the armature places them, with a note; for the
  // horse's own mesh, as bound.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string horse = test::data("quaternius/Horse.glb");
  const SkinnedMesh skin = load_skinned_mesh(horse);
  const SkeletonFile own = read_skeleton_file(horse, load_mesh(horse));
  EXPECT_TRUE(own.note.empty()) << own.note;
  ASSERT_EQ(own.joints.size(), skin.joints.size());
  for (size_t j = 0; j < own.joints.size(); ++j)
    EXPECT_EQ(own.joints[j].bind, skin.joints[j].bind) << own.joints[j].name;
  // The re-export's mesh is in the scene's space (its inverse bind matrices
  // hold the armature): the horse's joints land on the re-export's own.
  const std::string again_file = std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/Horse_decimated.glb";
  const SurfaceMesh scene_mesh = load_mesh(again_file);
  const SkeletonFile placed = read_skeleton_file(horse, scene_mesh);
  EXPECT_NE(placed.note.find("taken as placed"), std::string::npos) << placed.note;
  const SkinnedMesh again = load_skinned_mesh(again_file);
  std::map<std::string, Vec3> there;
  for (const Joint& j : again.joints)
    there[j.name] = j.bind.block<3, 1>(0, 3);
  double worst = 0;
  for (const Joint& j : placed.joints)
    worst = std::max(worst, (Vec3(j.bind.block<3, 1>(0, 3)) - there.at(j.name)).norm());
  EXPECT_LT(worst, 1e-3 * scene_mesh.bbox_diagonal());
  // A rig file, or a skin without an armature, is as it was.
  const std::string hand = test::data("xr_tools_hand/hand_l.gltf");
  EXPECT_TRUE(read_skeleton_file(hand, scene_mesh).note.empty());
}

// --- dual-quaternion skinning, the baseline a rigger compares with ----------

namespace {

SkinnedMesh two_joint_skin(const std::vector<Vec3>& points, double child_weight) {
  SkinnedMesh s;
  Joint root, child;
  root.name = "root";
  child.name = "child";
  child.parent = "root";
  child.bind(1, 3) = 1; // one up the y axis
  s.joints = {root, child};
  for (size_t v = 0; v < points.size(); ++v) {
    s.vertex_joint.push_back({0, 1, -1, -1});
    s.vertex_weight.push_back({1 - child_weight, child_weight, 0, 0});
  }
  return s;
}

} // namespace

TEST(Skin, DualQuaternionSkinningIsExactForOneJointAndForRigidMotions) {
  const std::vector<Vec3> pts{{0.3, 0.2, -0.1}, {1, 2, 3}, {-0.5, 1.5, 0.25}};
  Eigen::Affine3d T = Eigen::Affine3d::Identity();
  T.translate(Vec3(0.4, -1, 2));
  T.rotate(Eigen::AngleAxisd(2.5, Vec3(1, -2, 0.5).normalized()));
  for (const double w : {0.0, 0.3, 1.0}) {
    const SkinnedMesh s = two_joint_skin(pts, w);
    // Both joints moved alike: every point moves rigidly.
    const auto out = skin_positions(s, pts, {T.matrix(), T.matrix()}, Skinning::DualQuaternion);
    for (size_t i = 0; i < pts.size(); ++i)
      EXPECT_LT((out[i] - T * pts[i]).norm(), 1e-12) << w;
  }
  // One joint alone: its own motion, exactly as LBS gives it.
  const SkinnedMesh s = two_joint_skin(pts, 1.0);
  const Mat4 R = Eigen::Affine3d(Eigen::AngleAxisd(1.1, Vec3::UnitZ())).matrix();
  const auto dq = skin_positions(s, pts, {Mat4::Identity(), R}, Skinning::DualQuaternion);
  const auto lbs = skin_positions(s, pts, {Mat4::Identity(), R}, Skinning::Linear);
  for (size_t i = 0; i < pts.size(); ++i)
    EXPECT_LT((dq[i] - lbs[i]).norm(), 1e-12);
}

TEST(Skin, DualQuaternionSkinningTurnsA180DegreeTwistInsteadOfCollapsingIt) {
  // Points on a unit circle about the y axis, weighted half and half: the
  // child twisted by 180 degrees about y. LBS averages each point with its
  // opposite, the centre; DQS turns it by 90 degrees and keeps its radius.
  std::vector<Vec3> ring;
  for (int k = 0; k < 8; ++k)
    ring.emplace_back(std::cos(k * 0.785398), 0.5, std::sin(k * 0.785398));
  const SkinnedMesh s = two_joint_skin(ring, 0.5);
  const Mat4 twist = Eigen::Affine3d(Eigen::AngleAxisd(std::numbers::pi, Vec3::UnitY())).matrix();
  const auto dq = skin_positions(s, ring, {Mat4::Identity(), twist}, Skinning::DualQuaternion);
  const auto lbs = skin_positions(s, ring, {Mat4::Identity(), twist}, Skinning::Linear);
  const Eigen::AngleAxisd quarter(std::numbers::pi / 2, Vec3::UnitY());
  for (size_t i = 0; i < ring.size(); ++i) {
    EXPECT_NEAR(std::hypot(dq[i].x(), dq[i].z()), 1.0, 1e-12);
    EXPECT_LT((dq[i] - quarter * ring[i]).norm(), 1e-12);
    EXPECT_LT(std::hypot(lbs[i].x(), lbs[i].z()), 1e-12);
  }
  // A bend of 90 degrees about the joint: the half-way point turns by 45
  // degrees about the joint (on the circle about it), where LBS cuts the chord.
  const Mat4 bend = (Eigen::Translation3d(0, 1, 0) * Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitZ()) *
                     Eigen::Translation3d(0, -1, 0))
                        .matrix();
  const std::vector<Vec3> p{{0, 2, 0}};
  const auto b = skin_positions(two_joint_skin(p, 0.5), p, {Mat4::Identity(), bend}, Skinning::DualQuaternion);
  EXPECT_NEAR((b[0] - Vec3(0, 1, 0)).norm(), 1.0, 1e-12);
  EXPECT_NEAR(std::atan2(-b[0].x(), b[0].y() - 1), std::numbers::pi / 4, 1e-12);
}

TEST(Skin, DualQuaternionBlendTakesTheHeaviestJointsHemisphereWhateverTheOrder) {
  // Two heavy joints turned +-20 degrees about z (weights 0.5 and 0.4) and a
  // light one (0.1) turned 180:
  // the light one's quaternion is nearly orthogonal to both heavy ones. Taken
  // as the hemisphere, it sent the heavy ones to opposite sides, their sum
  // cancelled, and the point turned by nearly 180 degrees. From the heaviest
  // joint it turns by about 9 degrees, for any order of the joints.
  SkinnedMesh s;
  for (const char* name : {"a", "b", "c"}) {
    Joint j;
    j.name = name;
    s.joints.push_back(j);
  }
  const Vec3 p(1, 0, 0);
  const auto turn = [](double degrees) {
    return Eigen::Affine3d(Eigen::AngleAxisd(degrees * std::numbers::pi / 180, Vec3::UnitZ())).matrix();
  };
  const std::vector<Mat4> pose{turn(180), turn(20), turn(-20)};
  const std::vector<std::array<int, 3>> orders{{0, 1, 2}, {1, 0, 2}, {2, 1, 0}, {0, 2, 1}};
  const std::array<double, 3> weight{0.1, 0.5, 0.4};
  std::vector<Vec3> results;
  for (const auto& order : orders) {
    s.vertex_joint = {{order[0], order[1], order[2], -1}};
    s.vertex_weight = {{weight[order[0]], weight[order[1]], weight[order[2]], 0}};
    const Vec3 q = skin_positions(s, {p}, pose, Skinning::DualQuaternion)[0];
    const double angle = std::atan2(q.y(), q.x()) * 180 / std::numbers::pi;
    EXPECT_NEAR(q.norm(), 1.0, 1e-12);
    EXPECT_GT(angle, 5);
    EXPECT_LT(angle, 20);
    results.push_back(q);
  }
  for (const Vec3& q : results)
    EXPECT_LT((q - results[0]).norm(), 1e-12);
}
