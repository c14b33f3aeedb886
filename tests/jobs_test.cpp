// The jobs layer (curvenet/jobs.hpp): a clip's frames as a checked range,
// deformed in blocks and streamed in order to sinks.

#include "core/convex_least_squares.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/jobs.hpp"
#include "curvenet/layer.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/rig.hpp"
#include "curvenet/starter.hpp"
#include "helpers.hpp"
#include "io/file_bytes.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <filesystem>
#include <fstream>
#include <sstream>

using namespace curvenet;
namespace fs = std::filesystem;

namespace {

struct Rigged {
  SurfaceMesh mesh;
  SkinnedMesh clips;
  Binding binding;
};

Rigged rigged_simple() {
  const std::string path = test::data("rigged_simple/RiggedSimple.gltf");
  SurfaceMesh mesh = load_mesh(path);
  SkinnedMesh clips = load_skinned_mesh(path);
  Binding binding = bind(mesh, make_starter(mesh, clips.joints).rig);
  return {std::move(mesh), std::move(clips), std::move(binding)};
}

} // namespace

TEST(Jobs, AFrameRangeIsTheClipsOrTwoWholeNumbersWithinTheCap) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SkinnedMesh clips = load_skinned_mesh(test::data("rigged_simple/RiggedSimple.gltf"));
  const auto [first, last] = clip_frames(clips, 0, 24);
  const FrameRange whole = frame_range(clips, 0, 24);
  EXPECT_EQ(whole.first, first);
  EXPECT_EQ(whole.last, last);
  EXPECT_DOUBLE_EQ(whole.time(12), 0.5);
  const FrameRange part = frame_range(clips, 0, 24, "-3:7");
  EXPECT_EQ(part.first, -3);
  EXPECT_EQ(part.count(), 11);
  for (const char* bad : {"1.5:3", "1:2:3", "0:1e3", "3", "4:2", ":", "a:b"})
    EXPECT_THROW(frame_range(clips, 0, 24, bad), InputError) << bad;
  try {
    frame_range(clips, 0, 24, "0:200", 100);
    ADD_FAILURE() << "the cap was not kept";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("201 frames is more than --max-frames (100)"), std::string::npos) << e.what();
  }
}

TEST(Jobs, FramesReachEverySinkInOrderExactlyAsDeformGivesThem) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const Rigged s = rigged_simple();
  const FrameRange range = frame_range(s.clips, 0, 24);
  ASSERT_GT(range.count(), 2);
  std::vector<int> seen_a, seen_b;
  std::vector<std::vector<Vec3>> got;
  FunctionSink a([&](int f, std::span<const Vec3> p) {
    seen_a.push_back(f);
    got.emplace_back(p.begin(), p.end());
  });
  FunctionSink b([&](int f, std::span<const Vec3>) { seen_b.push_back(f); });
  FrameSink* sinks[] = {&a, &b};
  animate(s.binding, s.clips, 0, range, sinks);
  ASSERT_EQ(static_cast<int>(seen_a.size()), range.count());
  EXPECT_EQ(seen_a, seen_b);
  for (int k = 0; k < range.count(); ++k) {
    EXPECT_EQ(seen_a[k], range.first + k);
    std::vector<Vec3> want(s.binding.num_input_vertices());
    s.binding.deform(clip_skinning_matrices(s.binding.joints(), s.clips, 0, range.time(range.first + k)), want);
    EXPECT_EQ(got[k], want) << "frame " << range.first + k; // bit for bit
  }
}

