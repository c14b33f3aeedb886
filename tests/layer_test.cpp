// The layer (layer.hpp): over the mesh's own skin, envelope 0 and mask 0
// are the skin exactly, and envelope 1 puts the chains on the posed
// curves; over the net's own deformation, a node's offset moves the
// regions its profiles bound, and nothing beyond.

#include "curvenet/layer.hpp"

#include "bind/constraints.hpp"
#include "bind/laplacian.hpp"
#include "core/dual_quaternion.hpp"
#include "curvenet/compare.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/jobs.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/subdivide.hpp"
#include "curvenet/transfer.hpp"
#include "embed/embedding_impl.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>

using namespace curvenet;

namespace {

struct Hand {
  SurfaceMesh mesh = load_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  SkinnedMesh skin = load_skinned_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  Rig rig = read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json"));
  SkinnedMesh clips = load_skinned_mesh(test::data("xr_tools_hand/hand_l_poses.glb"));
  std::vector<Vec3> rest() const {
    std::vector<Vec3> r;
    for (int w : mesh.input_to_welded)
      r.push_back(mesh.positions[w]);
    return r;
  }
};

/// The tube net over the net's own deformation (no skin), on a capped tube,
/// with node 0 of its middle ring pulled outwards by 2 % of the diagonal.
struct PulledTube {
  SurfaceMesh mesh = make_surface_mesh(make_capped_tube([] {
                                         TubeSpec spec;
                                         spec.around = 32;
                                         spec.along = 40;
                                         spec.cap_rings = 8;
                                         return spec;
                                       }()),
                                       "tube");
  Rig rig = make_tube_net();
  CurveLayer layer = bind_layer(mesh, rig, nullptr);
  double diag = mesh.bbox_diagonal();
  Vec3 node = rig.nodes[rig.node_index("ring1_0")].position;
  NodeOffsets pull{{"ring1_0", 0.02 * diag* Vec3(node.x(), 0, node.z()).normalized()}};
};

/// The binding's chain constraints (`rig` with the binding's skeleton).
detail::ChainConstraints constraints_of(const Binding& b, Rig rig) {
  std::map<std::string, int> joint_index;
  for (size_t j = 0; j < b.joints().size(); ++j)
    joint_index[b.joints()[j].name] = static_cast<int>(j);
  rig.weights = b.node_weights();
  return detail::chain_constraints(b.embedding().impl(), rig, joint_index);
}

/// Per cut-mesh vertex on a chain, where its chain weights, blended as dual
/// quaternions, take its rest position: the posed curve; nothing elsewhere.
std::vector<std::optional<Vec3>> posed_curves(const Binding& b, const Rig& rig, std::span<const Mat4> M) {
  const detail::ChainConstraints cc = constraints_of(b, rig);
  std::vector<detail::DualJoint> dj;
  for (const Mat4& m : M)
    dj.push_back(detail::split_joint(m));
  std::vector<std::optional<Vec3>> out(cc.constrained.size());
  for (size_t v = 0; v < out.size(); ++v) {
    if (!cc.constrained[v])
      continue;
    detail::DualBlend blend;
    for (const auto& [j, w] : cc.cw[v])
      blend.add(dj[j], w);
    out[v] = blend.apply(b.embedding().impl().cut.position(detail::Vertex(static_cast<int>(v))));
  }
  return out;
}

double max_apart(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  double d = 0;
  for (size_t i = 0; i < a.size(); ++i)
    d = std::max(d, (a[i] - b[i]).norm());
  return d;
}

} // namespace

TEST(Layer, EnvelopeZeroAndMaskZeroAreTheSkinExactly) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  Hand h;
  h.rig = with_skeleton(h.rig, h.skin.joints, "skin"); // what bind_layer does over a skin
  const double diag = h.mesh.bbox_diagonal();
  const int grip = h.clips.find_clip("Grip");
  // The skin computed on its own: its joints' matrices from the clip, its weights.
  const std::vector<Mat4> skin_M = clip_skinning_matrices(h.skin.joints, h.clips, grip, 1 / 24.0);
  for (const Skinning method : {Skinning::Linear, Skinning::DualQuaternion}) {
    LayerOptions opt;
    opt.skinning = method;
    const CurveLayer layer = bind_layer(h.mesh, h.rig, &h.skin, opt);
    const std::vector<Mat4> M = clip_skinning_matrices(layer.joints(), h.clips, grip, 1 / 24.0);
    const std::vector<Vec3> skin = skin_positions(h.skin, h.rest(), skin_M, method);
    std::vector<Vec3> out(layer.num_input_vertices());
    layer.deform(M, out, 0.0);
    EXPECT_LT(max_apart(out, skin), 1e-12 * diag);
    // The correction is real: with envelope 1 the mesh moves.
    layer.deform(M, out, 1.0);
    EXPECT_GT(max_apart(out, skin), 1e-3 * diag);
    // Masked: the vertices masked out are the skin exactly, the others move.
    LayerOptions half = opt;
    half.mask.assign(out.size(), 1.0);
    for (size_t i = 0; i < out.size(); i += 2)
      half.mask[i] = 0;
    const CurveLayer masked = bind_layer(h.mesh, h.rig, &h.skin, half);
    masked.deform(M, out, 1.0);
    double masked_apart = 0, open_apart = 0;
    for (size_t i = 0; i < out.size(); ++i)
      (i % 2 ? open_apart : masked_apart) = std::max(i % 2 ? open_apart : masked_apart, (out[i] - skin[i]).norm());
    EXPECT_LT(masked_apart, 1e-12 * diag);
    EXPECT_GT(open_apart, 1e-3 * diag);
  }
}

