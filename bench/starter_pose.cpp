// Starter nets, measured by how they pose (issue 14's yardstick): for each
// skinned character, the starter net made from its own skeleton, bound in
// the dq, harmonic and gradient modes, posed by every clip, against the
// file's own skin posed by the same clip.
//
//   build/bin/starter_pose [--rules] [MESH.glb [CLIPS.glb]]...
//     default: the shared hand (its 35 clips), its low-resolution version
//     and our decimated one (tests/data/hand/hand_l_decimated.glb, 610 faces; the
//     same clips), CesiumMan (its walk, 6 frames), RiggedSimple, and the
//     four Quaternius animals and our decimations of them (tests/data/
//     quaternius; their walks and gallops, 6 frames each)
//
// Per character: the net's counts (rings, bending joints, components,
// joins, messages), then per mode the mean and max distance to the skin
// (% of the diagonal; mean over clips of the mean over vertices), the worst
// volume change against the skin's (points), and the most triangles turned
// more than 120 degrees against the skin in any clip, and how many poses
// meet each of issue 14's goals. The nets are made as `curvenet starter`
// makes them from the file: the nodes weighted by its own skin
// (CURVENET_RULE_WEIGHTS=1: by the weight rule, as with a bare skeleton).
// With --rules: the automatic weight rules (docs/weights.md), each measured
// on the starter nets it makes.

#include "curvenet/deform.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/quality.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <string>
#include <vector>

using namespace curvenet;