TEST(Jobs, ALayersFramesCarryTheirOwnEnvelopeAndNodeOffsetsExactlyAsDeformGivesThem) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string path = test::data("rigged_simple/RiggedSimple.gltf");
  const SurfaceMesh mesh = load_mesh(path);
  const SkinnedMesh skin = load_skinned_mesh(path);
  const Rig rig = make_starter(mesh, skin.joints).rig;
  const CurveLayer layer = bind_layer(mesh, rig, &skin);
  const FrameRange range = frame_range(skin, 0, 24, "0:9");
  // Per frame: an envelope rising from 0 to 1, and every other frame a node pulled.
  auto frame = [&](int f) {
    LayerFrame out;
    out.skinning = clip_skinning_matrices(layer.joints(), skin, 0, range.time(f));
    out.envelope = f / 9.0;
    if (f % 2)
      out.offsets[rig.nodes[0].id] = Vec3(0, 0, 0.05 * mesh.bbox_diagonal());
    return out;
  };
  std::vector<std::vector<Vec3>> got;
  FunctionSink sink([&](int, std::span<const Vec3> p) { got.emplace_back(p.begin(), p.end()); });
  FrameSink* sinks[] = {&sink};
  animate(layer, frame, range, sinks, "clip");
  ASSERT_EQ(static_cast<int>(got.size()), range.count());
  for (int f = range.first; f <= range.last; ++f) {
    const LayerFrame want_frame = frame(f);
    std::vector<Vec3> want(layer.num_input_vertices());
    layer.deform(want_frame.skinning, want, want_frame.envelope, &want_frame.offsets);
    EXPECT_EQ(got[f - range.first], want) << "frame " << f; // bit for bit
  }
  // The layer corrects the skin: frame 8 (envelope 8/9) is not the skin alone.
  std::vector<Vec3> skin_only(layer.num_input_vertices());
  layer.deform(frame(8).skinning, skin_only, 0);
  EXPECT_EQ(got[0].size(), skin_only.size());
  EXPECT_NE(got[8], skin_only);
  // An envelope out of range is refused, naming the frame.
  try {
    animate(
        layer,
        [&](int f) {
          LayerFrame out = frame(f);
          out.envelope = f == 4 ? 1.5 : 1.0;
          return out;
        },
        range, sinks, "clip");
    ADD_FAILURE() << "an envelope of 1.5 was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("frame 4"), std::string::npos) << e.what();
  }
}

TEST(Jobs, APc2StreamedOnOneThreadOrManyIsTheSameBytesAndIsAllOrNothing) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const Rigged s = rigged_simple();
  const auto dir = test::temp_dir("jobs_pc2");
  const FrameRange range = frame_range(s.clips, 0, 24);
  auto write = [&](const fs::path& path, int threads) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    OutputFiles files;
    Pc2Sink pc2(files, path.string(), s.binding.num_input_vertices(), range);
    FrameSink* sinks[] = {&pc2};
    animate(s.binding, s.clips, 0, range, sinks);
    files.commit();
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  };
  const std::string one = write(dir / "one.pc2", 1), four = write(dir / "four.pc2", 4);
  EXPECT_EQ(one, four);
  EXPECT_EQ(one.size(), 32 + static_cast<size_t>(range.count()) * s.binding.num_input_vertices() * 12);
  // A sink that fails part way: nothing is written.
  {
    OutputFiles files;
    Pc2Sink pc2(files, (dir / "failed.pc2").string(), s.binding.num_input_vertices(), range);
    FunctionSink fail([&](int f, std::span<const Vec3>) {
      if (f == range.first + 1)
        throw Error("stop");
    });
    FrameSink* sinks[] = {&pc2, &fail};
    EXPECT_THROW(animate(s.binding, s.clips, 0, range, sinks), Error);
  }
  EXPECT_FALSE(fs::exists(dir / "failed.pc2"));
}