TEST(Layer, WithEnvelopeOneTheChainsLieOnThePosedCurvesAndRestIsRest) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const Hand h;
  const double diag = h.mesh.bbox_diagonal();
  const CurveLayer layer = bind_layer(h.mesh, h.rig, &h.skin);
  const Binding& b = layer.binding();
  const std::vector<Mat4> M = clip_skinning_matrices(b.joints(), h.clips, h.clips.find_clip("Grip"), 1 / 24.0);
  std::vector<Vec3> cut, skin_cut;
  layer.deform_cut(M, cut);
  layer.deform_cut(M, skin_cut, 0.0);
  // And by the binding's own constraints: each chain vertex's weights,
  // blended as dual quaternions.
  const auto curves = posed_curves(b, with_skeleton(h.rig, h.skin.joints, "skin"), M);
  double on = 0, skin_off = 0;
  int checked = 0;
  for (size_t v = 0; v < cut.size(); ++v) {
    if (!curves[v])
      continue;
    on = std::max(on, (cut[v] - *curves[v]).norm());
    skin_off = std::max(skin_off, (skin_cut[v] - *curves[v]).norm());
    ++checked;
  }
  EXPECT_GT(checked, 1000);
  EXPECT_LT(on, 1e-12 * diag) << "the layered chains are on the posed curves";
  EXPECT_GT(skin_off, 1e-3 * diag) << "the skin alone does not put them there";
  // At rest, the skin, the curves and so the layer are the rest.
  const std::vector<Mat4> I(b.joints().size(), Mat4::Identity());
  std::vector<Vec3> out(layer.num_input_vertices());
  layer.deform(I, out);
  EXPECT_LT(max_apart(out, h.rest()), 1e-12 * diag);
}

TEST(Layer, TheCorrectionIsHarmonicOffTheChainsAndTheSameOnAnyThreadCount) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const Hand h;
  const CurveLayer layer = bind_layer(h.mesh, h.rig, &h.skin);
  const Binding& b = layer.binding();
  const std::vector<Mat4> M = clip_skinning_matrices(b.joints(), h.clips, h.clips.find_clip("Grip"), 1 / 24.0);
  std::vector<Vec3> cut, base, cut_two;
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    layer.deform_cut(M, cut);
  }
  {
    tbb::global_control two(tbb::global_control::max_allowed_parallelism, 2);
    layer.deform_cut(M, cut_two);
    layer.deform_cut(M, base, 0.0);
  }
  EXPECT_EQ(cut, cut_two) << "a frame is the same on one thread and on two";
  // Each region is solved on its own: the correction still satisfies the
  // whole cut mesh's Laplace equation at every vertex off the chains that
  // a chain reaches, and it is not zero.
  const Embedding::Impl& emb = b.embedding().impl();
  const detail::ChainConstraints cc = constraints_of(b, with_skeleton(h.rig, h.skin.joints, "skin"));
  const Eigen::SparseMatrix<double> lap = detail::cut_mesh_laplacian(emb.cut, detail::LaplacianKind::IntrinsicDelaunay);
  double worst = 0, largest = 0, scale = 0;
  int free = 0;
  for (int v = 0; v < lap.outerSize(); ++v) {
    largest = std::max(largest, (cut[v] - base[v]).norm());
    if (cc.constrained[v])
      continue;
    Vec3 r = Vec3::Zero();
    double diag_entry = 0;
    for (Eigen::SparseMatrix<double>::InnerIterator it(lap, v); it; ++it) {
      r += it.value() * (cut[it.row()] - base[it.row()]);
      diag_entry = std::max(diag_entry, std::abs(it.value()));
    }
    worst = std::max(worst, r.norm() / diag_entry);
    ++free;
  }
  scale = largest;
  EXPECT_GT(free, 500);
  EXPECT_GT(largest, 1e-3 * h.mesh.bbox_diagonal());
  EXPECT_LT(worst, 1e-9 * scale) << "the correction is harmonic off the chains";
}