namespace {

const std::string kData = CURVENET_DATA_DIR;
const std::string kOwnData = CURVENET_OWN_DATA_DIR; // tests/data: meshes made here (scripts/make_decimated.py)

struct Character {
  std::string mesh, clips;
  int samples_per_clip = 1;      ///< 1: each clip's last key; more: evenly over the clip
  std::vector<std::string> only; ///< clip names to pose by (by their last part after '|' or '_'); empty for all
};

std::vector<std::array<int, 3>> triangles(const SurfaceMesh& m) {
  std::vector<std::array<int, 3>> t;
  for (int f = 0; f < m.num_faces(); ++f) {
    const auto face = m.face(f);
    for (size_t k = 1; k + 1 < face.size(); ++k)
      t.push_back({face[0], face[k], face[k + 1]});
  }
  return t;
}

int turned(const std::vector<std::array<int, 3>>& t, const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  int n = 0;
  const double c120 = std::cos(120 * std::numbers::pi / 180);
  for (const auto& f : t) {
    const Vec3 na = (a[f[1]] - a[f[0]]).cross(a[f[2]] - a[f[0]]), nb = (b[f[1]] - b[f[0]]).cross(b[f[2]] - b[f[0]]);
    if (na.norm() > 0 && nb.norm() > 0 && na.normalized().dot(nb.normalized()) < c120)
      ++n;
  }
  return n;
}

/// A character loaded once: its mesh, its own skin, the clips that pose it.
struct Loaded {
  SurfaceMesh mesh;
  SkinnedMesh skin, clips;
  RawMesh raw;
  std::vector<std::array<int, 3>> tris;
  std::vector<int> dominant; ///< per welded vertex, its strongest joint in the skin
  double diag = 0, v0 = 0;
  explicit Loaded(const Character& ch)
      : mesh(load_mesh(ch.mesh)), skin(load_skinned_mesh(ch.mesh)), clips(load_skinned_mesh(ch.clips)),
        raw(read_raw_mesh(ch.mesh)), tris(triangles(mesh)), dominant(dominant_joints(mesh, skin)),
        diag(mesh.bbox_diagonal()), v0(mesh.enclosed_volume(mesh.positions)) {}
};

/// A binding posed by every clip against the skin posed by the same clip.
struct Scores {
  double mean = 0, max = 0, worst_volume = 0; ///< % of the diagonal; points against the skin's change
  int poses = 0, most_turned = 0, volume_ok = 0, turned_ok = 0, mean_ok = 0;
  /// Folded triangles (turned over against their rest normal carried by
  /// their joint) in the pose where ours fold most beyond the skin's, and
  /// the poses where ours fold no more than the skin's.
  int folds = 0, skin_folds = 0, folds_ok = 0;
};

Scores pose_all(const Loaded& c, const Binding& b, int samples_per_clip, const std::vector<std::string>& only) {
  // The similarity a file's armature puts around its whole skeleton (Blender's
  // exports scale it by 100), taken off every frame so that volumes and
  // distances compare with the rest mesh.
  const Mat4 undo = c.clips.skinning_matrices(-1, 0)[0].inverse();
  auto normalised = [&](std::vector<Mat4> m) {
    for (auto& x : m)
      x = undo * x;
    return m;
  };
  auto wanted = [&](int k) {
    if (only.empty())
      return true;
    const std::string& n = c.clips.clip_names[k];
    for (const auto& w : only)
      for (const std::string tail : {w, "|" + w, "_" + w})
        if (n.size() >= tail.size() && n.compare(n.size() - tail.size(), tail.size(), tail) == 0)
          return true;
    return false;
  };
  Scores sc;
  double sum = 0;
  std::vector<Vec3> ours(b.num_input_vertices());
  for (int k = 0; k < c.clips.num_clips(); ++k) {
    if (!wanted(k))
      continue;
    const auto [t0, t1] = c.clips.clip_range(k);
    for (int s = 0; s < samples_per_clip; ++s) {
      const double t = samples_per_clip == 1 ? t1 : t0 + (t1 - t0) * s / (samples_per_clip - 1);
      b.deform(normalised(clip_skinning_matrices(b.joints(), c.clips, k, t)), ours);
      const std::vector<Mat4> skinning = normalised(clip_skinning_matrices(c.skin.joints, c.clips, k, t));
      const auto theirs = skin_positions(c.skin, c.raw.positions, skinning);
      double d = 0;
      for (size_t i = 0; i < ours.size(); ++i) {
        const double e = (ours[i] - theirs[i]).norm();
        d += e;
        sc.max = std::max(sc.max, e);
      }
      sum += d / ours.size();
      sc.mean_ok += d / ours.size() < 0.01 * c.diag;
      ++sc.poses;
      const auto wo = c.mesh.welded(ours), wt = c.mesh.welded(theirs);
      // Volume changes in points of the rest volume; the goal: ours no
      // worse than the skin's plus 3 points.
      const double vo = 100 * (c.mesh.enclosed_volume(wo) / c.v0 - 1),
                   vt = 100 * (c.mesh.enclosed_volume(wt) / c.v0 - 1);
      if (std::abs(vo - vt) > std::abs(sc.worst_volume))
        sc.worst_volume = vo - vt;
      sc.volume_ok += std::abs(vo) <= std::abs(vt) + 3;
      const int n = turned(c.tris, wo, wt);
      sc.most_turned = std::max(sc.most_turned, n);
      sc.turned_ok += n == 0;
      const int fo = turned_triangles(c.mesh, wo, skinning, c.dominant),
                ft = turned_triangles(c.mesh, wt, skinning, c.dominant);
      if (sc.poses == 1 || fo - ft > sc.folds - sc.skin_folds) {
        sc.folds = fo;
        sc.skin_folds = ft;
      }
      sc.folds_ok += fo <= ft;
    }
  }
  sc.mean = 100 * sum / std::max(sc.poses, 1) / c.diag;
  sc.max *= 100 / c.diag;
  return sc;
}

std::string name_of(const std::string& path) {
  return path.substr(path.find_last_of('/') + 1);
}

void measure(const Character& ch) {
  const Loaded c(ch);
  std::printf("%s (%d faces, %zu joints), clips from %s\n", name_of(ch.mesh).c_str(), c.mesh.num_faces(),
              c.skin.joints.size(), name_of(ch.clips).c_str());
  StarterResult st;
  double starter_ms = 0;
  try {
    const auto t0 = std::chrono::steady_clock::now();
    StarterOptions so;
    so.deforming = weighted_joints(c.skin);
    if (!std::getenv("CURVENET_RULE_WEIGHTS"))
      so.skin = &c.skin; // as `curvenet starter` does with a skinned file
    st = make_starter(c.mesh, c.skin.joints, so);
    starter_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  } catch (const Error& e) {
    std::printf("  starter refused: %s\n\n", e.what());
    return;
  }
  std::printf("  net: %d rings, %zu nodes, %zu profiles; %zu of %zu joints have a ring; %d components, %d joins, %d "
              "unjoined; made in %.0f ms\n",
              st.rings, st.rig.nodes.size(), st.rig.profiles.size(), c.skin.joints.size() - st.ringless.size(),
              c.skin.joints.size(), st.net_components, st.joins, st.unjoined, starter_ms);
  for (const auto& [joint, why] : st.ringless)
    std::printf("    no ring at %s: %s\n", joint.c_str(), why.c_str());
  for (const auto& m : st.messages)
    if (m.find("dropped") != std::string::npos || m.find("not joined") != std::string::npos ||
        m.find("abandoned") != std::string::npos)
      std::printf("    %s\n", m.c_str());
  std::printf("  | mode | mean distance to the skin | max | worst volume change vs the skin's | most turned > 120 deg "
              "against the skin | folded, ours / the skin's | poses within the goals: volume, 0 turned, mean < 1%%, "
              "folding no more than the skin |\n"
              "  |---|---|---|---|---|---|---|\n");
  for (const auto method : {DeformMethod::DualQuaternion, DeformMethod::Harmonic, DeformMethod::Gradient}) {
    BindOptions o;
    o.method = method;
    const Scores sc = pose_all(c, bind(c.mesh, st.rig, o), ch.samples_per_clip, ch.only);
    std::printf("  | %s | %.3f%% | %.3f%% | %+.2f | %d | %d / %d | %d, %d, %d, %d of %d |\n", to_string(method),
                sc.mean, sc.max, sc.worst_volume, sc.most_turned, sc.folds, sc.skin_folds, sc.volume_ok, sc.turned_ok,
                sc.mean_ok, sc.folds_ok, sc.poses);
  }
  std::printf("\n");
}

/// The automatic weight rules of docs/weights.md, measured on the starter
/// nets they make (the rule sets the nodes' weights, and the blend zone
/// where a trunk's ring sits), in the default mode.
void measure_rules(const Character& ch) {
  const Loaded c(ch);
  std::printf("%s, starter nets by weight rule (%s mode)\n", name_of(ch.mesh).c_str(), to_string(BindOptions{}.method));
  std::printf("  | rule | blend | mean | max | worst volume vs the skin's | poses within the volume goal |\n"
              "  |---|---|---|---|---|---|\n");
  for (const auto& [rule, blend] : {std::pair{WeightRule::Segment, 0.0}, std::pair{WeightRule::BlendZone, 0.1},
                                    std::pair{WeightRule::BlendZone, 0.2}, std::pair{WeightRule::BlendZone, 0.3},
                                    std::pair{WeightRule::BlendZone, 0.5}}) {
    StarterOptions so;
    so.deforming = weighted_joints(c.skin);
    so.weights.rule = rule;
    so.weights.blend = blend;
    const std::string name = rule == WeightRule::Segment ? "segment" : "blend-zone";
    try {
      const StarterResult st = make_starter(c.mesh, c.skin.joints, so);
      BindOptions bo;
      bo.weights = so.weights;
      const Scores sc = pose_all(c, bind(c.mesh, st.rig, bo), ch.samples_per_clip, ch.only);
      std::printf("  | %s | %.1f | %.3f%% | %.3f%% | %+.2f | %d of %d |\n", name.c_str(), blend, sc.mean, sc.max,
                  sc.worst_volume, sc.volume_ok, sc.poses);
    } catch (const Error& e) {
      std::printf("  | %s | %.1f | refused: %s |\n", name.c_str(), blend, e.what());
    }
  }
  std::printf("\n");
}

} // namespace

