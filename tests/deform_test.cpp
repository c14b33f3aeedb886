// Binding and deforming: the invariants, the maths, and the thesis's tube.

#include "bind/bone_heat.hpp"
#include "bind/gradient.hpp"
#include "bind/laplacian.hpp"
#include "curvenet/bake.hpp"
#include "curvenet/compare.hpp"
#include "curvenet/deform.hpp"
#include "curvenet/edit.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/quality.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/subdivide.hpp"
#include "embed/embedding_impl.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"
#include "trace/trace_mesh.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <nlohmann/json.hpp>
#include <tbb/task_arena.h>

#include <algorithm>

#include <sstream>

#include <fstream>

#include <cstring>

#include <Eigen/SparseCholesky>

#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <random>

using namespace curvenet;

namespace {

std::vector<Vec3> input_positions(const SurfaceMesh& m) {
  std::vector<Vec3> p;
  for (int w : m.input_to_welded)
    p.push_back(m.positions[w]);
  return p;
}

std::vector<Vec3> deform(const Binding& b, const Pose& pose) {
  std::vector<Vec3> out(b.num_input_vertices());
  const auto M = skinning_matrices(b.joints(), pose);
  b.deform(M, out);
  return out;
}

JointPose rotation(double degrees, Vec3 axis) {
  JointPose j;
  j.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(degrees * std::numbers::pi / 180, axis.normalized()));
  return j;
}

struct Variant {
  DeformMethod method;
  LaplacianChoice laplacian;
  RigidMode rigid;
};
const Variant kVariants[] = {{DeformMethod::DualQuaternion, LaplacianChoice::IntrinsicDelaunay, RigidMode::PerVertex},
                             {DeformMethod::DualQuaternion, LaplacianChoice::Uniform, RigidMode::PerVertex},
                             {DeformMethod::Harmonic, LaplacianChoice::IntrinsicDelaunay, RigidMode::PerVertex},
                             {DeformMethod::Harmonic, LaplacianChoice::Uniform, RigidMode::PerVertex},
                             {DeformMethod::Harmonic, LaplacianChoice::IntrinsicDelaunay, RigidMode::Horn},
                             {DeformMethod::Harmonic, LaplacianChoice::Uniform, RigidMode::Horn}};

/// A rigid motion of the whole skeleton moves every vertex rigidly.
void expect_rigid_motion_reproduced(const Binding& b, const SurfaceMesh& m) {
  Pose pose;
  pose["root"] = rotation(37, {1, 2, 0.5});
  pose["root"].translation = {0.3, -1.2, 2.5};
  const auto X = input_positions(m);
  const Mat4 T = skinning_matrices(b.joints(), pose)[0];
  const auto out = deform(b, pose);
  for (size_t i = 0; i < X.size(); ++i)
    ASSERT_LT((out[i] - (T * X[i].homogeneous()).head<3>()).norm(), 1e-9 * m.bbox_diagonal()) << i;
}

/// Skinning matrices of `frames` random poses of the tube net's three joints, frame after frame.
std::vector<Mat4> random_frames(const Binding& b, int frames, unsigned seed, double max_degrees) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> angle(-max_degrees, max_degrees), axis(-1, 1);
  std::vector<Mat4> all;
  for (int f = 0; f < frames; ++f) {
    Pose pose;
    for (const char* j : {"root", "mid", "tip"})
      pose[j] = rotation(angle(rng), {axis(rng), axis(rng), axis(rng) + 1e-3});
    const auto M = skinning_matrices(b.joints(), pose);
    all.insert(all.end(), M.begin(), M.end());
  }
  return all;
}

/// deform_frames gives, bit for bit, each frame deform gives.
void expect_frames_match(const Binding& b, const std::vector<Mat4>& all) {
  const size_t nj = b.joints().size(), nv = static_cast<size_t>(b.num_input_vertices());
  const size_t frames = all.size() / nj;
  std::vector<Vec3> together(frames * nv), one(nv);
  b.deform_frames(all, together);
  for (size_t f = 0; f < frames; ++f) {
    b.deform(std::span<const Mat4>(all).subspan(f * nj, nj), one);
    for (size_t i = 0; i < nv; ++i)
      ASSERT_EQ(together[f * nv + i], one[i]) << "frame " << f << " vertex " << i;
  }
}

BindOptions options(const Variant& v) {
  BindOptions o;
  o.method = v.method;
  o.laplacian = v.laplacian;
  o.rigid = v.rigid;
  return o;
}

} // namespace

TEST(Laplacian, IntrinsicDelaunayReproducesLinearFieldsOnAPlane) {
  // A planar mesh with badly shaped (obtuse) triangles.
  RawMesh raw = test::grid(8, 8, true);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.35, 0.35);
  for (auto& p : raw.positions)
    if (p.x() > 0 && p.x() < 8 && p.y() > 0 && p.y() < 8)
      p += Vec3(jitter(rng), jitter(rng), 0);
  const SurfaceMesh m = make_surface_mesh(raw, "plane");
  std::vector<std::array<int, 3>> tris;
  for (int f = 0; f < m.num_faces(); ++f)
    tris.push_back({m.face(f)[0], m.face(f)[1], m.face(f)[2]});
  detail::LaplacianStats st;
  const auto L = detail::intrinsic_delaunay_laplacian(m.num_vertices(), m.positions, tris, &st);
  std::printf("plane: %d negative cotangent weights before the flips, %d after, %d flips\n", st.negative_before,
              st.negative_after, st.flips);
  EXPECT_GT(st.negative_before, 0);
  EXPECT_EQ(st.negative_after, 0);
  // Boundary values from a linear function; the interior solve must give it back.
  auto f = [](const Vec3& p) { return 0.7 * p.x() - 1.3 * p.y() + 2.0; };
  std::vector<int> idx(m.num_vertices(), -1), interior;
  for (int v = 0; v < m.num_vertices(); ++v) {
    const Vec3& p = m.positions[v];
    if (p.x() > 0 && p.x() < 8 && p.y() > 0 && p.y() < 8) {
      idx[v] = static_cast<int>(interior.size());
      interior.push_back(v);
    }
  }
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(interior.size());
  for (size_t k = 0; k < interior.size(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, interior[k]); it; ++it) {
      const int u = static_cast<int>(it.row());
      if (idx[u] >= 0)
        trip.emplace_back(k, idx[u], it.value());
      else
        rhs[k] -= it.value() * f(m.positions[u]);
    }
  Eigen::SparseMatrix<double> A(interior.size(), interior.size());
  A.setFromTriplets(trip.begin(), trip.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
  const Eigen::VectorXd x = ldlt.solve(rhs);
  for (size_t k = 0; k < interior.size(); ++k)
    EXPECT_NEAR(x[k], f(m.positions[interior[k]]), 1e-10);
}

TEST(Deform, RestPoseReturnsTheInput) {
  const SurfaceMesh m = test::tube(16, 16, 4, false);
  const auto X = input_positions(m);
  const double diag = m.bbox_diagonal();
  for (const Variant& v : kVariants) {
    const Binding b = bind(m, make_tube_net(), options(v));
    const auto out = deform(b, {});
    for (size_t i = 0; i < X.size(); ++i)
      ASSERT_LT((out[i] - X[i]).norm(), 1e-9 * diag) << i;
  }
}