TEST(Layer, OverALinearSkinWithLinearCurvesTheFrameIsAPrecomputedSumEqualToTheSolve) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const Hand h;
  const double diag = h.mesh.bbox_diagonal();
  LayerOptions fast;
  fast.bind.method = DeformMethod::Harmonic;
  LayerOptions solved = fast;
  solved.precompute_linear = false;
  const CurveLayer a = bind_layer(h.mesh, h.rig, &h.skin, fast);
  const CurveLayer b = bind_layer(h.mesh, h.rig, &h.skin, solved);
  const std::vector<Vec3> rest = h.rest();
  std::vector<Vec3> skin(rest.size()), out_a(rest.size()), out_b(rest.size()), cut;
  std::vector<double> mask(rest.size());
  for (size_t i = 0; i < mask.size(); ++i)
    mask[i] = 0.25 + 0.5 * static_cast<double>(i % 3) / 2; // 0.25, 0.5, 0.75
  const CurveLayer a_masked = a.with_mask(mask), b_masked = b.with_mask(mask);
  // Every clip's last key, at two envelopes and with a mask: the sum and
  // the solve agree to rounding, and the correction is real.
  double apart = 0, largest = 0, cut_off = 0;
  for (int clip = 0; clip < h.clips.num_clips(); clip += 5) {
    const std::vector<Mat4> M = clip_skinning_matrices(a.joints(), h.clips, clip, h.clips.clip_range(clip).second);
    a.deform(M, skin, 0.0);
    for (const double envelope : {1.0, 0.4}) {
      a.deform(M, out_a, envelope);
      b.deform(M, out_b, envelope);
      apart = std::max(apart, max_apart(out_a, out_b));
      largest = std::max(largest, max_apart(out_a, skin));
      a_masked.deform(M, out_a, envelope);
      b_masked.deform(M, out_b, envelope);
      apart = std::max(apart, max_apart(out_a, out_b));
    }
    // The posed cut mesh, which always solves, has every input vertex where
    // the sum puts it (the chains' own on the linearly posed curves).
    a.deform(M, out_a);
    a.deform_cut(M, cut);
    for (size_t i = 0; i < rest.size(); ++i) {
      const int v = h.mesh.input_to_welded[i];
      cut_off = std::max(cut_off, (out_a[i] - cut[v]).norm());
    }
  }
  EXPECT_GT(largest, 1e-3 * diag) << "the layer corrects the skin";
  EXPECT_LT(apart, 1e-12 * diag) << "the precomputed sum is the solve";
  EXPECT_LT(cut_off, 1e-12 * diag);
  // A vertex masked with 0 is the skin computed on its own; the others move.
  {
    std::vector<double> half(rest.size(), 1.0);
    for (size_t i = 0; i < half.size(); i += 2)
      half[i] = 0;
    const std::vector<Mat4> skin_M =
        clip_skinning_matrices(h.skin.joints, h.clips, h.clips.find_clip("Grip"), 1 / 24.0);
    const std::vector<Vec3> own = skin_positions(h.skin, rest, skin_M, Skinning::Linear);
    a.with_mask(half).deform(clip_skinning_matrices(a.joints(), h.clips, h.clips.find_clip("Grip"), 1 / 24.0), out_a);
    double masked = 0, open = 0;
    for (size_t i = 0; i < rest.size(); ++i)
      (i % 2 ? open : masked) = std::max(i % 2 ? open : masked, (out_a[i] - own[i]).norm());
    EXPECT_LT(masked, 1e-12 * diag);
    EXPECT_GT(open, 1e-3 * diag);
  }
  // The same on any thread count, and the rest is the rest.
  const std::vector<Mat4> M = clip_skinning_matrices(a.joints(), h.clips, h.clips.find_clip("Grip"), 1 / 24.0);
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    a.deform(M, out_a);
  }
  a.deform(M, out_b);
  EXPECT_EQ(out_a, out_b);
  const std::vector<Mat4> I(a.joints().size(), Mat4::Identity());
  a.deform(I, out_a);
  EXPECT_LT(max_apart(out_a, rest), 1e-12 * diag);
}

