// Our deformation modes side by side with the skins a rigger already has,
// linear blend skinning (LBS) and dual-quaternion skinning (DQS), on the
// same skeleton and poses (docs/deform.md, "Against the skins"):
//
//   build/bin/deform_quality [CASE...]        the table; cases by name prefix (cylinder, hand, cesium, horse, ...)
//   build/bin/deform_quality --ply DIR CASE   also writes rest and each deformation of a case's last frame as PLY
//   (checker colours); --ply-frame N writes frame N instead
//   build/bin/deform_quality --layer [CASE...]  the skins, the net and the layer over each skin only, with the
//   change of the surface's detail away from the curves (docs/deform.md, "A layer over the skin")
//
// LBS and DQS use the character's own skin weights where it has a skin, and
// `curvenet bake`'s weights of the same rig on the generated cylinder. Each
// case is posed by one or more frames; each metric is its worst frame.
// CURVENET_RINGS_PER_BONE=N and CURVENET_MIDDLE_NODES=0 make the starter nets
// with other options, for comparison.

#include "curvenet/bake.hpp"
#include "curvenet/deform.hpp"
#include "curvenet/edit.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/layer.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/quality.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "core/polyline_distance.hpp"
#include "generate/tube.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

using namespace curvenet;

namespace {

const std::string kData = CURVENET_DATA_DIR;

/// One case: a mesh, a rig on it, the baseline skin, the frames that pose it.
struct Case {
  std::string name;
  std::string mesh_path; ///< empty for a generated mesh
  SurfaceMesh mesh;
  RawMesh raw;
  Rig rig;
  /// The baseline skin: joints in mesh space and per input vertex weights.
  std::vector<Joint> skin_joints;
  SkinWeights skin;
  /// Per frame: the skin joints' matrices (the rig's come by name).
  std::vector<Pose> poses;            ///< poses, or
  const SkinnedMesh* clips = nullptr; ///< clip frames
  std::vector<std::pair<int, double>> clip_times;
  QualityOptions quality;
  std::vector<int> dominant; ///< per welded vertex, a skin joint
  /// Applied before every frame's matrices: the inverse of the similarity
  /// that a file's armature puts around its whole skeleton (Blender's
  /// exports scale it by 100), so that volumes compare with the rest mesh.
  Mat4 normalise = Mat4::Identity();
};

int joint_index(const std::vector<Joint>& joints, const std::string& name) {
  for (size_t j = 0; j < joints.size(); ++j)
    if (joints[j].name == name)
      return static_cast<int>(j);
  throw Error("no joint named " + name);
}

/// A skinned file's own weights as SkinWeights over its joints.
SkinWeights weights_of(const SkinnedMesh& s) {
  SkinWeights w;
  w.influences = 4;
  for (const auto& j : s.joints)
    w.joints.push_back(j.name);
  for (size_t v = 0; v < s.vertex_joint.size(); ++v)
    for (int k = 0; k < 4; ++k) {
      w.joint.push_back(s.vertex_joint[v][k]);
      w.weight.push_back(s.vertex_joint[v][k] >= 0 ? s.vertex_weight[v][k] : 0.0);
    }
  return w;
}

/// Each welded vertex's strongest joint, by the baseline skin.
std::vector<int> dominant_of(const SurfaceMesh& mesh, const SkinWeights& w) {
  std::vector<int> d(mesh.num_vertices(), 0);
  std::vector<double> best(mesh.num_vertices(), -1);
  for (int i = 0; i < w.num_vertices(); ++i) {
    const int v = mesh.input_to_welded[i];
    for (int k = 0; k < w.influences; ++k)
      if (w.joint[i * w.influences + k] >= 0 && w.weight[i * w.influences + k] > best[v]) {
        best[v] = w.weight[i * w.influences + k];
        d[v] = w.joint[i * w.influences + k];
      }
  }
  return d;
}

std::vector<Mat4> frame_matrices(const Case& c, const std::vector<Joint>& joints, size_t f) {
  std::vector<Mat4> m = c.clips
                            ? clip_skinning_matrices(joints, *c.clips, c.clip_times[f].first, c.clip_times[f].second)
                            : skinning_matrices(joints, c.poses[f]);
  for (auto& x : m)
    x = c.normalise * x;
  return m;
}
size_t frames_of(const Case& c) {
  return c.clips ? c.clip_times.size() : c.poses.size();
}

struct Method {
  std::string name;
  /// Positions per input vertex for frame f.
  std::function<std::vector<Vec3>(size_t f)> pose;
};

struct Row {
  std::string method;
  DeformationQuality worst;
};

void worst_of(DeformationQuality& w, const DeformationQuality& q, bool first) {
  if (first) {
    w = q;
    return;
  }
  if (std::abs(q.volume_change) > std::abs(w.volume_change))
    w.volume_change = q.volume_change;
  w.smallest_section = std::min(w.smallest_section, q.smallest_section);
  w.bulge = std::max(w.bulge, q.bulge);
  w.self_intersections = std::max(w.self_intersections, q.self_intersections);
  w.turned = std::max(w.turned, q.turned);
  w.stretch_mean = std::max(w.stretch_mean, q.stretch_mean);
  w.stretch_max = std::max(w.stretch_max, q.stretch_max);
  w.detail_change = std::max(w.detail_change, q.detail_change);
}

// ---- cases --------------------------------------------------------------

Case cylinder(const std::string& name, double degrees, bool twist) {
  Case c;
  c.name = name;
  TubeSpec ts;
  ts.radius = 0.5;
  ts.length = 4;
  ts.around = 40;
  ts.along = 64;
  ts.cap_rings = 6;
  ts.triangulate = true;
  c.raw = make_capped_tube(ts);
  c.mesh = make_surface_mesh(c.raw, "cylinder");
  const auto joints = make_tube_skeleton({0.4, 2.0, 3.6});
  {
    StarterOptions so;
    if (const char* r = std::getenv("CURVENET_RINGS_PER_BONE"))
      so.rings_per_bone = std::atoi(r);
    if (const char* m = std::getenv("CURVENET_MIDDLE_NODES"))
      so.middle_nodes = std::atoi(m) != 0;
    c.rig = make_starter(c.mesh, joints, so).rig;
  }
  c.skin_joints = joints;
  c.skin = bake_weights(bind(c.mesh, c.rig), 4); // `curvenet bake`'s weights of the same rig
  Pose p;
  p["j1"].rotation =
      Eigen::Quaterniond(Eigen::AngleAxisd(degrees * std::numbers::pi / 180, twist ? Vec3::UnitY() : Vec3::UnitZ()));
  c.poses.push_back(p);
  c.quality.limbs = {{0, 1, 2}};
  return c;
}

/// The cylinder whose net lacks the ring at the bent joint (an imperfect
/// net): the baseline skin is the full net's baked weights.
Case cylinder_without_ring(const std::string& name, double degrees) {
  Case c = cylinder(name, degrees, false);
  std::vector<std::string> ring;
  for (const auto& n : c.rig.nodes)
    if (n.id.rfind("j1_", 0) == 0)
      ring.push_back(n.id);
  c.rig = remove_nodes(c.rig, ring);
  return c;
}

struct HandData {
  SkinnedMesh skin = load_skinned_mesh(kData + "/xr_tools_hand/hand_l.gltf");
  SkinnedMesh clips = load_skinned_mesh(kData + "/xr_tools_hand/hand_l_poses.glb");
};
HandData& hand_data() {
  static HandData h;
  return h;
}

Case hand_base(const std::string& name) {
  Case c;
  c.name = name;
  c.mesh_path = kData + "/xr_tools_hand/hand_l.gltf";
  c.mesh = load_mesh(c.mesh_path);
  c.raw = read_raw_mesh(c.mesh_path);
  c.rig = read_rig(kData + "/xr_tools_hand/example/hand_l.cnrig.json");
  c.skin_joints = hand_data().skin.joints;
  c.skin = weights_of(hand_data().skin);
  return c;
}

/// A joint's bone direction in its own frame (towards its first child).
Vec3 bone_axis(const std::vector<Joint>& joints, const std::string& name, const std::string& child) {
  const Joint& b = joints[joint_index(joints, name)];
  const Joint& k = joints[joint_index(joints, child)];
  return (b.bind.inverse() * k.bind.col(3)).head<3>().normalized();
}

/// The axis about which the Grip clip turns a joint, in its own frame.
Vec3 grip_axis(const std::string& joint) {
  const auto& h = hand_data();
  const int clip = h.clips.find_clip("Grip");
  const auto [t0, t1] = h.clips.clip_range(clip);
  const Pose p = pose_from_clip(h.clips, clip, t1);
  const Eigen::AngleAxisd aa(p.at(joint).rotation);
  return aa.axis();
}

Case hand_fist() {
  Case c = hand_base("hand fist (Grip, hand-drawn net)");
  c.clips = &hand_data().clips;
  const int clip = c.clips->find_clip("Grip");
  c.clip_times.push_back({clip, c.clips->clip_range(clip).second});
  return c;
}

/// The example folder's own fist (fist.pose.json, 14 joint rotations).
Case hand_fist_pose() {
  Case c = hand_base("hand fist (fist.pose.json, hand-drawn net)");
  c.poses.push_back(read_pose(kData + "/xr_tools_hand/example/fist.pose.json"));
  return c;
}

Case hand_twist() {
  Case c = hand_base("hand, middle finger twisted 90 about its bone");
  Pose p;
  p["Middle_Proximal_L"].rotation = Eigen::Quaterniond(
      Eigen::AngleAxisd(std::numbers::pi / 2, bone_axis(c.skin_joints, "Middle_Proximal_L", "Middle_Intermediate_L")));
  c.poses.push_back(p);
  const auto& J = c.skin_joints;
  c.quality.limbs = {{joint_index(J, "Middle_Proximal_L"), joint_index(J, "Middle_Intermediate_L"),
                      joint_index(J, "Middle_Distal_L")}};
  return c;
}

Case hand_flex() {
  Case c = hand_base("hand, middle finger's middle joint flexed 120");
  Pose p;
  p["Middle_Intermediate_L"].rotation =
      Eigen::Quaterniond(Eigen::AngleAxisd(120 * std::numbers::pi / 180, grip_axis("Middle_Intermediate_L")));
  c.poses.push_back(p);
  const auto& J = c.skin_joints;
  c.quality.limbs = {{joint_index(J, "Middle_Proximal_L"), joint_index(J, "Middle_Intermediate_L"),
                      joint_index(J, "Middle_Distal_L")}};
  return c;
}

/// A skinned character with a starter net, posed by frames of its own clips.
Case skinned(const std::string& name, const std::string& path, const std::vector<std::string>& clip_names,
             int frames_per_clip) {
  static std::map<std::string, std::unique_ptr<SkinnedMesh>> loaded;
  Case c;
  c.name = name;
  c.mesh_path = path;
  c.mesh = load_mesh(path);
  c.raw = read_raw_mesh(path);
  auto& s = loaded[path];
  if (!s)
    s = std::make_unique<SkinnedMesh>(load_skinned_mesh(path));
  c.skin_joints = s->joints;
  c.skin = weights_of(*s);
  StarterOptions so;
  if (const char* r = std::getenv("CURVENET_RINGS_PER_BONE"))
    so.rings_per_bone = std::atoi(r);
  if (const char* m = std::getenv("CURVENET_MIDDLE_NODES"))
    so.middle_nodes = std::atoi(m) != 0;
  so.deforming = weighted_joints(*s);
  so.skin = s.get(); // as `curvenet starter` does with a skinned file
  c.rig = make_starter(c.mesh, s->joints, so).rig;
  c.clips = s.get();
  c.normalise = s->skinning_matrices(-1, 0)[0].inverse();
  for (const auto& n : clip_names) {
    // By name, or by the name after an armature's prefix ("AnimalArmature|Walk", "Armature|TRex_Walk").
    int clip = s->find_clip(n);
    for (int k = 0; k < s->num_clips() && clip < 0; ++k) {
      const std::string& cn = s->clip_names[k];
      for (const std::string tail : {"|" + n, "_" + n})
        if (cn.size() > tail.size() && cn.compare(cn.size() - tail.size(), tail.size(), tail) == 0)
          clip = k;
    }
    if (clip < 0)
      throw Error(path + ": no clip named " + n);
    const auto [t0, t1] = s->clip_range(clip);
    for (int k = 0; k < frames_per_clip; ++k)
      c.clip_times.push_back({clip, t0 + (t1 - t0) * k / frames_per_clip});
  }
  return c;
}

// ---- the table ----------------------------------------------------------

std::vector<std::pair<std::string, std::function<Case()>>> all_cases() {
  return {
      {"cylinder bend 90", [] { return cylinder("cylinder bend 90", 90, false); }},
      {"cylinder bend 135", [] { return cylinder("cylinder bend 135", 135, false); }},
      {"cylinder bend 160", [] { return cylinder("cylinder bend 160", 160, false); }},
      {"cylinder without the bent joint's ring, bend 90",
       [] { return cylinder_without_ring("cylinder without the bent joint's ring, bend 90", 90); }},
      {"cylinder without the bent joint's ring, bend 135",
       [] { return cylinder_without_ring("cylinder without the bent joint's ring, bend 135", 135); }},
      {"cylinder twist 90", [] { return cylinder("cylinder twist 90", 90, true); }},
      {"cylinder twist 180", [] { return cylinder("cylinder twist 180", 180, true); }},
      {"hand fist grip", [] { return hand_fist(); }},
      {"hand fist pose", [] { return hand_fist_pose(); }},
      {"hand twist", [] { return hand_twist(); }},
      {"hand flex", [] { return hand_flex(); }},
      {"cesium man walk", [] { return skinned("cesium man walk", kData + "/cesium_man/CesiumMan.glb", {"0"}, 8); }},
      {"horse",
       [] {
         return skinned("horse walk and gallop", kData + "/quaternius/Horse.glb", {"Walk", "Gallop"}, 6);
       }},
      {"wolf",
       [] {
         return skinned("wolf walk and gallop", kData + "/quaternius/Wolf.glb", {"Walk", "Gallop"}, 6);
       }},
      {"trex",
       [] {
         return skinned("trex walk and run", kData + "/quaternius/Trex.glb", {"Walk", "Run"}, 6);
       }},
      {"apatosaurus", [] { return skinned("apatosaurus walk", kData + "/quaternius/Apatosaurus.glb", {"Walk"}, 6); }},
  };
}

/// An ASCII PLY of the welded mesh with vertex colours: a checker of the
/// rest positions (cells of 1/24 of the diagonal), so that a twist shows.
void write_ply(const std::string& path, const SurfaceMesh& mesh, const std::vector<Vec3>& welded) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f)
    throw Error("cannot write " + path);
  std::fprintf(f,
               "ply\nformat ascii 1.0\nelement vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"
               "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face %d\n"
               "property list uchar int vertex_indices\nend_header\n",
               welded.size(), mesh.num_faces());
  const double cell = mesh.bbox_diagonal() / 24;
  for (size_t v = 0; v < welded.size(); ++v) {
    const Vec3& r = mesh.positions[v];
    const long k = static_cast<long>(std::floor(r.x() / cell) + std::floor(r.y() / cell) + std::floor(r.z() / cell));
    const bool dark = (k % 2 + 2) % 2 == 1;
    std::fprintf(f, "%.9g %.9g %.9g %d %d %d\n", welded[v].x(), welded[v].y(), welded[v].z(), dark ? 70 : 235,
                 dark ? 90 : 225, dark ? 150 : 205);
  }
  for (int k = 0; k < mesh.num_faces(); ++k) {
    std::fprintf(f, "%zu", mesh.face(k).size());
    for (int v : mesh.face(k))
      std::fprintf(f, " %d", v);
    std::fprintf(f, "\n");
  }
  std::fclose(f);
}

