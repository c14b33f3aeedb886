#pragma once
// The transfer end-to-end check, shared by transfer_test and
// bench/transfer_table: author a rig on one mesh of a family with the
// starter net, transfer it to the family's other meshes, pose them all with
// the same poses, and compare each posed target with the posed source.

#include "curvenet/compare.hpp"
#include "curvenet/deform.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/subdivide.hpp"
#include "curvenet/transfer.hpp"
#include "cut/cut_mesh.hpp"
#include "trace/trace_mesh.hpp"

#include <array>
#include <cstdio>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace curvenet::check {

struct Row {
  std::string pair, clip;
  SurfaceDistance rest, posed;
  /// The posed source against the target as a perfect transfer would pose
  /// it: each target vertex carried by the source's own deformation from
  /// its closest point at rest. It holds what no transfer can remove: the
  /// surfaces' own difference, and how the pose bends the target's faces
  /// (a non-planar quad folds differently from the source's triangles).
  SurfaceDistance ideal;
  /// The target against the source, each refined by midpoint subdivision
  /// (the same surfaces, finer) and posed through its rig: a bent joint is
  /// then the curved surface the deformation makes on either side, not a
  /// coarse mesh's chord across it.
  SurfaceDistance refined;
  double agreement = 0; ///< region agreement of the transfer
  double moved = 0;     ///< largest vertex displacement of the posed source, as % of its diagonal
  /// posed <= max(1.5 x ideal, 0.5 % of the diagonal), for the mean and for the max
  [[nodiscard]] double bound(double ideal_value) const { return std::max(1.5 * ideal_value, 0.005 * rest.diagonal); }
  [[nodiscard]] bool pass_mean() const { return posed.mean <= bound(ideal.mean); }
  [[nodiscard]] bool pass_max() const { return posed.max <= bound(ideal.max); }
  /// Refined on both sides: within 1.5 x the rest distance (or 0.5 % of the
  /// diagonal), mean and max.
  [[nodiscard]] bool pass_refined() const { return refined.mean <= bound(rest.mean) && refined.max <= bound(rest.max); }
};

struct Target {
  std::string path;
  Mat4 frame = Mat4::Identity(); ///< the target mesh's space to the source's
  int levels = 0;                ///< Catmull-Clark levels applied to the file (a control cage)
  int cage_levels = 0; ///< TransferOptions::target_cage_levels: the file is a cage, transferred through its limit
};

struct Family {
  std::string source;
  int source_levels = 0; ///< Catmull-Clark levels applied to the source file
  std::vector<Target> targets;
  std::vector<Joint> joints;
  std::vector<std::pair<std::string, Pose>> poses;
  StarterOptions starter;
};

inline SurfaceMesh transformed(SurfaceMesh m, const Mat4& t) {
  for (auto& p : m.positions)
    p = (t * p.homogeneous()).head<3>();
  return m;
}

/// A two-joint skeleton along the mesh's longest bounding-box axis, and
/// poses that bend at the second joint and turn the first.
inline void two_joint_family(const SurfaceMesh& mesh, Family& f) {
  Vec3 lo = mesh.positions[0], hi = lo;
  for (const auto& p : mesh.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (hi[k] - lo[k] > hi[axis] - lo[axis])
      axis = k;
  const Vec3 centre = (lo + hi) / 2;
  Vec3 a = centre, b = centre;
  a[axis] = lo[axis] + 0.25 * (hi[axis] - lo[axis]);
  b[axis] = lo[axis] + 0.6 * (hi[axis] - lo[axis]);
  f.joints.resize(2);
  f.joints[0].name = "root";
  f.joints[0].bind.block<3, 1>(0, 3) = a;
  f.joints[1].name = "bend";
  f.joints[1].parent = "root";
  f.joints[1].bind.block<3, 1>(0, 3) = b;
  const Vec3 side = Vec3::Unit((axis + 1) % 3);
  for (const double deg : {30.0, 60.0}) {
    Pose p;
    p["bend"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(deg * std::numbers::pi / 180, side));
    f.poses.emplace_back("bend " + std::to_string(static_cast<int>(deg)), p);
  }
  Pose twist;
  twist["root"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Vec3::Unit(axis)));
  twist["bend"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(-0.5, Vec3::Unit((axis + 2) % 3)));
  f.poses.emplace_back("turn+bend", twist);
  f.starter.rings_per_bone = 3;
  f.starter.first_angle_deg = 45; // keep nodes off the side fins and the spine of a fish or a cow
}