TEST(Layer, ThePosedCutMeshShowsTheCurvesBetweenACoarseMeshsVertices) {
  // A coarse tube (8 around, 6 along), bent 90 degrees at its middle joint.
  // Posed, the tube is a chord between its own vertices; its cut mesh, whose
  // chains the net puts on the posed curves, lies closer on average to the
  // same rig posed on the tube refined twice (the same surface, 16 times the
  // faces).
  const SurfaceMesh m = test::tube(8, 6, 2, true);
  const Rig rig = make_tube_net();
  Pose pose;
  pose["mid"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitZ()));
  const Binding b = bind(m, rig);
  const CurveLayer layer = bind_layer(m, rig, nullptr, {}, &b);
  EXPECT_EQ(&layer.binding().embedding().impl(), &b.embedding().impl()) << "the binding is reused";
  const std::vector<Mat4> M = skinning_matrices(b.joints(), pose);
  std::vector<Vec3> cut;
  layer.deform_cut(M, cut);
  const SurfaceMesh cs = layer.binding().embedding().cut_surface();
  ASSERT_EQ(cut.size(), cs.input_to_welded.size());
  EXPECT_GT(cs.num_vertices(), m.num_vertices()); // the curves' vertices added
  auto posed_surface = [&](const SurfaceMesh& mesh, const std::vector<Vec3>& input) {
    SurfaceMesh p = mesh;
    p.positions = mesh.welded(input);
    return p;
  };
  std::vector<Vec3> out(b.num_input_vertices());
  b.deform(M, out);
  const SurfaceMesh fine = midpoint_subdivide(m, 2);
  const Binding fb = bind(fine, rig);
  std::vector<Vec3> fine_out(fb.num_input_vertices());
  fb.deform(M, fine_out);
  const SurfaceMesh posed_fine = posed_surface(fine, fine_out);
  const SurfaceDistance coarse = surface_distance(posed_surface(m, out), posed_fine);
  const SurfaceDistance with_curves = surface_distance(posed_surface(cs, cut), posed_fine);
  std::printf("against the refined tube posed: the tube %.3f%% mean, %.3f%% max; its cut mesh %.3f%%, %.3f%%\n",
              coarse.percent(coarse.mean), coarse.percent(coarse.max), with_curves.percent(with_curves.mean),
              with_curves.percent(with_curves.max));
  EXPECT_LT(with_curves.mean, 0.8 * coarse.mean);
  // The chains lie on the posed curves: each chain vertex where its
  // weights, blended as dual quaternions, take its rest position.
  const auto curves = posed_curves(b, rig, M);
  double off = 0, chord = 0;
  const std::vector<Vec3> welded_out = m.welded(out);
  std::vector<Vec3> base;
  layer.deform_cut(std::vector<Mat4>(M.size(), Mat4::Identity()), base);
  for (size_t v = 0; v < cut.size(); ++v) {
    if (!curves[v])
      continue;
    off = std::max(off, (cut[v] - *curves[v]).norm());
    Vec3 on_chord = Vec3::Zero(); // where the posed input vertices put it
    for (const auto& [u, w] : b.embedding().impl().cut.input_weights(detail::Vertex(static_cast<int>(v))))
      on_chord += w * welded_out[u];
    chord = std::max(chord, (on_chord - *curves[v]).norm());
  }
  EXPECT_LT(off, 1e-12 * m.bbox_diagonal());
  EXPECT_GT(chord, 1e-3 * m.bbox_diagonal()) << "the chords are not the curves";
  // At rest the cut mesh is its rest positions.
  double rest_off = 0;
  for (size_t v = 0; v < base.size(); ++v)
    rest_off =
        std::max(rest_off, (base[v] - b.embedding().impl().cut.position(detail::Vertex(static_cast<int>(v)))).norm());
  EXPECT_LT(rest_off, 1e-12 * m.bbox_diagonal());
  // The OBJ: every cut-mesh vertex, posed, and one polyline per profile.
  const std::string obj = layer.binding().embedding().cut_mesh_obj(cut);
  std::istringstream in(obj);
  int v = 0, l = 0;
  for (std::string line; std::getline(in, line);) {
    v += line.rfind("v ", 0) == 0;
    l += line.rfind("l ", 0) == 0;
  }
  EXPECT_EQ(v, static_cast<int>(cut.size()));
  EXPECT_EQ(l, static_cast<int>(rig.profiles.size()));
}