TEST(Jobs, APoseJobReadsTheMeshFileOnceForItsSurfaceAndItsTopology) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("jobs_reads");
  for (const std::string mesh : {"xr_tools_hand/hand_l.gltf", "xr_tools_hand/example/hand_l_welded.obj"}) {
    PoseJob job;
    job.scene = {test::data(mesh), test::data("xr_tools_hand/example/hand_l.cnrig.json"), "", ""};
    job.pose = test::data("xr_tools_hand/example/fist.pose.json");
    job.out = (dir / "fist.obj").string();
    job.cut_mesh = (dir / "fist_cut.obj").string();
    const long before = detail::file_reads(job.scene.mesh);
    (void)run(job); // the surface, the input topology, the cut mesh: one read at most (none if cached)
    EXPECT_LE(detail::file_reads(job.scene.mesh) - before, 1) << mesh;
    const long again = detail::file_reads(job.scene.mesh);
    (void)run(job); // a settled file, unchanged: not read again
    EXPECT_EQ(detail::file_reads(job.scene.mesh), again) << mesh;
  }
}

TEST(Jobs, ABakeCountsItsClipsFramesBeforeAnyWorkAndRefusesPastMaxFrames) {
  // A clip whose keys ran for days was sampled for hours (a fuzzer's hang).
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("bake_max_frames");
  BakeJob job;
  job.scene = {test::data("xr_tools_hand/hand_l.gltf"), test::data("xr_tools_hand/example/hand_l.cnrig.json"), "", ""};
  job.clip_file = test::data("xr_tools_hand/hand_l_poses.glb"); // 35 clips of one frame or two each
  job.glb = (dir / "hand.glb").string();
  job.max_frames = 20;
  try {
    (void)run(job);
    ADD_FAILURE() << "35 clips at 24 fps were baked under --max-frames 20";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), job.clip_file);
    EXPECT_NE(std::string(e.what()).find("more than --max-frames (20)"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(job.glb));
  job.clip_names = {"Grip"}; // only the carried clips count
  EXPECT_NO_THROW((void)run(job));
  EXPECT_TRUE(fs::exists(job.glb));
}

TEST(Jobs, ABakeRefusesAClipFileWithoutClips) {
  // A file with no clips was baked with none, exit 0.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("bake_no_clips");
  BakeJob job;
  job.scene = {test::data("xr_tools_hand/hand_l.gltf"), test::data("xr_tools_hand/example/hand_l.cnrig.json"), "", ""};
  job.clip_file = test::data("xr_tools_hand/hand_l.gltf"); // a skin, no animation
  job.glb = (dir / "hand.glb").string();
  for (const bool fit : {false, true}) {
    BakeJob j = job;
    if (fit)
      std::swap(j.clip_file, j.fit);
    try {
      (void)run(j);
      ADD_FAILURE() << "a file without clips was baked";
    } catch (const InputError& e) {
      EXPECT_EQ(e.element(), "/animations");
      EXPECT_NE(std::string(e.what()).find(fit ? "no animation clips to fit over" : "no animation clips to carry"),
                std::string::npos)
          << e.what();
    }
    EXPECT_FALSE(fs::exists(j.glb));
  }
}

TEST(Jobs, ABakeCountsCarriesAndReportsAClipNamedByItsShortName) {
  // "Walk" for "AnimalArmature|Walk" passed the name check, and then the
  // frame count and the fidelity report looked for the name as written and
  // found nothing: --max-frames let it through and no fidelity was said.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("bake_short_name");
  const std::string horse = test::data("quaternius/Horse.glb");
  write_rig(test::skinned_starter(horse), (dir / "horse.cnrig.json").string());
  BakeJob job;
  job.scene = {horse, (dir / "horse.cnrig.json").string(), "", ""};
  job.clip_file = horse;
  job.clip_names = {"Walk"};
  job.glb = (dir / "horse.glb").string();
  job.max_frames = 1;
  EXPECT_THROW((void)run(job), InputError) << "the walk's frames are counted against --max-frames";
  EXPECT_FALSE(fs::exists(job.glb));
  job.max_frames = 100000;
  const BakeSummary s = run(job);
  EXPECT_EQ(s.clips, 1);
  ASSERT_EQ(s.fidelity.size(), 1u);
  EXPECT_EQ(s.fidelity[0].clip, "AnimalArmature|Walk");
  EXPECT_EQ(load_skinned_mesh(job.glb).clip_names, std::vector<std::string>{"AnimalArmature|Walk"});
}