inline Family make_family(const std::string& name, const std::string& data, const std::vector<std::string>& clips) {
  Family f;
  if (name == "hand") {
    const std::string d = data + "/xr_tools_hand/";
    f.source = d + "hand_l.gltf";
    f.targets = {{d + "Hand_low_L.gltf"}, {d + "hand_l_quads.obj"}, {d + "hand_low_l_quads.obj"}};
    f.joints = load_skinned_mesh(f.source).joints;
    const SkinnedMesh poses = load_skinned_mesh(d + "hand_l_poses.glb");
    std::vector<std::string> names = clips;
    if (names.empty())
      names = poses.clip_names;
    for (const auto& n : names) {
      const int c = poses.find_clip(n);
      if (c >= 0)
        f.poses.emplace_back(n, pose_from_clip(poses, c, poses.clip_range(c).second));
    }
  } else if (name == "spot") {
    const std::string d = data + "/spot/";
    f.source = d + "spot_quadrangulated.obj";
    f.targets = {{d + "spot_triangulated.obj"},
                 {d + "spot_low_resolution.obj"},
                 {d + "spot_control_mesh.obj"},
                 {d + "spot_control_mesh.obj", Mat4::Identity(), 0, 2}};
    two_joint_family(load_mesh(f.source), f);
  } else if (name == "blub") {
    // Blub's control cage stands for its Catmull-Clark limit surface, which
    // fish_low_resolution.obj remeshes: the cage refined twice (quads) is
    // the source, so this transfer goes from quads to triangles. fish.obj is
    // Blub in another pose (tail swung sideways, fins raised), so no frame
    // lines it up with the others: its transfer must be refused, saying how
    // far apart the surfaces are. The bare cage, up to 11 % of the diagonal
    // off its own limit surface, is a target too.
    const std::string d = data + "/blub/";
    f.source = d + "fish_control_mesh.obj";
    f.source_levels = 2;
    Mat4 onto_source = Mat4::Identity();
    onto_source(0, 3) = -3.3963165; // fish.obj's bounding box, centred on the others' along x
    f.targets = {{d + "fish_low_resolution.obj"},
                 {d + "fish_control_mesh.obj"},
                 {d + "fish_control_mesh.obj", Mat4::Identity(), 0, 2},
                 {d + "fish.obj", onto_source}};
    two_joint_family(catmull_clark(load_mesh(f.source), f.source_levels), f);
  } else if (name == "penguin") {
    // A triangle remesh of a cage's limit surface, to the cage refined twice
    // (quads) and to the bare cage (quads, triangles and pentagons).
    const std::string d = data + "/penguin/";
    f.source = d + "penguin.obj";
    f.targets = {{d + "penguin_control_mesh.obj", Mat4::Identity(), 2},
                 {d + "penguin_control_mesh.obj"},
                 {d + "penguin_control_mesh.obj", Mat4::Identity(), 0, 2}};
    two_joint_family(load_mesh(f.source), f);
  }
  return f;
}

inline SurfaceMesh posed_mesh(const SurfaceMesh& mesh, const Binding& b, const Pose& pose) {
  std::vector<Vec3> out(b.num_input_vertices());
  b.deform(skinning_matrices(b.joints(), pose), out);
  SurfaceMesh m = mesh;
  for (size_t i = 0; i < out.size(); ++i)
    m.positions[mesh.input_to_welded[i]] = out[i];
  return m;
}