TEST(Layer, ASkinOnAnotherSkeletonIsRefusedNamingTheJoint) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  Hand h;
  h.rig.joints[3].bind(0, 3) += 0.01; // a joint moved in the rig only
  try {
    (void)bind_layer(h.mesh, h.rig, &h.skin);
    ADD_FAILURE() << "a rig on another skeleton was layered over the skin";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("joint '" + h.rig.joints[3].name + "': its bind matrix differs"),
              std::string::npos)
        << e.what();
  }
  LayerOptions bad;
  bad.mask = {0.5};
  EXPECT_THROW(bind_layer(Hand().mesh, Hand().rig, &h.skin, bad), InputError);
}

TEST(Layer, APulledNodeMovesTheRegionsItsProfilesBoundAndNothingBeyond) {
  // The tube net's middle ring, node 0 pulled outwards by 2 % of the
  // diagonal, at rest and bent: over the net's own deformation.
  const PulledTube tube;
  const auto& [mesh, rig, layer, diag, node, pull] = tube;
  for (const double bend : {0.0, 0.6}) {
    Pose pose;
    pose["mid"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(bend, Eigen::Vector3d::UnitZ()));
    const std::vector<Mat4> M = skinning_matrices(layer.joints(), pose);
    std::vector<Vec3> base(layer.num_input_vertices()), out(base.size());
    layer.deform(M, base);
    EXPECT_LT(max_apart(base,
                        [&] {
                          std::vector<Vec3> net(base.size());
                          layer.binding().deform(M, net);
                          return net;
                        }()),
              1e-12 * diag)
        << "no offsets: the net's own deformation";
    layer.deform(M, out, 1.0, &pull);
    double at_node = 0, beyond = 0;
    for (size_t i = 0; i < out.size(); ++i) {
      const double moved = (out[i] - base[i]).norm();
      const Vec3 r = mesh.positions[mesh.input_to_welded[i]];
      if ((r - node).norm() < 0.05 * diag)
        at_node = std::max(at_node, moved);
      // Beyond the next rings along the tube (at heights 0.6 and 3.4).
      if (r.y() < 0.55 || r.y() > 3.45)
        beyond = std::max(beyond, moved);
    }
    EXPECT_NEAR(at_node, 0.02 * diag, 0.25 * 0.02 * diag) << "bend " << bend;
    EXPECT_LT(beyond, 2e-4 * diag) << "bend " << bend;
  }
  std::vector<Vec3> out(layer.num_input_vertices());
  const NodeOffsets unknown{{"no_such_node", Vec3::Zero()}};
  EXPECT_THROW(layer.deform(std::vector<Mat4>(layer.joints().size(), Mat4::Identity()), out, 1.0, &unknown),
               InputError);
}

TEST(Layer, ARegionMaskedOutKeepsItsBaseAndTheOthersStillMove) {
  // The tube net's middle ring, node 0 pulled: the regions its profiles
  // bound move. Masked by region, one of them stays the base inside, the
  // curves around it still follow the net, and the others move as before.
  const PulledTube tube;
  const auto& [mesh, rig, layer, diag, node, pull] = tube;
  const std::vector<Mat4> M(layer.joints().size(), Mat4::Identity());
  std::vector<Vec3> base(layer.num_input_vertices()), open(base.size()), out(base.size());
  layer.deform(M, base);
  layer.deform(M, open, 1.0, &pull);
  // Each welded vertex's regions, from the cut mesh.
  const Embedding& e = layer.binding().embedding();
  const RawMesh cut = e.cut_mesh();
  std::vector<std::set<int>> regions_at(mesh.num_vertices());
  for (size_t f = 0; f + 1 < cut.face_offsets.size(); ++f)
    for (int k = cut.face_offsets[f]; k < cut.face_offsets[f + 1]; ++k)
      if (cut.face_vertices[k] < mesh.num_vertices())
        regions_at[cut.face_vertices[k]].insert(e.face_regions()[f]);
  // The region that moves most, inside.
  const auto& list = e.report().region_list;
  std::vector<double> moved(list.size(), 0);
  for (size_t i = 0; i < open.size(); ++i)
    if (const auto& at = regions_at[mesh.input_to_welded[i]]; at.size() == 1 && *at.begin() >= 0)
      moved[*at.begin()] = std::max(moved[*at.begin()], (open[i] - base[i]).norm());
  const int held = static_cast<int>(std::max_element(moved.begin(), moved.end()) - moved.begin());
  ASSERT_GT(moved[held], 5e-3 * diag);
  const std::vector<double> mask = layer.region_mask({{list[held].key(), 0.0}});
  layer.with_mask(mask).deform(M, out, 1.0, &pull);
  double inside = 0, boundary = 0, elsewhere = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    const auto& at = regions_at[mesh.input_to_welded[i]];
    const double d = (out[i] - base[i]).norm(), o = (open[i] - out[i]).norm();
    if (at.size() == 1 && *at.begin() == held)
      inside = std::max(inside, d);
    else if (at.count(held))
      boundary = std::max(boundary, o);
    else
      elsewhere = std::max(elsewhere, o);
  }
  EXPECT_LT(inside, 1e-12 * diag) << "the masked region is the base inside";
  EXPECT_LT(boundary, 1e-12 * diag) << "its curves follow the net";
  EXPECT_LT(elsewhere, 1e-12 * diag) << "the other regions move as unmasked";
  // Every other region, and a value between: as given.
  const std::vector<double> half = layer.region_mask({{list[held].key(), 0.5}}, 0.0);
  for (size_t i = 0; i < half.size(); ++i) {
    const auto& at = regions_at[mesh.input_to_welded[i]];
    EXPECT_EQ(half[i], at.count(held) ? 0.5 : 0.0) << "vertex " << i;
  }
  EXPECT_THROW((void)layer.region_mask({{"no_such:L", 0.0}}), InputError);
  EXPECT_THROW((void)layer.region_mask({{list[held].key(), 1.5}}), InputError);
}