TEST(Jobs, ABakeReportsEachClipsFidelityToTheRigWorstFirst) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("bake_fidelity");
  BakeJob job;
  job.scene = {test::data("xr_tools_hand/hand_l.gltf"), test::data("xr_tools_hand/example/hand_l.cnrig.json"), "", ""};
  job.clip_file = test::data("xr_tools_hand/hand_l_poses.glb");
  job.glb = (dir / "hand.glb").string();
  const BakeSummary s = run(job);
  ASSERT_EQ(s.fidelity.size(), 35u);
  for (size_t i = 0; i < s.fidelity.size(); ++i) {
    const auto& f = s.fidelity[i];
    EXPECT_EQ(f.frames, 1) << f.clip; // the hand's clips are single poses
    EXPECT_GE(f.max, f.mean) << f.clip;
    EXPECT_GE(f.worst_vertex, 0) << f.clip;
    EXPECT_FALSE(f.worst_joint.empty()) << f.clip;
    if (i > 0)
      EXPECT_LE(f.max, s.fidelity[i - 1].max) << "worst first";
  }
  // The worst clip's worst vertex, measured anew: the baked file's own
  // weights under LBS against the rig's deformation at that pose.
  const auto& worst = s.fidelity.front();
  const SurfaceMesh mesh = load_mesh(job.scene.mesh);
  const Binding b = bind(mesh, read_rig(job.scene.rig));
  const SkinnedMesh baked = load_skinned_mesh(job.glb), clips = load_skinned_mesh(job.clip_file);
  const int c = clips.find_clip(worst.clip);
  const double t = clips.clip_range(c).first;
  std::vector<Vec3> rest(b.num_input_vertices()), rig(rest.size());
  b.deform(std::vector<Mat4>(b.joints().size(), Mat4::Identity()), rest);
  b.deform(clip_skinning_matrices(b.joints(), clips, c, t), rig);
  const std::vector<Vec3> skin = skin_positions(baked, rest, clip_skinning_matrices(baked.joints, clips, c, t));
  const double diag = mesh.bbox_diagonal();
  const auto v = static_cast<size_t>(worst.worst_vertex);
  EXPECT_NEAR((skin[v] - rig[v]).norm() / diag, worst.max, 1e-5);
  for (size_t i = 0; i < rest.size(); ++i)
    EXPECT_LE((skin[i] - rig[i]).norm() / diag, worst.max + 1e-5);
  // Its floor: the rig's position there against the convex hull of where
  // the joints that move the vertex carry it. The baked joints are some of
  // those, so the skin is never closer than the floor.
  std::vector<std::pair<int, double>> inf;
  b.harmonic_weights(worst.worst_vertex, inf);
  std::vector<Vec3> carried;
  const auto M = clip_skinning_matrices(b.joints(), clips, c, t);
  for (const auto& [j, x] : inf)
    carried.push_back((M[static_cast<size_t>(j)] * rest[v].homogeneous()).head<3>());
  EXPECT_EQ(worst.worst_joints, static_cast<int>(carried.size()));
  const auto hull = detail::nearest_in_hull(carried, rig[v]);
  EXPECT_NEAR(hull.distance / diag, worst.worst_floor, 1e-9); // the report's diagonal is the rig's rest box
  for (const auto& f : s.fidelity) {
    EXPECT_GE(f.worst_floor, 0) << f.clip;
    EXPECT_LE(f.worst_floor, f.max + 1e-12) << f.clip;
    EXPECT_GE(f.worst_joints, 1) << f.clip;
  }
  // Weights fitted to these clips play them closer, worst vertex and mean.
  job.fit = job.clip_file;
  const BakeSummary fitted = run(job);
  EXPECT_LT(fitted.fidelity.front().max, worst.max);
  double mean = 0, fitted_mean = 0;
  for (size_t i = 0; i < s.fidelity.size(); ++i) {
    mean += s.fidelity[i].mean;
    fitted_mean += fitted.fidelity[i].mean;
  }
  EXPECT_LT(fitted_mean, mean);
}