TEST(Deform, TheReportAsJsonHasEveryCountTheStagesInOrderAndTheNotes) {
  const SurfaceMesh m = test::tube(16, 16, 4, false);
  const Binding b = bind(m, make_tube_net());
  const BindReport& r = b.report();
  const auto j = nlohmann::ordered_json::parse(report_to_json(r));
  EXPECT_EQ(j.at("vertices"), r.vertices);
  EXPECT_EQ(j.at("constrained"), r.constrained);
  EXPECT_EQ(j.at("free"), r.free);
  EXPECT_EQ(j.at("rigid"), r.rigid);
  EXPECT_EQ(j.at("influences"), r.influences);
  EXPECT_DOUBLE_EQ(j.at("mean_influences").get<double>(), r.mean_influences);
  EXPECT_EQ(j.at("negative_weights_before"), r.negative_weights_before);
  EXPECT_EQ(j.at("negative_weights_after"), r.negative_weights_after);
  EXPECT_EQ(j.at("negative_weights_solved"), r.negative_weights_solved);
  EXPECT_EQ(j.at("flips"), r.flips);
  ASSERT_FALSE(r.timings_ms.empty());
  ASSERT_EQ(j.at("timings_ms").size(), r.timings_ms.size());
  size_t k = 0;
  for (const auto& [stage, ms] : j.at("timings_ms").items()) {
    EXPECT_EQ(stage, r.timings_ms[k].first);
    EXPECT_DOUBLE_EQ(ms.get<double>(), r.timings_ms[k].second);
    ++k;
  }
  EXPECT_EQ(j.at("notes").get<std::vector<std::string>>(), r.notes);
}

TEST(Deform, ARigidPoseMovesEveryVertexRigidly) {
  const SurfaceMesh m = test::tube(24, 20, 6, true);
  for (const Variant& v : kVariants)
    expect_rigid_motion_reproduced(bind(m, make_tube_net(), options(v)), m);
}

TEST(Deform, OutputIsAlwaysFiniteAndResetsToNeutral) {
  const SurfaceMesh m = test::tube(20, 12, 4, true);
  const Binding b = bind(m, make_tube_net());
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> angle(-170, 170), axis(-1, 1);
  for (int trial = 0; trial < 20; ++trial) {
    Pose pose;
    for (const char* j : {"root", "mid", "tip"})
      pose[j] = rotation(angle(rng), {axis(rng), axis(rng), axis(rng) + 1e-3});
    pose["tip"].scale = {1.5, 0.5, 1};
    for (const auto& p : deform(b, pose))
      ASSERT_TRUE(p.allFinite());
  }
  // After any pose, the rest pose gives the input back: no state is kept.
  const auto X = input_positions(m);
  const auto out = deform(b, {});
  for (size_t i = 0; i < X.size(); ++i)
    ASSERT_LT((out[i] - X[i]).norm(), 1e-9 * m.bbox_diagonal());
}

TEST(Deform, TubeBendsTheSameOnTwoTessellations) {
  // Bend the tube's two joints and look at its far end, the top cap's centre.
  Pose pose;
  pose["mid"] = rotation(40, {0, 0, 1});
  pose["tip"] = rotation(30, {0, 0, 1});
  std::vector<double> angles;
  std::vector<Vec3> tips;
  for (const SurfaceMesh& m : {test::tube(16, 16, 4, false), test::tube(30, 24, 7, true)}) {
    const Binding b = bind(m, make_tube_net());
    const auto out = deform(b, pose);
    const auto X = input_positions(m);
    // The top cap's centre vertex, and the direction of the tube's last quarter.
    size_t top = 0;
    for (size_t i = 0; i < X.size(); ++i)
      if ((X[i] - Vec3(0, 4, 0)).norm() < (X[top] - Vec3(0, 4, 0)).norm())
        top = i;
    size_t ring = 0; // a vertex on the axis side at y = 3: the centre of the ring there
    Vec3 centre3 = Vec3::Zero();
    int count = 0;
    for (size_t i = 0; i < X.size(); ++i)
      if (std::abs(X[i].y() - 3.0) < 1e-9) {
        centre3 += out[i];
        ++count;
        ring = i;
      }
    (void)ring;
    ASSERT_GT(count, 0);
    centre3 /= count;
    const Vec3 dir = (out[top] - centre3).normalized();
    angles.push_back(std::acos(std::clamp(dir.y(), -1.0, 1.0)) * 180 / std::numbers::pi);
    tips.push_back(out[top]);
  }
  std::printf("bend at the tube's end: %.2f and %.2f degrees; tips %.4f apart\n", angles[0], angles[1],
              (tips[0] - tips[1]).norm());
  EXPECT_GT(angles[0], 40.0); // the end turns with both joints
  EXPECT_NEAR(angles[0], angles[1], 2.0);
  EXPECT_LT((tips[0] - tips[1]).norm(), 0.05);
}