TEST(Layer, ARegionMaskWithAFalloffRisesSmoothlyToItsCurvesAndIsExactBeyondIt) {
  // The same region masked with 0, with a falloff of 2 % of the diagonal:
  // on its curves the mask is 1 (they follow the net), inside it falls
  // with the distance from them, no value rises as the distance grows, and
  // beyond the falloff it is 0 exactly, so the region's inside is the base
  // there. The open regions keep 1.
  const PulledTube tube;
  const auto& [mesh, rig, layer, diag, node, pull] = tube;
  const Embedding& e = layer.binding().embedding();
  const RawMesh cut = e.cut_mesh();
  std::vector<std::set<int>> regions_at(cut.positions.size());
  for (size_t f = 0; f + 1 < cut.face_offsets.size(); ++f)
    for (int k = cut.face_offsets[f]; k < cut.face_offsets[f + 1]; ++k)
      regions_at[cut.face_vertices[k]].insert(e.face_regions()[f]);
  const auto& list = e.report().region_list;
  const int held = 0;
  const double falloff = 0.02;
  const std::vector<double> hard = layer.region_mask({{list[held].key(), 0.0}});
  const std::vector<double> soft = layer.region_mask({{list[held].key(), 0.0}}, 1.0, falloff);
  // Each welded vertex's distance from the region's curves, straight (a
  // lower bound on the distance along the surface).
  std::vector<Vec3> curve;
  for (size_t v = 0; v < cut.positions.size(); ++v)
    if (regions_at[v].count(held) && regions_at[v].size() > 1)
      curve.push_back(cut.positions[v]);
  ASSERT_FALSE(curve.empty());
  int ramped = 0, exact = 0;
  std::vector<std::pair<double, double>> inside; // (distance, value)
  for (size_t i = 0; i < soft.size(); ++i) {
    const int v = mesh.input_to_welded[i];
    EXPECT_GE(soft[i], hard[i]) << "a falloff only raises the mask";
    EXPECT_LE(soft[i], 1.0);
    const auto& at = regions_at[v];
    if (!(at.size() == 1 && *at.begin() == held)) {
      EXPECT_EQ(soft[i], hard[i]) << "outside the region, as without a falloff: vertex " << i;
      continue;
    }
    double d = INFINITY;
    for (const Vec3& q : curve)
      d = std::min(d, (cut.positions[v] - q).norm());
    if (d >= falloff * diag * 1.0001) {
      EXPECT_EQ(soft[i], 0.0) << "beyond the falloff, the region's value exactly: vertex " << i;
      ++exact;
    } else if (soft[i] > 0) {
      ++ramped;
    }
    inside.emplace_back(d, soft[i]);
  }
  EXPECT_GT(ramped, 10);
  EXPECT_GT(exact, 10);
  // The value is the smoothstep of the distance along the surface, which is
  // no shorter than the straight one: never above the smoothstep of that.
  for (const auto& [d, x] : inside) {
    const double t = std::min(d / (falloff * diag), 1.0);
    EXPECT_LE(x, 1 - t * t * (3 - 2 * t) + 1e-12) << "at " << d;
  }
  EXPECT_THROW((void)layer.region_mask({{list[held].key(), 0.0}}, 1.0, -0.1), InputError);
  EXPECT_THROW((void)layer.region_mask({{list[held].key(), 0.0}}, 1.0, std::nan("")), InputError);
}