void run(Case c, const std::string& ply_dir, size_t ply_frame, bool layer_only) {
  c.dominant = dominant_of(c.mesh, c.skin);
  if (c.quality.bone_joints.empty()) {
    // Bones to joints that carry skin weight (IK helpers and poles do not).
    c.quality.bone_joints.assign(c.skin_joints.size(), 0);
    for (size_t k = 0; k < c.skin.joint.size(); ++k)
      if (c.skin.joint[k] >= 0 && c.skin.weight[k] > 0)
        c.quality.bone_joints[c.skin.joint[k]] = 1;
  }
  std::vector<Vec3> rest_in(c.raw.positions.begin(), c.raw.positions.end());
  std::vector<Method> methods;
  methods.push_back({"LBS", [&](size_t f) {
                       return skin_positions(c.skin, rest_in, frame_matrices(c, c.skin_joints, f), Skinning::Linear);
                     }});
  methods.push_back({"DQS", [&](size_t f) {
                       return skin_positions(c.skin, rest_in, frame_matrices(c, c.skin_joints, f),
                                             Skinning::DualQuaternion);
                     }});
  std::vector<std::pair<std::string, BindOptions>> modes;
  for (const DeformMethod m : {DeformMethod::DualQuaternion, DeformMethod::Harmonic, DeformMethod::Gradient}) {
    BindOptions o;
    o.method = m;
    modes.push_back({std::string(to_string(m)) + (m == DeformMethod::DualQuaternion ? " (default)" : ""), o});
  }
  if (layer_only)
    modes.resize(1);
  if (!layer_only) {
    BindOptions o; // the dq mode as it was: the harmonic extension of the curves' weights inside the regions
    o.interior = InteriorWeights::Harmonic;
    modes.push_back({"dq, harmonic interior", o});
  }
  if (!layer_only) {
    BindOptions o; // the gradient mode as it was: targets that do not turn with the sections, and polar rotations
    o.method = DeformMethod::Gradient;
    o.sections = false;
    modes.push_back({"gradient without sections", o});
  }
  std::vector<std::unique_ptr<Binding>> bindings;
  for (const auto& [label, o] : modes) {
    try {
      bindings.push_back(std::make_unique<Binding>(bind(c.mesh, c.rig, o)));
    } catch (const Error& e) {
      std::printf("| %s | %s | bind refused: %s |\n", c.name.c_str(), label.c_str(), e.what());
      return;
    }
    const Binding* b = bindings.back().get();
    methods.push_back({label, [&c, b](size_t f) {
                         std::vector<Vec3> out(b->num_input_vertices());
                         b->deform(frame_matrices(c, b->joints(), f), out);
                         return out;
                       }});
  }
  // The net as a layer over the same skin (layer.hpp), with LBS and DQS.
  SkinnedMesh skin_file;
  skin_file.joints = c.skin_joints;
  skin_file.source = c.name;
  for (int v = 0; v < c.skin.num_vertices(); ++v) {
    std::array<int, 4> j{-1, -1, -1, -1};
    std::array<double, 4> w{0, 0, 0, 0};
    for (int k = 0; k < std::min(c.skin.influences, 4); ++k) {
      j[k] = c.skin.joint[static_cast<size_t>(v) * c.skin.influences + k];
      w[k] = c.skin.weight[static_cast<size_t>(v) * c.skin.influences + k];
    }
    skin_file.vertex_joint.push_back(j);
    skin_file.vertex_weight.push_back(w);
  }
  std::vector<std::unique_ptr<CurveLayer>> layers;
  // Over LBS and DQS with the curves posed as dual quaternions (the
  // default), and over LBS with the curves posed linearly (the harmonic
  // method: a frame is a precomputed sum, docs/deform.md).
  for (const int which : {0, 1, 2}) {
    if (which == 2 && !layer_only)
      continue;
    const Skinning s = which == 1 ? Skinning::DualQuaternion : Skinning::Linear;
    LayerOptions o;
    o.skinning = s;
    if (which == 2)
      o.bind.method = DeformMethod::Harmonic;
    const std::string label = which == 0   ? "layer over LBS"
                              : which == 1 ? "layer over DQS"
                                           : "layer over LBS, linear curves";
    try {
      layers.push_back(std::make_unique<CurveLayer>(bind_layer(c.mesh, c.rig, &skin_file, o)));
    } catch (const Error& e) {
      std::printf("| %s | %s | refused: %s |\n", c.name.c_str(), label.c_str(), e.what());
      continue;
    }
    const CurveLayer* l = layers.back().get();
    methods.push_back({label, [&c, l](size_t f) {
                         std::vector<Vec3> out(l->num_input_vertices());
                         l->deform(frame_matrices(c, l->joints(), f), out);
                         return out;
                       }});
  }
  size_t counted = 0;
  if (layer_only) {
    // The detail counts away from the curves: more than 2 % of the diagonal
    // from every chain of the net, at rest.
    const double far = 0.02 * c.mesh.bbox_diagonal();
    const auto chains = bindings.front()->embedding().chains();
    c.quality.detail_vertices.assign(c.mesh.num_vertices(), 1);
    for (int v = 0; v < c.mesh.num_vertices(); ++v) {
      for (const auto& [id, line] : chains) {
        for (size_t k = 0; k + 1 < line.size() && c.quality.detail_vertices[v]; ++k)
          if (detail::point_segment_distance(c.mesh.positions[v], line[k], line[k + 1]) < far)
            c.quality.detail_vertices[v] = 0;
        if (!c.quality.detail_vertices[v])
          break;
      }
      counted += c.quality.detail_vertices[v];
    }
  }
  std::vector<Row> rows;
  for (const auto& m : methods) {
    Row r;
    r.method = m.name;
    for (size_t f = 0; f < frames_of(c); ++f) {
      const auto posed = c.mesh.welded(m.pose(f));
      const auto M = frame_matrices(c, c.skin_joints, f);
      worst_of(r.worst, measure_deformation(c.mesh, posed, c.skin_joints, M, c.dominant, c.quality), f == 0);
      if (!ply_dir.empty() && f == std::min(ply_frame, frames_of(c) - 1)) {
        std::filesystem::create_directories(ply_dir);
        std::string file = m.name.substr(0, m.name.find(" ("));
        std::replace(file.begin(), file.end(), ' ', '_');
        write_ply(ply_dir + "/" + file + ".ply", c.mesh, posed);
        if (&m == &methods.front())
          write_ply(ply_dir + "/rest.ply", c.mesh, c.mesh.positions);
      }
    }
    rows.push_back(r);
    const auto& w = r.worst;
    const bool limb = !c.quality.limbs.empty();
    char section[32] = "";
    if (limb)
      std::snprintf(section, sizeof(section), "%.2f", w.smallest_section);
    if (layer_only) {
      std::printf("| %s | %s | %+.2f%% | %d | %.3f (%zu of %d vertices) |\n", c.name.c_str(), r.method.c_str(),
                  100 * w.volume_change, w.self_intersections, w.detail_change, counted, c.mesh.num_vertices());
      std::fflush(stdout);
      continue;
    }
    std::printf("| %s | %s | %+.2f%% | %s | %.2f%% | %d | %d | %.1f%% / %.0f%% |\n", c.name.c_str(), r.method.c_str(),
                100 * w.volume_change, section, 100 * w.bulge, w.self_intersections, w.turned, 100 * w.stretch_mean,
                100 * w.stretch_max);
    std::fflush(stdout);
  }
  if (layer_only)
    return;
  // The goals (the default against DQS, and LBS for self-intersection).
  const DeformationQuality &lbs = rows[0].worst, &dqs = rows[1].worst, &ours = rows[2].worst;
  auto mark = [](bool ok) { return ok ? "yes" : "no"; };
  std::printf("| %s | default meets the goals: volume %s, section %s, bulge %s, pairs %s, turned %s | | | | | | |\n",
              c.name.c_str(), mark(std::abs(ours.volume_change) <= std::abs(dqs.volume_change) + 0.005),
              c.quality.limbs.empty() ? "-" : mark(ours.smallest_section >= dqs.smallest_section - 0.02),
              mark(ours.bulge <= dqs.bulge + 1e-12),
              mark(ours.self_intersections <= std::min(lbs.self_intersections, dqs.self_intersections)),
              mark(ours.turned <= dqs.turned));
}

} // namespace