TEST(Deform, NoNegativeLaplacianWeightTouchesAVertexSolvedFor) {
  // The capped cylinder of issue 22 (radius 0.5, length 4, 6,000 triangles)
  // with its starter net, and the hand with its hand-drawn net. After the
  // intrinsic flips only boundary edges can keep a negative weight, and on
  // a closed mesh those are the cut's own edges along the curves, between
  // two constrained vertices: none touches a vertex that is solved for, so
  // the maximum principle holds. (A right angle's cotangent, 1e-16, is
  // zero, not negative: the flat quads of a tube once counted 56.)
  TubeSpec ts;
  ts.radius = 0.5;
  ts.length = 4;
  ts.around = 40;
  ts.along = 64;
  ts.cap_rings = 6;
  ts.triangulate = true;
  const SurfaceMesh cylinder = make_surface_mesh(make_capped_tube(ts), "cylinder");
  ASSERT_EQ(cylinder.num_faces(), 6000);
  const Binding c = bind(cylinder, make_starter(cylinder, make_tube_skeleton({0.4, 2.0, 3.6})).rig);
  EXPECT_GT(c.report().negative_weights_before, 0);
  EXPECT_GT(c.report().flips, 0);
  EXPECT_EQ(c.report().negative_weights_solved, 0);
  std::printf("cylinder: %d negative weights before, %d after %d flips, %d at a vertex solved for\n",
              c.report().negative_weights_before, c.report().negative_weights_after, c.report().flips,
              c.report().negative_weights_solved);
  const Binding quads = bind(test::tube(16, 16, 4, false), make_tube_net());
  EXPECT_EQ(quads.report().negative_weights_before, 0); // rectangles: right angles only
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const Binding hand = bind(load_mesh(test::data("xr_tools_hand/hand_l.gltf")),
                            read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json")));
  EXPECT_GT(hand.report().negative_weights_before, 100);
  EXPECT_EQ(hand.report().negative_weights_after, 0);
  EXPECT_EQ(hand.report().negative_weights_solved, 0);
}

TEST(Deform, BindingCacheRoundTrips) {
  const SurfaceMesh m = test::tube(20, 12, 4, true);
  const auto dir = test::temp_dir("cache");
  const std::string path = (dir / "tube.cnbind").string();
  Pose pose;
  pose["mid"] = rotation(50, {0, 0, 1});
  bool reused = true;
  const Binding first = bind_cached(m, make_tube_net(), {}, path, &reused);
  EXPECT_FALSE(reused);
  const Binding second = bind_cached(m, make_tube_net(), {}, path, &reused);
  EXPECT_TRUE(reused);
  EXPECT_FALSE(second.has_embedding());
  const auto a = deform(first, pose), b = deform(second, pose);
  for (size_t i = 0; i < a.size(); ++i)
    ASSERT_EQ(a[i], b[i]);
  // Another rig, or other options, do not reuse it.
  TubeNetSpec other;
  other.first_angle_deg = 10;
  bind_cached(m, make_tube_net(other), {}, path, &reused);
  EXPECT_FALSE(reused);
  BindOptions horn;
  horn.rigid = RigidMode::Horn;
  bind_cached(m, make_tube_net(other), horn, path, &reused);
  EXPECT_FALSE(reused);
}

namespace {

/// The cache's checksum (FNV-1a over all but its last 8 bytes) made to match.
void refix_checksum(std::string& bytes) {
  std::uint64_t h = 1469598103934665603ULL;
  for (size_t i = 0; i + 8 < bytes.size(); ++i)
    h = (h ^ static_cast<unsigned char>(bytes[i])) * 1099511628211ULL;
  std::memcpy(bytes.data() + bytes.size() - 8, &h, 8);
}

} // namespace

TEST(Deform, ADamagedBindingCacheIsRebuilt) {
  // The right fingerprint, but a byte changed in the tables, or the file cut
  // short, or a joint index made out of range with the checksum fixed up to
  // match: each is found and the binding rebuilt, deforming as a fresh one.
  const SurfaceMesh m = test::tube(20, 12, 4, true);
  const auto dir = test::temp_dir("cache_damage");
  const std::string path = (dir / "tube.cnbind").string();
  Pose pose;
  pose["mid"] = rotation(50, {0, 0, 1});
  const Binding fresh = bind_cached(m, make_tube_net(), {}, path);
  const std::string good = test::file_bytes(path);
  auto rewrite = [&](std::string bytes) { std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes; };
  std::string flipped = good;
  flipped[good.size() / 2] ^= 0x5a;
  std::string joint_out_of_range = good;
  {
    // Every int in the joint table set to a huge joint index: find the table
    // by its length (the fourth vector after the header), and patch it.
    size_t at = 8 + 8 + 4 + 8;
    for (int v = 0; v < 3; ++v) { // binds, input_to_welded, offset
      std::uint64_t n = 0;
      std::memcpy(&n, good.data() + at, 8);
      at += 8 + n * (v == 0 ? 8 : 4);
    }
    std::uint64_t n = 0;
    std::memcpy(&n, good.data() + at, 8);
    ASSERT_GT(n, 0u);
    const int huge = 1 << 30;
    std::memcpy(joint_out_of_range.data() + at + 8, &huge, 4);
    refix_checksum(joint_out_of_range);
  }
  for (const std::string& damaged : {flipped, good.substr(0, good.size() / 3), joint_out_of_range}) {
    rewrite(damaged);
    bool reused = true;
    const Binding again = bind_cached(m, make_tube_net(), {}, path, &reused);
    EXPECT_FALSE(reused);
    EXPECT_NE(std::find_if(again.report().notes.begin(), again.report().notes.end(),
                           [](const std::string& n) { return n.find("damaged") != std::string::npos; }),
              again.report().notes.end());
    const auto a = deform(fresh, pose), b = deform(again, pose);
    for (size_t i = 0; i < a.size(); ++i)
      ASSERT_EQ(a[i], b[i]);
  }
}

TEST(Deform, ACraftedBindingCacheWithAValidChecksumIsCheckedOnItsOwn) {
  // A checksum catches accidents, not crafted files: each of the cache's
  // eleven tables emptied in turn, and random bytes changed, with the
  // checksum made to match. An emptied table is found and the binding
  // rebuilt; a changed byte is either found or deforms to finite numbers.
  // (Under the sanitizers this is also the reader's memory-safety test.)
  const SurfaceMesh m = test::tube(12, 8, 4, true);
  const auto dir = test::temp_dir("cache_crafted");
  const std::string path = (dir / "tube.cnbind").string();
  Pose pose;
  pose["mid"] = rotation(50, {0, 0, 1});
  const Binding fresh = bind_cached(m, make_tube_net(), {}, path);
  const std::string good = test::file_bytes(path);
  auto rebind = [&](std::string bytes, bool* reused) {
    refix_checksum(bytes);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    return bind_cached(m, make_tube_net(), {}, path, reused);
  };
  // The tables after the header (magic, fingerprint, mode, tolerance), in
  // the order written, with their element sizes.
  const size_t sizes[] = {8, 4, 4, 4, 8, 24, 24, 24, 4, 4, 8};
  size_t at = 8 + 8 + 4 + 8;
  for (int t = 0; t < 11; ++t) {
    std::uint64_t n = 0;
    std::memcpy(&n, good.data() + at, 8);
    const size_t bytes = n * sizes[t];
    if (n > 0) {
      std::string emptied = good.substr(0, at);
      const std::uint64_t zero = 0;
      emptied.append(reinterpret_cast<const char*>(&zero), 8);
      emptied += good.substr(at + 8 + bytes);
      bool reused = true;
      const Binding again = rebind(emptied, &reused);
      EXPECT_FALSE(reused) << "table " << t;
      const auto a = deform(fresh, pose), b = deform(again, pose);
      for (size_t i = 0; i < a.size(); ++i)
        ASSERT_EQ(a[i], b[i]) << "table " << t;
    }
    at += 8 + bytes;
  }
  ASSERT_EQ(at + 8, good.size()); // every table walked, the checksum last
  std::mt19937 rng(20261202);
  for (int k = 0; k < 200; ++k) {
    std::string changed = good;
    for (int j = 0; j < 1 + k % 4; ++j)
      changed[std::uniform_int_distribution<size_t>(0, good.size() - 9)(rng)] ^=
          static_cast<char>(1 << std::uniform_int_distribution<int>(0, 7)(rng));
    bool reused = false;
    const Binding again = rebind(changed, &reused);
    for (const Vec3& p : deform(again, pose))
      ASSERT_TRUE(p.allFinite()) << "mutation " << k;
  }
}

TEST(Deform, HandClipsFollowTheSkeleton) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string path = test::data("xr_tools_hand/hand_l_poses.glb");
  const SkinnedMesh clips = load_skinned_mesh(path);
  const SurfaceMesh mesh = load_mesh(path);
  const Binding b = bind(mesh, read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json")));
  const RawMesh raw = read_raw_mesh(path);
  const double diag = mesh.bbox_diagonal();
  std::printf("hand bind: %d constrained, %d free, %.2f influences per vertex, %d/%d negative weights before/after\n",
              b.report().constrained, b.report().free, b.report().mean_influences, b.report().negative_weights_before,
              b.report().negative_weights_after);
  double worst_mean = 0;
  for (const char* name : {"Grip", "Pinch", "Peace", "Thumb", "Sign 3"}) {
    const int c = clips.find_clip(name);
    if (c < 0)
      continue;
    const double t = clips.clip_range(c).second;
    std::vector<Vec3> out(b.num_input_vertices());
    b.deform(skinning_matrices(b.joints(), pose_from_clip(clips, c, t)), out);
    const auto lbs = skin_positions(clips, raw.positions, clips.skinning_matrices(c, t));
    double mean = 0;
    for (size_t i = 0; i < out.size(); ++i) {
      ASSERT_TRUE(out[i].allFinite());
      mean += (out[i] - lbs[i]).norm();
    }
    mean /= static_cast<double>(out.size());
    std::printf("clip %-8s: mean distance from the file's own skinning %.3f%% of the diagonal\n", name,
                100 * mean / diag);
    worst_mean = std::max(worst_mean, mean / diag);
  }
  EXPECT_LT(worst_mean, 0.05); // a sanity bound, not a target
}

TEST(Deform, ManyFramesAtOnceAreExactlyTheFramesOneByOne) {
  const SurfaceMesh m = test::tube(20, 12, 4, true);
  const Binding b = bind(m, make_tube_net());
  const size_t nj = b.joints().size(), nv = static_cast<size_t>(b.num_input_vertices());
  const auto all = random_frames(b, 9, 11, 120);
  expect_frames_match(b, all);
  std::vector<Vec3> together(9 * nv), one(nv);
  // Sizes that do not make whole frames are refused, not read past.
  std::vector<Vec3> short_out(nv - 1);
  EXPECT_THROW(b.deform(std::span<const Mat4>(all).first(nj), short_out), Error);
  EXPECT_THROW(b.deform(std::span<const Mat4>(all).first(nj - 1), one), Error);
  EXPECT_THROW(b.deform_frames(std::span<const Mat4>(all).first(nj + 1), together), Error);
  EXPECT_THROW(b.deform_frames(all, std::span<Vec3>(together).first(nv)), Error);
}

// --- the dual-quaternion mode (the default) ---------------------------------

namespace {

/// A limb: a capped cylinder of length 4 and radius 0.5 (about 6k
/// triangles), a 3-joint chain along it, and the starter net on it.
struct Limb {
  SurfaceMesh mesh;
  Rig rig;
};
const Limb& limb() {
  static const Limb l = [] {
    TubeSpec ts;
    ts.radius = 0.5;
    ts.length = 4;
    ts.around = 40;
    ts.along = 64;
    ts.cap_rings = 6;
    ts.triangulate = true;
    Limb out{make_surface_mesh(make_capped_tube(ts), "limb"), {}};
    out.rig = make_starter(out.mesh, make_tube_skeleton({0.4, 2.0, 3.6})).rig;
    return out;
  }();
  return l;
}

BindOptions method(DeformMethod m) {
  BindOptions o;
  o.method = m;
  return o;
}

/// The limb posed with its middle joint turned by `degrees` about `axis`:
/// the volume change, and the smallest section across its bones over rest.
DeformationQuality pose_limb(const BindOptions& o, double degrees, const Vec3& axis) {
  const Limb& l = limb();
  const Binding b = bind(l.mesh, l.rig, o);
  Pose pose;
  pose["j1"] = rotation(degrees, axis);
  const auto M = skinning_matrices(b.joints(), pose);
  const auto posed = l.mesh.welded(deform(b, pose));
  QualityOptions q;
  q.limbs = {{0, 1, 2}};
  const std::vector<int> dominant(l.mesh.num_vertices(), 0);
  return measure_deformation(l.mesh, posed, b.joints(), M, dominant, q);
}

} // namespace

TEST(DualQuaternion, IsTheDefault) {
  EXPECT_EQ(BindOptions{}.method, DeformMethod::DualQuaternion);
  const SurfaceMesh m = test::tube(16, 12, 4, true);
  EXPECT_EQ(bind(m, make_tube_net()).method(), DeformMethod::DualQuaternion);
  DeformMethod parsed = DeformMethod::Harmonic;
  EXPECT_TRUE(parse_deform_method("dq", parsed));
  EXPECT_EQ(parsed, DeformMethod::DualQuaternion);
  EXPECT_FALSE(parse_deform_method("DQ", parsed));
  for (const auto m2 : {DeformMethod::DualQuaternion, DeformMethod::Harmonic, DeformMethod::Gradient})
    EXPECT_TRUE(parse_deform_method(to_string(m2), parsed) && parsed == m2);
}

TEST(DualQuaternion, IsDualQuaternionSkinningWithTheNetsHarmonicWeights) {
  // The definition: each vertex's harmonic weights s_j, as an ordinary skin
  // blended by dual quaternions, give exactly the mode's positions.
  const SurfaceMesh m = test::tube(24, 20, 4, true);
  const Binding b = bind(m, make_tube_net());
  const SkinWeights w = bake_weights(b, 8);
  Pose pose;
  pose["mid"] = rotation(120, {0.2, 0, 1});
  pose["tip"] = rotation(-70, {1, 0.5, 0});
  pose["tip"].scale = {1.2, 0.9, 1};
  const auto M = skinning_matrices(b.joints(), pose);
  const auto ours = deform(b, pose);
  const auto dqs = skin_positions(w, input_positions(m), M, Skinning::DualQuaternion);
  for (size_t i = 0; i < ours.size(); ++i)
    ASSERT_LT((ours[i] - dqs[i]).norm(), 1e-12 * m.bbox_diagonal()) << i;
}

TEST(DualQuaternion, ATwistOf180KeepsTheLimbsSections) {
  const auto dq = pose_limb({}, 180, Vec3::UnitY());
  EXPECT_GE(dq.smallest_section, 0.95);
  EXPECT_LT(std::abs(dq.volume_change), 0.01);
  // The harmonic mode, the default before, blends the joints' matrices and
  // collapses the middle of the limb.
  EXPECT_LT(pose_limb(method(DeformMethod::Harmonic), 180, Vec3::UnitY()).smallest_section, 0.5);
}

TEST(DualQuaternion, ANetWithoutARingAtTheBentJointBendsAsTheCompleteNetsSkin) {
  // The limb's net without its middle ring: the bent joint lies inside one
  // region. Against dual-quaternion skinning with the complete net's baked
  // weights (the skin a rigger would have): its volume within one point,
  // its smallest section within 0.02, and no more bulge. With the harmonic
  // interior the region blends its two rings' joints end to end and the
  // bent joint leaves the surface behind: a lost section or a bulge.
  const Limb& l = limb();
  std::vector<std::string> ring;
  for (const auto& n : l.rig.nodes)
    if (n.id.rfind("j1_", 0) == 0)
      ring.push_back(n.id);
  ASSERT_EQ(ring.size(), 4u);
  const Rig ringless = remove_nodes(l.rig, ring);
  const SkinWeights skin = bake_weights(bind(l.mesh, l.rig), 4);
  const std::vector<Vec3> rest = input_positions(l.mesh);
  QualityOptions q;
  q.limbs = {{0, 1, 2}};
  const std::vector<int> dominant(l.mesh.num_vertices(), 0);
  BindOptions harmonic_inside;
  harmonic_inside.interior = InteriorWeights::Harmonic;
  const Binding ours = bind(l.mesh, ringless), harmonic = bind(l.mesh, ringless, harmonic_inside);
  for (const double degrees : {90.0, 135.0}) {
    Pose pose;
    pose["j1"] = rotation(degrees, Vec3::UnitZ());
    const auto M = skinning_matrices(ours.joints(), pose);
    auto measure = [&](const std::vector<Vec3>& per_input) {
      return measure_deformation(l.mesh, l.mesh.welded(per_input), ours.joints(), M, dominant, q);
    };
    const DeformationQuality dqs = measure(skin_positions(skin, rest, M, Skinning::DualQuaternion));
    const DeformationQuality a = measure(deform(ours, pose)), h = measure(deform(harmonic, pose));
    std::printf("bend %.0f: DQS %+.2f%% %.2f %.2f%%; bone heat %+.2f%% %.2f %.2f%%; harmonic %+.2f%% %.2f %.2f%%\n",
                degrees, 100 * dqs.volume_change, dqs.smallest_section, 100 * dqs.bulge, 100 * a.volume_change,
                a.smallest_section, 100 * a.bulge, 100 * h.volume_change, h.smallest_section, 100 * h.bulge);
    EXPECT_LE(std::abs(a.volume_change), std::abs(dqs.volume_change) + 0.01) << degrees;
    EXPECT_GE(a.smallest_section, dqs.smallest_section - 0.02) << degrees;
    EXPECT_LE(a.bulge, dqs.bulge) << degrees;
    EXPECT_TRUE(h.smallest_section < dqs.smallest_section - 0.02 || h.bulge > dqs.bulge) << degrees;
  }
}

TEST(DualQuaternion, BoneHeatInsideTheRegionsLeavesTheCurvesTheirWeights) {
  // Every vertex of a curve keeps its profile's interpolated weights (the
  // rig format's rule), whatever the inside of the regions does.
  const Limb& l = limb();
  BindOptions harmonic_inside;
  harmonic_inside.interior = InteriorWeights::Harmonic;
  const Binding b = bind(l.mesh, l.rig), h = bind(l.mesh, l.rig, harmonic_inside);
  const auto& emb = b.embedding().impl();
  std::vector<std::pair<int, double>> wb, wh;
  int curve_vertices = 0, inside_differs = 0;
  std::vector<char> on_curve(l.mesh.num_vertices(), 0);
  for (const auto& chain : emb.result.chains)
    for (const auto v : chain.vertices)
      if (v.idx < l.mesh.num_vertices())
        on_curve[v.idx] = 1;
  for (int v = 0; v < l.mesh.num_vertices(); ++v) {
    b.harmonic_weights(v, wb);
    h.harmonic_weights(v, wh);
    double sum = 0;
    for (const auto& [j, x] : wb)
      sum += x;
    EXPECT_NEAR(sum, 1.0, 1e-12) << v;
    if (on_curve[v]) {
      ++curve_vertices;
      EXPECT_EQ(wb, wh) << v;
    } else {
      inside_differs += wb != wh;
    }
  }
  EXPECT_GT(curve_vertices, 100);
  EXPECT_GT(inside_differs, 100); // the inside does change
}

TEST(DualQuaternion, ABendOf135KeepsTheVolumeWithinOnePercent) {
  EXPECT_LT(std::abs(pose_limb({}, 135, Vec3::UnitZ()).volume_change), 0.01);
  EXPECT_GT(std::abs(pose_limb(method(DeformMethod::Harmonic), 135, Vec3::UnitZ()).volume_change), 0.1);
}

TEST(DualQuaternion, TheHandDrawnHandNetMakesAFistNoWorseThanItsSkin) {
  // The example rig has no rings at the finger bases: the fingers' first
  // bones bend inside one region. The Grip clip's fist, through the net,
  // against the file's own skin on the same pose: no more self-intersecting
  // triangle pairs than its linear blend skin, and a volume change within
  // its dual-quaternion skin's plus one and a half points. The net gains
  // volume where DQS loses it: its palm ring follows the first finger
  // bones (the rig's weights), which domes the back of the hand by about
  // 10 % of the hand's volume. The harmonic interior hid part of that
  // under a collapse of the thumb's base, which bone heat inside the
  // regions keeps (about 2.5 points of the hand's volume), so its total was
  // nearer (+4.7 % against +5.1 %); the bound is not tightened to that
  // cancellation.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string path = test::data("xr_tools_hand/hand_l.gltf");
  const SurfaceMesh mesh = load_mesh(path);
  const SkinnedMesh skin = load_skinned_mesh(path);
  const SkinnedMesh clips = load_skinned_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  const RawMesh raw = read_raw_mesh(path);
  const int grip = clips.find_clip("Grip");
  ASSERT_GE(grip, 0);
  const double t = clips.clip_range(grip).second;
  const double v0 = mesh.enclosed_volume(mesh.positions);
  auto score = [&](const std::vector<Vec3>& per_input) {
    const auto w = mesh.welded(per_input);
    return std::pair{mesh.enclosed_volume(w) / v0 - 1, self_intersecting_pairs(mesh, w)};
  };
  const auto Ms = clip_skinning_matrices(skin.joints, clips, grip, t);
  const auto [lbs_volume, lbs_pairs] = score(skin_positions(skin, raw.positions, Ms, Skinning::Linear));
  const auto [dqs_volume, dqs_pairs] = score(skin_positions(skin, raw.positions, Ms, Skinning::DualQuaternion));
  const Rig rig = read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json"));
  auto ours = [&](const BindOptions& o) {
    const Binding b = bind(mesh, rig, o);
    std::vector<Vec3> out(b.num_input_vertices());
    b.deform(clip_skinning_matrices(b.joints(), clips, grip, t), out);
    return score(out);
  };
  const auto [volume, pairs] = ours({});
  std::printf("Grip fist: LBS %+.2f%% (%d pairs), DQS %+.2f%% (%d), dq %+.2f%% (%d)\n", 100 * lbs_volume, lbs_pairs,
              100 * dqs_volume, dqs_pairs, 100 * volume, pairs);
  EXPECT_LE(pairs, lbs_pairs);
  EXPECT_LE(std::abs(volume), std::abs(dqs_volume) + 0.015);
  // The harmonic mode loses a fifth of the hand's volume here.
  EXPECT_GT(std::abs(ours(method(DeformMethod::Harmonic)).first), std::abs(dqs_volume) + 0.015);
}

TEST(DualQuaternion, TheHandPosesTheSameOnItsRefinement) {
  // The rig drives any tessellation of the character. Split every triangle
  // of the hand into three quads (the same surface, the original vertices first) and
  // pose the Grip fist on both: each original vertex lands where it did on
  // the hand itself. A blend whose hemisphere hung on the order the joints
  // came in sent a knuckle 13 % of the diagonal away on one of the two.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SurfaceMesh mesh = load_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  const SurfaceMesh refined = midpoint_subdivide(mesh, 1);
  const Rig rig = read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json"));
  const SkinnedMesh clips = load_skinned_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  const int grip = clips.find_clip("Grip");
  ASSERT_GE(grip, 0);
  const double t = clips.clip_range(grip).second;
  auto posed = [&](const SurfaceMesh& m) {
    const Binding b = bind(m, rig);
    std::vector<Vec3> out(b.num_input_vertices());
    b.deform(clip_skinning_matrices(b.joints(), clips, grip, t), out);
    return m.welded(out);
  };
  const auto a = posed(mesh), b = posed(refined);
  double worst = 0, sum = 0;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    const double d = (a[v] - b[v]).norm();
    worst = std::max(worst, d);
    sum += d;
  }
  const double diagonal = mesh.bbox_diagonal();
  std::printf("Grip on the hand and on its refinement: mean %.3f%%, max %.3f%% of the diagonal\n",
              100 * sum / mesh.num_vertices() / diagonal, 100 * worst / diagonal);
  EXPECT_LT(worst, 0.01 * diagonal);
  EXPECT_LT(sum / mesh.num_vertices(), 0.001 * diagonal);
}