TEST(Layer, APoseFileOfVersionTwoGivesNodeOffsetsAndVersionOneReadsAsBefore) {
  const std::string v1 = R"({"format": "curvenet-pose", "version": 1,
    "joints": {"mid": {"rotation": [0.8660254037844387, 0, 0, 0.5]}}})";
  const PoseFile one = parse_pose_file(v1, "v1.pose.json");
  EXPECT_EQ(one.joints.size(), 1u);
  EXPECT_TRUE(one.nodes.empty());
  EXPECT_EQ(parse_pose(v1, "v1").size(), 1u);
  const std::string v2 = R"({"format": "curvenet-pose", "version": 2,
    "joints": {"mid": {"rotation": [1, 0, 0, 0]}},
    "nodes": {"ring1_0": {"offset": [0.1, 0, -0.25]}, "cap_top": {"offset": [0, 0.5, 0], "x_note": "kept"}}})";
  const PoseFile two = parse_pose_file(v2, "v2.pose.json");
  ASSERT_EQ(two.nodes.size(), 2u);
  EXPECT_EQ(two.nodes.at("ring1_0"), Vec3(0.1, 0, -0.25));
  EXPECT_EQ(two.nodes.at("cap_top"), Vec3(0, 0.5, 0));
  // Nodes need version 2; a node entry gives a finite offset, and nothing else.
  auto refused = [](const std::string& text, const std::string& where) {
    try {
      (void)parse_pose_file(text, "p.pose.json");
    } catch (const InputError& e) {
      return std::string(e.what()).find("p.pose.json: " + where) != std::string::npos;
    }
    return false;
  };
  EXPECT_TRUE(refused(R"({"format": "curvenet-pose", "version": 1, "nodes": {}})", "/nodes"));
  EXPECT_TRUE(refused(R"({"format": "curvenet-pose", "version": 3})", "/version"));
  EXPECT_TRUE(refused(R"({"format": "curvenet-pose", "version": 2, "nodes": {"a": {}}})", "/nodes/a/offset"));
  EXPECT_TRUE(
      refused(R"({"format": "curvenet-pose", "version": 2, "nodes": {"a": {"offset": [1, 2]}}})", "/nodes/a/offset"));
  EXPECT_TRUE(refused(R"({"format": "curvenet-pose", "version": 2, "nodes": {"a": {"offset": [1, 2, 3], "b": 1}}})",
                      "/nodes/a/b"));
}

TEST(Layer, NodeKeysInterpolateOverTheFramesAndAnAnimationFollowsThem) {
  const NodeKeys keys = parse_node_keys(R"({"format": "curvenet-node-keys", "version": 1, "nodes": {
      "a": [{"frame": 0, "offset": [0, 0, 0]}, {"frame": 10, "offset": [0, 1, 0]}],
      "b": [{"frame": 5, "offset": [2, 0, 0]}]}})",
                                        "k.json");
  EXPECT_EQ(keys.at(-3).at("a"), Vec3(0, 0, 0));
  EXPECT_EQ(keys.at(2.5).at("a"), Vec3(0, 0.25, 0));
  EXPECT_EQ(keys.at(40).at("a"), Vec3(0, 1, 0));
  EXPECT_EQ(keys.at(0).at("b"), Vec3(2, 0, 0)); // one key: held
  EXPECT_THROW(parse_node_keys(R"({"format": "curvenet-node-keys", "version": 1, "nodes": {
      "a": [{"frame": 3, "offset": [0, 0, 0]}, {"frame": 3, "offset": [0, 1, 0]}]}})",
                               "k.json"),
               InputError);
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  // The hand's Grip over frames 0:8 through the net, a node pulled from
  // nothing at frame 0 to 4 mm at frame 8: frame 0 is the plain animation
  // exactly, frame 8 moves.
  const auto dir = test::temp_dir("node_keys");
  const std::string key_file = (dir / "pull.keys.json").string();
  std::ofstream(key_file) << R"({"format": "curvenet-node-keys", "version": 1, "nodes": {
      "index_pip_1": [{"frame": 0, "offset": [0, 0, 0]}, {"frame": 8, "offset": [0, 0.004, 0]}]}})";
  AnimateJob job;
  job.scene = {test::data("xr_tools_hand/hand_l.gltf"), test::data("xr_tools_hand/example/hand_l.cnrig.json"), "", ""};
  job.clip_file = test::data("xr_tools_hand/hand_l_poses.glb");
  job.clip = "Grip";
  job.frames = "0:8";
  job.obj_sequence = (dir / "plain").string();
  (void)run(job);
  job.node_keys = key_file;
  job.obj_sequence = (dir / "pulled").string();
  (void)run(job);
  const std::string f0 = sequence_name("frame", 0), f8 = sequence_name("frame", 8);
  EXPECT_EQ(test::file_bytes(dir / "plain" / f0), test::file_bytes(dir / "pulled" / f0));
  EXPECT_NE(test::file_bytes(dir / "plain" / f8), test::file_bytes(dir / "pulled" / f8));
}