int main(int argc, char** argv) {
  std::vector<std::string> wanted;
  std::string ply_dir;
  size_t ply_frame = std::numeric_limits<size_t>::max(); // the last
  bool layer_only = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--ply" && i + 1 < argc)
      ply_dir = argv[++i];
    else if (a == "--ply-frame" && i + 1 < argc)
      ply_frame = std::strtoul(argv[++i], nullptr, 10);
    else if (a == "--layer")
      layer_only = true;
    else
      wanted.push_back(a);
  }
  if (layer_only)
    std::printf("| case | deformation | volume change | self-intersecting pairs | detail change away from the curves |\n"
                "|---|---|---|---|---|\n");
  else
    std::printf("| case | deformation | volume change | smallest section / rest | bulge (%% of diagonal) | "
                "self-intersecting pairs | turned > 90 deg | edge stretch mean / max |\n"
                "|---|---|---|---|---|---|---|---|\n");
  for (const auto& [name, make] : all_cases()) {
    bool take = wanted.empty();
    for (const auto& w : wanted)
      take = take || name.rfind(w, 0) == 0;
    if (!take)
      continue;
    try {
      run(make(), ply_dir, ply_frame, layer_only);
    } catch (const Error& e) {
      std::printf("| %s | (refused) | %s |\n", name.c_str(), e.what());
    }
  }
  return 0;
}