TEST(DualQuaternion, TheBindDoesNotDependOnTheThreadCount) {
  // Bone heat runs beside the embedding and the harmonic factor, and its
  // rays in parallel: the tables come out the same on one thread and on two.
  const SurfaceMesh m = test::tube(64, 60, 8, true);
  auto tables = [&](int threads) {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    return bind(m, make_tube_net()).cache_bytes("tube.cache");
  };
  const std::string one = tables(1), two = tables(2);
  EXPECT_GT(one.size(), 1000u);
  EXPECT_TRUE(one == two);
}

TEST(DualQuaternion, FramesDoNotDependOnTheThreadCount) {
  const SurfaceMesh m = test::tube(64, 60, 8, true); // large enough for several blocks of vertices
  const Binding b = bind(m, make_tube_net());
  const auto all = random_frames(b, 6, 5, 150);
  const size_t nv = static_cast<size_t>(b.num_input_vertices());
  std::vector<Vec3> one(all.size() / 3 * nv), four(one.size());
  tbb::task_arena(1).execute([&] { b.deform_frames(all, one); });
  tbb::task_arena(4).execute([&] { b.deform_frames(all, four); });
  for (size_t i = 0; i < one.size(); ++i)
    ASSERT_EQ(one[i], four[i]) << i;
  expect_frames_match(b, all);
}