TEST(Jobs, ABakesFidelityIsMeasuredAtThePosesOwnScaleWhenTheArmatureScalesTheSkeleton) {
  // The T-rex's armature scales its skeleton by 100 (Blender's export): the
  // skin and the rig are posed 100 times the rest mesh's size, and the
  // report measures them against the diagonal at that scale.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("bake_fidelity_scaled");
  const std::string trex = test::data("quaternius/Trex.glb"), rig = (dir / "trex.cnrig.json").string();
  const SurfaceMesh mesh = load_mesh(trex);
  const SkinnedMesh clips = load_skinned_mesh(trex);
  write_rig(test::skinned_starter(trex), rig);
  BakeJob job;
  job.scene = {trex, rig, "", ""};
  job.clip_file = trex;
  job.clip_names = {clips.clip_names[static_cast<size_t>(clips.find_clip("TRex_Walk"))]};
  job.glb = (dir / "trex.glb").string();
  const BakeSummary s = run(job);
  ASSERT_EQ(s.fidelity.size(), 1u);
  const auto& f = s.fidelity.front();
  // Measured anew on the worst frame's scale: the posed rig's own diagonal.
  const Binding b = bind(mesh, read_rig(rig));
  const double t = clips.clip_range(f.index).first + f.worst_time;
  const std::vector<Mat4> M = clip_skinning_matrices(b.joints(), clips, f.index, t);
  std::vector<Vec3> rest(b.num_input_vertices()), posed(rest.size());
  b.deform(std::vector<Mat4>(M.size(), Mat4::Identity()), rest);
  b.deform(M, posed);
  Eigen::AlignedBox3d box0, box1;
  for (size_t v = 0; v < rest.size(); ++v) {
    box0.extend(rest[v]);
    box1.extend(posed[v]);
  }
  const double scale = box1.diagonal().norm() / box0.diagonal().norm();
  EXPECT_GT(scale, 50.0) << "the armature scales the pose";
  EXPECT_LT(f.mean, 0.01) << "a mean under 1 % of the diagonal, not 100 times it";
  EXPECT_GT(f.mean, 1e-5);
  EXPECT_LT(f.max, 0.2);
  // The floor at that scale too: no more than the worst vertex's distance,
  // and found anew at the worst frame of the walk (the rig's position there
  // against the hull of where the vertex's joints carry it).
  EXPECT_GT(f.worst_floor, 0);
  EXPECT_LE(f.worst_floor, f.max + 1e-12);
  std::vector<std::pair<int, double>> inf;
  b.harmonic_weights(f.worst_vertex, inf);
  std::vector<Vec3> carried;
  const auto v = static_cast<size_t>(f.worst_vertex);
  for (const auto& [j, x] : inf)
    carried.push_back((M[static_cast<size_t>(j)] * rest[v].homogeneous()).head<3>());
  std::vector<double> scales;
  for (const Mat4& m : M)
    scales.push_back(std::cbrt(std::abs(m.block<3, 3>(0, 0).determinant())));
  std::nth_element(scales.begin(), scales.begin() + static_cast<std::ptrdiff_t>(scales.size() / 2), scales.end());
  const double at_scale = box0.diagonal().norm() * scales[scales.size() / 2];
  EXPECT_NEAR(detail::nearest_in_hull(carried, posed[v]).distance / at_scale, f.worst_floor, 1e-6);
}