TEST(Layer, ABakeFittedToTheLayerComesCloserToItThanTheSkinItCorrects) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const auto dir = test::temp_dir("layer_bake");
  BakeJob job;
  job.scene = {test::data("xr_tools_hand/hand_l.gltf"), test::data("xr_tools_hand/example/hand_l.cnrig.json"), "", ""};
  job.fit = test::data("xr_tools_hand/hand_l_poses.glb");
  job.glb = (dir / "layered.glb").string();
  job.layer.over_skin = true;
  (void)run(job);
  // Over every pose of the clip file: the baked skin against the layer it
  // was fitted to, and the original skin against the same.
  const Hand h;
  const CurveLayer layer = bind_layer(h.mesh, h.rig, &h.skin);
  const SkinnedMesh baked = load_skinned_mesh(job.glb);
  double baked_err = 0, skin_err = 0;
  for (int c = 0; c < h.clips.num_clips(); ++c) {
    const double t = h.clips.clip_range(c).first;
    std::vector<Vec3> target(layer.num_input_vertices());
    layer.deform(clip_skinning_matrices(layer.joints(), h.clips, c, t), target);
    const std::vector<Vec3> b = skin_positions(baked, h.rest(), clip_skinning_matrices(baked.joints, h.clips, c, t));
    const std::vector<Vec3> s = skin_positions(h.skin, h.rest(), clip_skinning_matrices(h.skin.joints, h.clips, c, t));
    for (size_t i = 0; i < target.size(); ++i) {
      baked_err += (b[i] - target[i]).norm();
      skin_err += (s[i] - target[i]).norm();
    }
  }
  EXPECT_LT(baked_err, 0.5 * skin_err) << "baked " << baked_err << ", skin " << skin_err;
  // A layered bake needs clips to fit over.
  job.fit.clear();
  EXPECT_THROW(run(job), InputError);
}

TEST(Layer, APulledRigTransferredToAnotherTessellationPosesTheSameShape) {
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const SurfaceMesh source = load_mesh(test::data("xr_tools_hand/hand_l.gltf"));
  const SurfaceMesh target = load_mesh(test::data("xr_tools_hand/Hand_low_L.gltf"));
  const Rig rig = read_rig(test::data("xr_tools_hand/example/hand_l.cnrig.json"));
  const TransferResult moved = transfer(rig, source, target);
  ASSERT_TRUE(moved.report.ok);
  const PoseFile pose = read_pose_file(std::string(CURVENET_SOURCE_DIR) + "/tests/data/hand/fist_pull.pose.json");
  ASSERT_FALSE(pose.nodes.empty());
  auto posed = [&](const SurfaceMesh& mesh, const Rig& r, bool pulled) {
    const CurveLayer layer = bind_layer(mesh, r, nullptr);
    std::vector<Vec3> out(layer.num_input_vertices());
    layer.deform(skinning_matrices(layer.joints(), pose.joints), out, 1.0, pulled ? &pose.nodes : nullptr);
    SurfaceMesh m = mesh;
    m.positions = m.welded(out);
    return m;
  };
  const double diag = source.bbox_diagonal();
  const SurfaceDistance rest = surface_distance(source, target);
  const SurfaceMesh a = posed(source, rig, true), b = posed(target, moved.rig, true);
  const SurfaceDistance apart = surface_distance(a, b);
  const SurfaceDistance unpulled = surface_distance(posed(source, rig, false), posed(target, moved.rig, false));

  // The pull moves both, by about its 4 mm.
  EXPECT_GT(surface_distance(a, posed(source, rig, false)).max, 0.01 * diag);
  EXPECT_GT(surface_distance(b, posed(target, moved.rig, false)).max, 0.01 * diag);
  // Pulled, the two agree as well as the net alone makes them agree (the
  // low hand's coarse fingers fold differently: 0.28 % apart on average,
  // 3.3 % at the worst vertex, unpulled), and on average within the
  // transfer bound, 1.5 x their rest distance.
  EXPECT_LE(apart.mean, unpulled.mean + 1e-3 * diag) << apart.mean / diag;
  EXPECT_LE(apart.max, unpulled.max + 2e-3 * diag) << apart.max / diag;
  EXPECT_LE(apart.mean, std::max(1.5 * rest.mean, 0.005 * diag)) << apart.mean / diag;
}