// --- the gradient mode -------------------------------------------------------

namespace {
BindOptions gradient(bool cut_aware = true) {
  BindOptions o;
  o.method = DeformMethod::Gradient;
  o.cut_aware = cut_aware;
  return o;
}
} // namespace

TEST(Gradient, TheNearestRotationOfABlendOfTwoRotationsIsTheirGeodesicMidpoint) {
  for (double deg : {10.0, 90.0, 150.0, 179.0}) {
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(deg * std::numbers::pi / 180, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    const Eigen::Matrix3d blend = 0.5 * (Eigen::Matrix3d::Identity() + R); // the linear blend shrinks
    const Eigen::Matrix3d half = detail::nearest_rotation(blend);
    EXPECT_NEAR(half.determinant(), 1, 1e-12) << deg;
    EXPECT_LT((half * half.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12) << deg;
    const Eigen::Matrix3d want =
        Eigen::AngleAxisd(deg / 2 * std::numbers::pi / 180, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    EXPECT_LT((half - want).norm(), 1e-9) << deg;
  }
}

TEST(Gradient, RestAndRigidMotionsAreReproducedExactly) {
  const SurfaceMesh m = test::tube(24, 20, 4, true);
  const auto X = input_positions(m);
  const double diag = m.bbox_diagonal();
  for (auto blend : {BindOptions::RotationBlend::Polar, BindOptions::RotationBlend::Quaternion}) {
    BindOptions o = gradient();
    o.rotation_blend = blend;
    const Binding b = bind(m, make_tube_net(), o);
    EXPECT_EQ(b.method(), DeformMethod::Gradient);
    const auto rest = deform(b, {});
    for (size_t i = 0; i < X.size(); ++i)
      ASSERT_LT((rest[i] - X[i]).norm(), 1e-9 * diag) << i;
    expect_rigid_motion_reproduced(b, m);
  }
}

TEST(Gradient, AConstantGradientIsReproduced) {
  // Every joint moved by the same affine map (rotation, non-uniform scale,
  // translation): the interpolated gradient is that map's everywhere, and
  // the surface is the map applied to the rest surface.
  const SurfaceMesh m = test::tube(20, 16, 4, true);
  const Binding b = bind(m, make_tube_net(), gradient());
  Eigen::Affine3d G = Eigen::Affine3d::Identity();
  G.translate(Vec3(0.4, -0.2, 1.0));
  G.rotate(Eigen::AngleAxisd(0.7, Vec3(0.3, 1, -0.2).normalized()));
  G.scale(Vec3(1.3, 0.8, 1.1));
  const std::vector<Mat4> M(b.joints().size(), G.matrix());
  std::vector<Vec3> out(b.num_input_vertices());
  b.deform(M, out);
  const auto X = input_positions(m);
  for (size_t i = 0; i < X.size(); ++i)
    ASSERT_LT((out[i] - G * X[i]).norm(), 1e-9 * m.bbox_diagonal()) << i;
}

TEST(Gradient, ABentTubeKeepsItsVolumeBetterThanTheHarmonicMode) {
  const SurfaceMesh m = test::tube(32, 40, 5, true);
  Pose pose;
  pose["mid"] = rotation(90, {0, 0, 1});
  const double v0 = m.enclosed_volume(m.positions);
  BindOptions h;
  h.method = DeformMethod::Harmonic;
  const double harmonic = m.enclosed_volume(m.welded(deform(bind(m, make_tube_net(), h), pose))) / v0 - 1;
  const double grad = m.enclosed_volume(m.welded(deform(bind(m, make_tube_net(), gradient()), pose))) / v0 - 1;
  EXPECT_LT(std::abs(grad), 0.05);
  EXPECT_LT(std::abs(grad), 0.5 * std::abs(harmonic)) << "gradient " << grad << ", harmonic " << harmonic;
}

TEST(Gradient, TargetsThatTurnWithTheSectionsKeepATwistOf180) {
  // Per-face rotations alone make a waist where the twist is spread, since
  // the surface lines of a twisted limb are longer helices; turning each
  // face's offset from its bone with the blend keeps the sections.
  BindOptions o = gradient();
  EXPECT_TRUE(o.sections);
  const auto with = pose_limb(o, 180, Vec3::UnitY());
  EXPECT_GE(with.smallest_section, 0.95);
  EXPECT_LT(std::abs(with.volume_change), 0.01);
  o.sections = false;
  const auto without = pose_limb(o, 180, Vec3::UnitY());
  EXPECT_LT(without.smallest_section, 0.85);
  EXPECT_GT(std::abs(without.volume_change), 0.03);
}

TEST(Gradient, TwoSidesGivenDifferentScalesMakeACreaseOnlyWithTheCutAwareDiscretisation) {
  // The middle ring's four profiles: their upper side widened, their lower side narrowed.
  const SurfaceMesh m = test::tube(32, 48, 5, true);
  Rig rig = make_tube_net();
  std::string scales = "{";
  for (const auto& p : rig.profiles)
    if (p.id.rfind("ring1", 0) == 0)
      scales += std::string(scales.size() > 1 ? "," : "") + "\"" + p.id + "\": [1.6, 0.6]";
  scales += "}";
  ASSERT_GT(scales.size(), 2u) << "the tube net names its middle ring ring1_*";
  rig.extensions["x_side_scales"] = scales;
  // Per row of side vertices (by rest height): the mean deformed radius.
  auto radius_profile = [&](const BindOptions& o) {
    const Binding b = bind(m, rig, o);
    const auto out = deform(b, {});
    std::map<long, std::pair<double, int>> rows;
    const auto X = input_positions(m);
    for (size_t i = 0; i < X.size(); ++i) {
      const double r = std::hypot(X[i].x(), X[i].z());
      if (std::abs(r - 1) > 1e-9 || X[i].y() <= 0.01 || X[i].y() >= 3.99)
        continue;
      auto& row = rows[std::lround(X[i].y() * 1e6)];
      row.first += std::hypot(out[i].x(), out[i].z());
      ++row.second;
    }
    std::vector<std::pair<double, double>> profile; // (rest height, mean deformed radius)
    for (const auto& [y, rr] : rows)
      profile.emplace_back(y * 1e-6, rr.first / rr.second);
    return profile;
  };
  const double ring = 2.1; // the middle ring's height (TubeNetSpec)
  // Each side's mean change of radius, between the middle ring and the next ring up, or down.
  auto side_change = [&](const std::vector<std::pair<double, double>>& p, bool above) {
    double sum = 0;
    int n = 0;
    for (const auto& [y, r] : p)
      if (above ? (y > ring && y < 3.4) : (y < ring && y > 0.6)) {
        sum += r - 1;
        ++n;
      }
    return sum / std::max(n, 1);
  };
  // The crease: the largest change of the radius's slope at the ring, against elsewhere.
  auto kinks = [&](const std::vector<std::pair<double, double>>& p) {
    double at_ring = 0, elsewhere = 0;
    for (size_t k = 1; k + 1 < p.size(); ++k) {
      const double s0 = (p[k].second - p[k - 1].second) / (p[k].first - p[k - 1].first);
      const double s1 = (p[k + 1].second - p[k].second) / (p[k + 1].first - p[k].first);
      const double kink = std::abs(s1 - s0);
      if (std::abs(p[k].first - ring) < 0.1)
        at_ring = std::max(at_ring, kink);
      else if (std::abs(p[k].first - ring) > 0.4 && std::abs(p[k].first - 0.6) > 0.4 &&
               std::abs(p[k].first - 3.4) > 0.4)
        elsewhere = std::max(elsewhere, kink);
    }
    return std::pair{at_ring, elsewhere};
  };
  const auto aware = radius_profile(gradient(true)), plain = radius_profile(gradient(false));
  // The scales are 1.6 on one side and 0.6 on the other (which is which
  // follows the ring's direction): with the cut-aware discretisation one
  // side swells and the other narrows. Without it both see the average at
  // the ring, and both swell alike.
  const double aware_up = side_change(aware, true), aware_down = side_change(aware, false);
  const double plain_up = side_change(plain, true), plain_down = side_change(plain, false);
  EXPECT_LT(aware_up * aware_down, 0) << "opposite ways: " << aware_up << ", " << aware_down;
  EXPECT_GT(std::min(std::abs(aware_up), std::abs(aware_down)), 0.004);
  EXPECT_GE(plain_up, 0) << "without: " << plain_up;
  EXPECT_GE(plain_down, 0) << "without: " << plain_down;
  EXPECT_GT(std::abs(aware_up - aware_down), 5 * std::abs(plain_up - plain_down));
  const auto [at_ring, elsewhere] = kinks(aware);
  EXPECT_GT(at_ring, 3 * elsewhere) << "a crease along the ring";
}

TEST(Gradient, ABindingInTheGradientModeIsNotCached) {
  const SurfaceMesh m = test::tube(12, 8, 3, true);
  const Binding b = bind(m, make_tube_net(), gradient());
  EXPECT_THROW(b.save(::testing::TempDir() + "g.cnbind"), Error);
  EXPECT_THROW(bind_cached(m, make_tube_net(), gradient(), ::testing::TempDir() + "g.cnbind"), InputError);
}

TEST(Gradient, TheExampleFistFoldsNoTriangle) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const std::string ex = test::data("xr_tools_hand/example/");
  const SurfaceMesh m = load_mesh(ex + "hand_l_welded.obj");
  const Binding b = bind(m, read_rig(ex + "hand_l.cnrig.json"), gradient());
  const auto M = skinning_matrices(b.joints(), read_pose(ex + "fist.pose.json"));
  std::vector<Vec3> out(b.num_input_vertices());
  b.deform(M, out);
  std::vector<Vec3> p(m.num_vertices());
  for (size_t i = 0; i < out.size(); ++i)
    p[m.input_to_welded[i]] = out[i];
  // Each triangle against its rest normal carried by its first vertex's strongest joint.
  std::vector<std::pair<int, double>> s;
  int folded = 0, shrunk = 0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const auto t = m.face(f);
    const Vec3 n = (p[t[1]] - p[t[0]]).cross(p[t[2]] - p[t[0]]);
    const Vec3 r = (m.positions[t[1]] - m.positions[t[0]]).cross(m.positions[t[2]] - m.positions[t[0]]);
    int vi = 0;
    while (m.input_to_welded[vi] != t[0])
      ++vi;
    b.harmonic_weights(vi, s);
    const auto strongest = *std::max_element(s.begin(), s.end(), [](auto& a, auto& c) { return a.second < c.second; });
    const Vec3 expect = M[strongest.first].topLeftCorner<3, 3>() * r;
    folded += n.normalized().dot(expect.normalized()) < std::cos(120 * std::numbers::pi / 180);
    shrunk += n.norm() < 0.1 * r.norm();
  }
  EXPECT_EQ(folded, 0);
  EXPECT_EQ(shrunk, 0);
}

TEST(Gradient, CurveFramesKeepTheExactCasesAndFollowAPosedCurve) {
  const SurfaceMesh m = test::tube(24, 20, 4, true);
  BindOptions o = gradient();
  o.curve_frames = true;
  const Binding b = bind(m, make_tube_net(), o);
  const auto X = input_positions(m);
  const double diag = m.bbox_diagonal();
  const auto rest = deform(b, {});
  for (size_t i = 0; i < X.size(); ++i)
    ASSERT_LT((rest[i] - X[i]).norm(), 1e-9 * diag) << i;
  Eigen::Affine3d G = Eigen::Affine3d::Identity();
  G.rotate(Eigen::AngleAxisd(0.4, Vec3(0, 1, 0)));
  G.scale(Vec3(1.2, 0.9, 1.0));
  std::vector<Vec3> out(b.num_input_vertices());
  b.deform(std::vector<Mat4>(b.joints().size(), G.matrix()), out);
  for (size_t i = 0; i < X.size(); ++i)
    ASSERT_LT((out[i] - G * X[i]).norm(), 1e-9 * diag) << i;
  // In a bend the curves turn past their joints: the frames follow, and the result differs from joints' frames only.
  Pose pose;
  pose["mid"] = rotation(80, {0, 0, 1});
  const auto with_frames = deform(b, pose), joints_only = deform(bind(m, make_tube_net(), gradient()), pose);
  double diff = 0;
  for (size_t i = 0; i < X.size(); ++i) {
    ASSERT_TRUE(with_frames[i].allFinite());
    diff = std::max(diff, (with_frames[i] - joints_only[i]).norm());
  }
  EXPECT_GT(diff, 1e-4 * diag);
}

TEST(Gradient, ManyFramesAtOnceAreExactlyTheFramesOneByOne) {
  // Frames run in parallel, and each frame's faces too: no frame may see
  // another's scratch (a scratch shared between threads fails this). Enough
  // faces for many parallel chunks per frame, on four threads.
  tbb::task_arena arena(4);
  arena.execute([] {
    const SurfaceMesh m = test::tube(120, 160, 5, true);
    const Binding b = bind(m, make_tube_net(), gradient());
    expect_frames_match(b, random_frames(b, 16, 5, 100));
  });
}

TEST(Gradient, MalformedSideScalesAreRefusedNamingTheirPath) {
  const SurfaceMesh m = test::tube(12, 8, 3, true);
  const Rig base = make_tube_net();
  const std::string first = base.profiles.front().id;
  for (const auto& [text, path] : std::vector<std::pair<std::string, std::string>>{
           {"[1, 2]", "/x_side_scales"},
           {"{\"" + first + "\": [1]}", "/x_side_scales/" + first},
           {"{\"" + first + "\": [1, -2]}", "/x_side_scales/" + first},
           {"{\"" + first + "\": [1, 1e9]}", "/x_side_scales/" + first},
           {"{\"no_such_profile\": [1, 1]}", "/x_side_scales/no_such_profile"}}) {
    Rig rig = base;
    rig.extensions["x_side_scales"] = text;
    try {
      (void)bind(m, rig, gradient());
      ADD_FAILURE() << text << " was accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(e.element(), path) << text;
    }
    // The harmonic mode does not read them.
    EXPECT_NO_THROW((void)bind(m, rig));
  }
}

// ---- bone heat (bind/bone_heat.hpp) ----------------------------------------

namespace {

/// Bone heat on a welded mesh with a skeleton, every joint taking part.
detail::BoneHeat heat_on(const SurfaceMesh& m, const std::vector<Joint>& joints) {
  const detail::CutMesh cut = detail::CutMesh::from_surface(m);
  const detail::TraceMesh tm(m, cut);
  const auto L = detail::cut_mesh_laplacian(cut, detail::LaplacianKind::IntrinsicDelaunay);
  detail::BoneHeatInput in;
  in.cut = &cut;
  in.laplacian = &L;
  in.surface = &tm;
  in.joints = &joints;
  in.deforming.assign(joints.size(), 1);
  return detail::bone_heat(in);
}

} // namespace

TEST(BoneHeat, IsAPartitionOfUnityRigidInTheMiddleOfABoneAndHalvedAtItsJoint) {
  // A slender limb (bones 1.6 long, radius 0.25): heat spreads about as far
  // as the surface lies from its bone, so the middle of a bone is its own.
  TubeSpec ts;
  ts.radius = 0.25;
  ts.around = 32;
  ts.along = 64;
  ts.triangulate = true;
  const SurfaceMesh m = make_surface_mesh(make_capped_tube(ts), "slender tube");
  const auto joints = make_tube_skeleton({0.4, 2.0, 3.6}); // j0 -> j1 -> j2 along y
  const detail::BoneHeat h = heat_on(m, joints);
  EXPECT_EQ(h.blind, 0);
  for (int v = 0; v < m.num_vertices(); ++v) {
    double sum = 0;
    for (const auto& w : h.weight)
      if (w.size() > 0) {
        EXPECT_GE(w[v], 0);
        sum += w[v];
      }
    EXPECT_NEAR(sum, 1.0, 1e-12) << v;
    const double y = m.positions[v].y();
    if (std::abs(y - 1.0) < 0.05) // the middle of j0's bone
      EXPECT_GT(h.weight[0][v], 0.9) << y;
    if (std::abs(y - 2.0) < 0.02) // at j1: half and half
      EXPECT_NEAR(h.weight[0][v], 0.5, 0.1) << y;
    // The weight rule is the source: inside the blend zone about a joint
    // (30 % of the bone each side) the next joint already has a third, and
    // near the last joint it shares that bone (a bone's own joint alone, as
    // Pinocchio's sources give it, leaves a fifth and a sixth there).
    if (std::abs(y - 1.8) < 0.02)
      EXPECT_GT(h.weight[1][v], 0.3) << y;
    if (std::abs(y - 3.5) < 0.02)
      EXPECT_GT(h.weight[2][v], 0.3) << y;
    if (y > 3.7) // past the last joint: j1's bone runs to it, j2 takes what lies beyond
      EXPECT_LT(h.weight[0][v], 0.05) << y;
  }
}

TEST(BoneHeat, DoesNotDependOnTheModelsScale) {
  const SurfaceMesh m = test::tube(16, 24, 3, true);
  const auto joints = make_tube_skeleton({0.4, 2.0, 3.6});
  const double k = 1000;
  SurfaceMesh big = m;
  for (auto& p : big.positions)
    p *= k;
  auto big_joints = joints;
  for (auto& j : big_joints)
    j.bind.block<3, 1>(0, 3) *= k;
  const detail::BoneHeat a = heat_on(m, joints), b = heat_on(big, big_joints);
  for (size_t j = 0; j < joints.size(); ++j)
    for (int v = 0; v < m.num_vertices(); ++v)
      ASSERT_NEAR(a.weight[j][v], b.weight[j][v], 1e-9) << j << " " << v;
}

TEST(BoneHeat, AVertexTakesHeatFromTheBonesItSeesNotFromANearerOneBehindAnotherSurface) {
  // A thick limb (radius 1) with a thin one (radius 0.2) alongside it, a
  // gap of 0.1 between them (a finger against the palm), each with a bone
  // along its axis. Where the thick limb faces the thin one, the thin
  // limb's bone is three times nearer than its own, but behind the thin
  // limb's surface: the heat comes from its own bone.
  TubeSpec thick, thin;
  thick.radius = 1.0;
  thick.around = 64;
  thick.along = 24;
  thick.triangulate = true;
  thin = thick;
  thin.radius = 0.2;
  thin.around = 16;
  RawMesh a = make_capped_tube(thick);
  const RawMesh b = make_capped_tube(thin);
  const Vec3 shift(1.3, 0, 0);
  const int base = static_cast<int>(a.positions.size());
  for (const auto& p : b.positions)
    a.positions.push_back(p + shift);
  for (size_t f = 0; f + 1 < b.face_offsets.size(); ++f) {
    for (int k = b.face_offsets[f]; k < b.face_offsets[f + 1]; ++k)
      a.face_vertices.push_back(b.face_vertices[k] + base);
    a.face_offsets.push_back(static_cast<int>(a.face_vertices.size()));
  }
  const SurfaceMesh m = make_surface_mesh(a, "two limbs");
  // j0 -> j1 along the thick limb's axis, j2 -> j3 along the thin one's.
  std::vector<Joint> joints(4);
  for (int k = 0; k < 4; ++k) {
    joints[k].name = "j" + std::to_string(k);
    joints[k].bind.block<3, 1>(0, 3) = Vec3(k < 2 ? 0.0 : 1.3, k % 2 == 0 ? 0.5 : 3.5, 0);
  }
  joints[1].parent = "j0";
  joints[3].parent = "j2";
  const detail::BoneHeat h = heat_on(m, joints);
  int facing = 0;
  for (int v = 0; v < m.num_vertices(); ++v) {
    const Vec3& p = m.positions[v];
    if (p.y() < 1.5 || p.y() > 2.5)
      continue;
    const bool thick_limb = v < base;
    const double other = thick_limb ? h.weight[2][v] + h.weight[3][v] : h.weight[0][v] + h.weight[1][v];
    EXPECT_EQ(other, 0) << v << " at " << p.transpose();
    facing += thick_limb && p.x() > 0.95;
  }
  EXPECT_GT(facing, 0);
}