TEST(Jobs, ABakeWhoseClipOrFitFileHasAnotherSkeletonSaysSo) {
  // The keys a bake carries, measures and fits over are taken against the
  // file's own rest pose: a clip file in other units (a LOD exported at 100
  // times the scale) baked silently to a skin 45 % of the diagonal off.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("bake_other_skeleton");
  const std::string trex = test::data("quaternius/Trex.glb"), rig = (dir / "trex.cnrig.json").string();
  const Rig r = test::skinned_starter(trex);
  write_rig(r, rig);
  BakeJob job;
  job.scene = {trex, rig, "", ""};
  job.clip_file = trex;
  job.clip_names = {"TRex_Walk"};
  job.glb = (dir / "trex.glb").string();
  auto notes_of = [](const BakeSummary& s) {
    std::vector<std::string> out;
    for (const auto& n : s.notes)
      if (n.find("its skeleton is not the rig's") != std::string::npos)
        out.push_back(n);
    return out;
  };
  EXPECT_TRUE(notes_of(run(job)).empty()); // its own skeleton
  Rig longer = r; // bones a hundredth as long: the clip file is in other units
  for (Joint& j : longer.joints)
    j.bind.block<3, 1>(0, 3) *= 0.01;
  write_rig(longer, rig);
  auto notes = notes_of(run(job));
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("Trex.glb: its skeleton is not the rig's (joint '"), std::string::npos) << notes[0];
  EXPECT_NE(notes[0].find("--skeleton " + trex), std::string::npos) << notes[0];
  // The same file to fit over is said once, by another path too; a fit
  // file alone is said as well.
  job.fit = trex;
  EXPECT_EQ(notes_of(run(job)).size(), 1u);
  job.fit = (fs::path(trex).parent_path() / "." / fs::path(trex).filename()).string();
  EXPECT_EQ(notes_of(run(job)).size(), 1u) << job.fit;
  job.clip_file.clear();
  job.clip_names.clear();
  notes = notes_of(run(job));
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("Trex.glb: its skeleton is not the rig's"), std::string::npos) << notes[0];
}

TEST(Jobs, AnimatingWithAnotherSkeletonsClipsSaysHowManyJointsItMoves) {
  // Clip joints are matched to the rig's by name: a horse's walk on the
  // T-rex moves the joints both skeletons name, and the summary says how
  // few they are; the T-rex's own walk says nothing of the kind.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("animate_other_clips");
  const std::string trex = test::data("quaternius/Trex.glb"), rig = (dir / "trex.cnrig.json").string();
  const SkinnedMesh skin = load_skinned_mesh(trex);
  write_rig(test::skinned_starter(trex), rig);
  AnimateJob job;
  job.scene = {trex, rig, "", ""};
  job.frames = "0:1";
  job.pc2 = (dir / "walk.pc2").string();
  auto note_of = [](const AnimateSummary& s) {
    for (const auto& n : s.notes)
      if (n.find("joints (by name); the others stay at their rest pose") != std::string::npos)
        return n;
    return std::string();
  };
  job.clip_file = trex;
  job.clip = "TRex_Walk";
  EXPECT_EQ(note_of(run(job)), "");
  job.clip_file = test::data("quaternius/Horse.glb");
  job.clip = "Walk";
  const std::string note = note_of(run(job));
  EXPECT_NE(note.find("Horse.glb: its skeleton has "), std::string::npos) << note;
  EXPECT_NE(note.find(" of the rig's " + std::to_string(skin.joints.size()) + " joints"), std::string::npos) << note;
}