int main(int argc, char** argv) {
  const bool rules = argc > 1 && std::string(argv[1]) == "--rules";
  std::vector<Character> chars;
  for (int i = rules ? 2 : 1; i < argc; ++i) {
    Character c;
    c.mesh = argv[i];
    c.clips = i + 1 < argc && std::string(argv[i + 1]).find(".glb") != std::string::npos ? argv[++i] : c.mesh;
    chars.push_back(c);
  }
  if (chars.empty()) {
    const std::string h = kData + "/xr_tools_hand/";
    chars = {{h + "hand_l_poses.glb", h + "hand_l_poses.glb", 1},
             {h + "Hand_low_L.gltf", h + "hand_l_poses.glb", 1},
             {kOwnData + "/hand/hand_l_decimated.glb", h + "hand_l_poses.glb", 1},
             {kData + "/cesium_man/CesiumMan.glb", kData + "/cesium_man/CesiumMan.glb", 6},
             {kData + "/rigged_simple/RiggedSimple.glb", kData + "/rigged_simple/RiggedSimple.glb", 6}};
    for (const char* a : {"Horse", "Wolf", "Trex", "Apatosaurus"})
      for (const std::string& path :
           {kData + "/quaternius/" + a + ".glb", kOwnData + "/quaternius/" + a + "_decimated.glb"})
        chars.push_back({path, path, 6, {"Walk", "Gallop", "TRex_Walk", "Apatosaurus_Walk"}});
  }
  for (const auto& c : chars) {
    try {
      if (rules)
        measure_rules(c);
      else
        measure(c);
    } catch (const Error& e) {
      std::printf("%s: %s\n\n", c.mesh.c_str(), e.what());
    }
  }
  return 0;
}