/// Where each vertex of a target (in the source's space) lies on the source
/// surface: its closest point's triangle corners and weights, and its
/// offset from that point.
struct Carried {
  std::vector<std::array<int, 3>> corners;
  std::vector<std::array<double, 3>> weights;
  std::vector<Vec3> offset;
};

inline Carried closest_on_source(const SurfaceMesh& target_in_source_space, const SurfaceMesh& source) {
  const detail::CutMesh cut = detail::CutMesh::from_surface(source);
  const detail::TraceMesh tm(source, cut);
  Carried c;
  for (const Vec3& p : target_in_source_space.positions) {
    const auto near = tm.nearest(p);
    c.corners.push_back(tm.tri(near.tri));
    c.weights.push_back(near.bary);
    c.offset.push_back(p - near.point);
  }
  return c;
}

/// The target posed as a perfect transfer would pose it: each vertex moved
/// with its closest point on the source, whose triangle's corners move as
/// the posed source's vertices (the offset rides along, unturned).
inline SurfaceMesh ideally_posed(SurfaceMesh target_in_source_space, const Carried& c,
                                 const SurfaceMesh& posed_source) {
  for (size_t v = 0; v < target_in_source_space.positions.size(); ++v) {
    Vec3 p = c.offset[v];
    for (int k = 0; k < 3; ++k)
      p += c.weights[v][k] * posed_source.positions[c.corners[v][k]];
    target_in_source_space.positions[v] = p;
  }
  return target_in_source_space;
}

inline std::string short_name(const std::string& path) {
  return path.substr(path.find_last_of('/') + 1);
}

/// Rows for every target and pose; targets the transfer refuses get a row
/// with the refusal in `clip` and no distances.
inline std::vector<Row> run_family(const std::string& name, const std::string& data,
                                   const std::vector<std::string>& clips, std::vector<std::string>* refusals = nullptr,
                                   const BindOptions& bind_options = {}) {
  const Family f = make_family(name, data, clips);
  const SurfaceMesh source =
      f.source_levels > 0 ? catmull_clark(load_mesh(f.source), f.source_levels) : load_mesh(f.source);
  const Rig rig = make_starter(source, f.joints, f.starter).rig;
  const Binding sb = bind(source, rig, bind_options);
  // Refined twice (16 times the faces of a triangle mesh), or once on a large one.
  const SurfaceMesh refined = midpoint_subdivide(source, source.num_faces() * 48 <= 300000 ? 2 : 1);
  const Binding rb = bind(refined, rig, bind_options);
  std::vector<SurfaceMesh> posed_source, posed_refined;
  for (const auto& [n, p] : f.poses) {
    posed_source.push_back(posed_mesh(source, sb, p));
    posed_refined.push_back(posed_mesh(refined, rb, p));
  }
  std::vector<Row> rows;
  for (const auto& [t, frame, levels, cage_levels] : f.targets) {
    const SurfaceMesh target = levels > 0 ? catmull_clark(load_mesh(t), levels) : load_mesh(t);
    TransferOptions topt;
    topt.target_frame = frame;
    topt.target_cage_levels = cage_levels;
    TransferResult tr;
    try {
      tr = transfer(rig, source, target, topt);
    } catch (const Error& e) {
      if (refusals)
        refusals->push_back(short_name(t) + ": " + e.what());
      continue;
    }
    if (!tr.report.ok) {
      if (refusals)
        refusals->push_back(short_name(t) + ": " + (tr.report.problems.empty() ? "not ok" : tr.report.problems[0]));
      continue;
    }
    const Binding tb = bind(target, tr.rig, bind_options);
    // The target refined the same way, so that neither side is a chord
    // across a bent joint (a cage is bound through its limit: as it is).
    std::optional<SurfaceMesh> fine_target;
    std::optional<Binding> ftb;
    if (cage_levels == 0) {
      try {
        fine_target = midpoint_subdivide(target, target.num_faces() * 48 <= 300000 ? 2 : 1);
        ftb = bind(*fine_target, tr.rig, bind_options);
      } catch (const EmbedError&) {
        // A bare cage's non-planar quads refined are not the faces its rig
        // was placed on: compared as it is.
        fine_target.reset();
      }
    }
    const SurfaceMesh placed = transformed(target, frame);
    const SurfaceDistance rest = surface_distance(source, placed);
    const Carried carried = closest_on_source(placed, source);
    for (size_t k = 0; k < f.poses.size(); ++k) {
      Row r;
      r.pair = short_name(f.source) + (f.source_levels > 0 ? " (CC" + std::to_string(f.source_levels) + ")" : "") +
               " -> " + short_name(t) + (levels > 0 ? " (CC" + std::to_string(levels) + ")" : "") +
               (cage_levels > 0 ? " (as a cage)" : "");
      r.clip = f.poses[k].first;
      r.rest = rest;
      r.posed = surface_distance(posed_source[k], transformed(posed_mesh(target, tb, f.poses[k].second), frame));
      r.ideal = surface_distance(posed_source[k], ideally_posed(placed, carried, posed_source[k]));
      r.refined =
          surface_distance(posed_refined[k], transformed(fine_target ? posed_mesh(*fine_target, *ftb, f.poses[k].second)
                                                                     : posed_mesh(target, tb, f.poses[k].second),
                                                         frame));
      r.refined.diagonal = rest.diagonal;
      r.agreement = tr.report.agreement;
      for (int v = 0; v < source.num_vertices(); ++v)
        r.moved = std::max(r.moved, rest.percent((posed_source[k].positions[v] - source.positions[v]).norm()));
      rows.push_back(r);
    }
  }
  return rows;
}