TEST(Jobs, AClipWhoseArmatureScalesItsSkeletonSaysSoToARigThatIsItsSkeletonScaledAsAWhole) {
  // The horse's armature scales its skeleton by 100 and its root keys carry
  // that. A rig transferred to a Blender re-export of it (the armature
  // applied to the mesh) has the skeleton scaled by 100 as a whole, and the
  // horse's own keys then scaled the re-export's mesh a second time, with
  // no word. The rig's own file, and a file without an armature, say nothing.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SkinnedMesh horse = load_skinned_mesh(test::data("quaternius/Horse.glb"));
  const SkinnedMesh hand = load_skinned_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  auto scaled = [](std::vector<Joint> joints) {
    Mat4 g = Mat4::Identity();
    g.topLeftCorner<3, 3>() *= 100;
    for (Joint& j : joints)
      j.bind = g * j.bind;
    return joints;
  };
  auto says = [](const std::vector<std::string>& notes) {
    return std::any_of(notes.begin(), notes.end(),
                       [](const std::string& n) { return n.find("a second time") != std::string::npos; });
  };
  EXPECT_TRUE(says(clip_notes(scaled(horse.joints), horse)));
  EXPECT_FALSE(says(clip_notes(horse.joints, horse)));
  EXPECT_FALSE(says(clip_notes(scaled(hand.joints), hand)));
  // A Blender re-export puts the armature in its inverse bind matrices: its
  // skin rests at its vertices' size and its keys scale nothing, so the
  // horse's skeleton (a hundredth of it) animated by it says nothing of this.
  const SkinnedMesh again =
      load_skinned_mesh(std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/Horse_decimated.glb");
  EXPECT_FALSE(says(clip_notes(horse.joints, again)));
}

TEST(Jobs, AnimatingWithAClipFileWhoseSkeletonIsNotTheRigsSaysSo) {
  // A rig transferred to a mesh exported in other units (or with other
  // bone axes) keeps its source's skeleton; the target file's clips, taken
  // against their own rest pose, then move it by other amounts. The run
  // says which joint differs and how to give the rig that skeleton.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("animate_other_skeleton");
  const std::string trex = test::data("quaternius/Trex.glb"), rig = (dir / "trex.cnrig.json").string();
  Rig r = test::skinned_starter(trex);
  write_rig(r, rig);
  AnimateJob job;
  job.scene = {trex, rig, "", ""};
  job.frames = "0:1";
  job.pc2 = (dir / "walk.pc2").string();
  job.clip_file = trex;
  job.clip = "TRex_Walk";
  auto note_of = [](const AnimateSummary& s) {
    for (const auto& n : s.notes)
      if (n.find("its skeleton is not the rig's") != std::string::npos)
        return n;
    return std::string();
  };
  EXPECT_EQ(note_of(run(job)), ""); // its own skeleton
  // The whole skeleton moved, turned and scaled by a similarity (as a
  // transfer does): still the same bones.
  Rig similar = r;
  const Mat4 S = (Eigen::Translation3d(1, 2, 3) * Eigen::AngleAxisd(0.7, Vec3(0, 1, 0)) * Eigen::Scaling(3.0)).matrix();
  for (Joint& j : similar.joints)
    j.bind = S * j.bind;
  write_rig(similar, rig);
  EXPECT_EQ(note_of(run(job)), "");
  // Bones a hundred times as long (a file in centimetres): said, by joint.
  Rig longer = r;
  for (Joint& j : longer.joints)
    j.bind.block<3, 1>(0, 3) *= 0.01;
  write_rig(longer, rig);
  std::string note = note_of(run(job));
  EXPECT_NE(note.find("Trex.glb: its skeleton is not the rig's (joint '"), std::string::npos) << note;
  EXPECT_NE(note.find("rests 100 times as far from its parent"), std::string::npos) << note;
  EXPECT_NE(note.find("--skeleton " + trex), std::string::npos) << note;
  // One bone's rest frame turned a quarter turn (other bone axes).
  Rig turned = r;
  Joint& k = turned.joints.back();
  k.bind.block<3, 3>(0, 0) = k.bind.block<3, 3>(0, 0) * Eigen::AngleAxisd(1.5707963267948966, Vec3(1, 0, 0)).matrix();
  write_rig(turned, rig);
  note = note_of(run(job));
  EXPECT_NE(note.find("joint '" + k.name + "' rests turned 90 degrees against the rig's"), std::string::npos) << note;
}