inline void print_table(const std::vector<Row>& rows, FILE* out, bool markdown = false) {
  if (markdown) {
    std::fprintf(out,
                 "| pair | clip | moved | rest mean | posed mean | rest max | ideal max | posed max | refined mean "
                 "| refined max | region agreement | within bound | within 1.5 x rest of the refined |\n"
                 "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const Row& r : rows)
      std::fprintf(
          out,
          "| %s | %s | %.2f%% | %.3f%% | %.3f%% | %.3f%% | %.3f%% | %.3f%% | %.3f%% | %.3f%% | %.2f%% | %s | %s |\n",
          r.pair.c_str(), r.clip.c_str(), r.moved, r.rest.percent(r.rest.mean), r.rest.percent(r.posed.mean),
          r.rest.percent(r.rest.max), r.rest.percent(r.ideal.max), r.rest.percent(r.posed.max),
          r.rest.percent(r.refined.mean), r.rest.percent(r.refined.max), 100 * r.agreement,
          r.pass_mean() && r.pass_max() ? "yes" : "NO", r.pass_refined() ? "yes" : "NO");
    return;
  }
  std::fprintf(out, "%-64s %-14s %8s %9s %9s %9s %9s %9s %9s %9s %8s %5s %5s\n", "pair", "clip", "moved", "rest_mean",
               "posed_mean", "rest_max", "ideal_max", "posed_max", "ref_mean", "ref_max", "regions", "pass", "ref");
  for (const Row& r : rows)
    std::fprintf(out, "%-64s %-14s %7.2f%% %8.3f%% %8.3f%% %8.3f%% %8.3f%% %8.3f%% %8.3f%% %8.3f%% %7.2f%% %5s %5s\n",
                 r.pair.c_str(), r.clip.c_str(), r.moved, r.rest.percent(r.rest.mean), r.rest.percent(r.posed.mean),
                 r.rest.percent(r.rest.max), r.rest.percent(r.ideal.max), r.rest.percent(r.posed.max),
                 r.rest.percent(r.refined.mean), r.rest.percent(r.refined.max), 100 * r.agreement,
                 r.pass_mean() && r.pass_max() ? "yes" : "NO", r.pass_refined() ? "yes" : "NO");
}

} // namespace curvenet::check
