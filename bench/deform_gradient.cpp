// The gradient mode's variants against the other modes and linear blend
// skinning, on the same inputs (docs/deform.md, "The gradient mode"; the
// modes against the skins are bench/deform_quality, their speed bench/deform_bench):
//
//   build/bin/deform_gradient quality   volume, inverted triangles and detail: the example fist, a 90-degree
//                                       twist of a finger, a 90-degree tube bend
//   build/bin/deform_gradient families  the transfer test's posed agreement across tessellations, both modes
//
// One run on one machine; timings are medians of repeated frames.

#include "curvenet/bake.hpp"
#include "curvenet/deform.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/weights.hpp"
#include "generate/tube.hpp"
#include "transfer_check.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

using namespace curvenet;

namespace {

const std::string kData = CURVENET_DATA_DIR;

struct Tris {
  std::vector<std::array<int, 3>> t;
};
/// The welded mesh's faces as a fan of triangles each (input vertex ids through the weld are not needed:
/// positions come per welded vertex).
Tris triangles(const SurfaceMesh& m) {
  Tris out;
  for (int f = 0; f < m.num_faces(); ++f) {
    const auto face = m.face(f);
    for (size_t k = 1; k + 1 < face.size(); ++k)
      out.t.push_back({face[0], face[k], face[k + 1]});
  }
  return out;
}

double volume(const Tris& t, const std::vector<Vec3>& p) {
  double v = 0;
  for (const auto& f : t.t)
    v += p[f[0]].dot(p[f[1]].cross(p[f[2]])) / 6;
  return v;
}

Vec3 normal(const std::array<int, 3>& f, const std::vector<Vec3>& p) {
  return (p[f[1]] - p[f[0]]).cross(p[f[2]] - p[f[0]]);
}

/// Triangles whose normal turns more than 120 degrees against a reference,
/// and those whose area falls below 10% of rest.
std::pair<int, int> inverted(const Tris& t, const std::vector<Vec3>& rest, const std::vector<Vec3>& ref,
                             const std::vector<Vec3>& p) {
  int turned = 0, small = 0;
  const double c120 = std::cos(120 * std::numbers::pi / 180);
  for (const auto& f : t.t) {
    const Vec3 a = normal(f, p), b = normal(f, ref), r = normal(f, rest);
    if (a.norm() > 0 && b.norm() > 0 && a.normalized().dot(b.normalized()) < c120)
      ++turned;
    if (a.norm() < 0.1 * r.norm())
      ++small;
  }
  return {turned, small};
}

/// Triangles whose normal turns more than 120 degrees against their rest
/// normal carried by their dominant joint's rotation (a fold of the mesh
/// itself, whatever a reference does).
int folded(const Tris& t, const std::vector<Vec3>& rest, const std::vector<Vec3>& p, const std::vector<int>& joint_of,
           const std::vector<Mat4>& M) {
  int n = 0;
  const double c120 = std::cos(120 * std::numbers::pi / 180);
  for (const auto& f : t.t) {
    const Vec3 a = normal(f, p), r = normal(f, rest);
    const Vec3 expect = M[joint_of[f[0]]].topLeftCorner<3, 3>() * r;
    if (a.norm() > 0 && expect.norm() > 0 && a.normalized().dot(expect.normalized()) < c120)
      ++n;
  }
  return n;
}

/// Mean-curvature normal length per vertex (cotangent Laplacian of the positions over the barycentric area).
std::vector<double> mean_curvature(const Tris& t, const std::vector<Vec3>& p) {
  std::vector<Vec3> lap(p.size(), Vec3::Zero());
  std::vector<double> area(p.size(), 0);
  for (const auto& f : t.t) {
    const double a = 0.5 * normal(f, p).norm();
    for (int k = 0; k < 3; ++k) {
      const int i = f[k], j = f[(k + 1) % 3], o = f[(k + 2) % 3];
      const Vec3 u = p[i] - p[o], w = p[j] - p[o];
      const double cr = u.cross(w).norm();
      const double cot = cr > 0 ? u.dot(w) / cr : 0;
      lap[i] += 0.5 * cot * (p[j] - p[i]);
      lap[j] += 0.5 * cot * (p[i] - p[j]);
      area[f[k]] += a / 3;
    }
  }
  std::vector<double> h(p.size());
  for (size_t v = 0; v < p.size(); ++v)
    h[v] = area[v] > 0 ? lap[v].norm() / (2 * area[v]) : 0;
  return h;
}

/// The mean relative change of the mean curvature at vertices away from the net's curves.
double detail_change(const Tris& t, const std::vector<Vec3>& rest, const std::vector<Vec3>& p,
                     const std::vector<char>& far) {
  const auto h0 = mean_curvature(t, rest), h1 = mean_curvature(t, p);
  double num = 0, den = 0;
  for (size_t v = 0; v < rest.size(); ++v)
    if (far[v]) {
      num += std::abs(h1[v] - h0[v]);
      den += h0[v];
    }
  return den > 0 ? num / den : 0;
}

/// Vertices farther than `d` from every CutChain point.
std::vector<char> far_from_curves(const std::vector<Vec3>& rest, const Binding& b, double d) {
  std::vector<char> far(rest.size(), 1);
  for (const auto& [id, pts] : b.embedding().chains())
    for (const Vec3& q : pts)
      for (size_t v = 0; v < rest.size(); ++v)
        if (far[v] && (rest[v] - q).norm() < d)
          far[v] = 0;
  return far;
}

struct Case {
  std::string name;
  SurfaceMesh mesh;
  Rig rig;
  Pose pose;
  std::vector<Vec3> lbs; ///< the LBS reference, per welded vertex
  std::string lbs_name;
};

BindOptions with(DeformMethod m) {
  BindOptions o;
  o.method = m;
  return o;
}

void quality() {
  std::vector<Case> cases;
  const std::string ex = kData + "/xr_tools_hand/example/";
  {
    Case c;
    c.name = "fist (example rig)";
    c.mesh = load_mesh(ex + "hand_l_welded.obj");
    c.rig = read_rig(ex + "hand_l.cnrig.json");
    c.pose = read_pose(ex + "fist.pose.json");
    c.lbs = c.mesh.welded(read_raw_mesh(ex + "fist_lbs.obj").positions);
    c.lbs_name = "fist_lbs.obj (the file's skin)";
    cases.push_back(c);
  }
  {
    // A 90-degree twist of the middle finger's proximal bone about its own axis.
    Case c;
    c.name = "90-degree twist (Middle_Proximal_L)";
    c.mesh = load_mesh(ex + "hand_l_welded.obj");
    c.rig = read_rig(ex + "hand_l.cnrig.json");
    const Joint* bone = nullptr;
    const Joint* child = nullptr;
    for (const auto& j : c.rig.joints) {
      if (j.name == "Middle_Proximal_L")
        bone = &j;
      if (j.name == "Middle_Intermediate_L")
        child = &j;
    }
    const Vec3 axis = (bone->bind.inverse() * child->bind.block<4, 1>(0, 3)).head<3>().normalized();
    c.pose["Middle_Proximal_L"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 2, axis));
    // The file's own skin on the same pose: the glTF hand, welded the same way.
    const SkinnedMesh skin = load_skinned_mesh(kData + "/xr_tools_hand/hand_l.gltf");
    const SurfaceMesh g = load_mesh(kData + "/xr_tools_hand/hand_l.gltf");
    const auto moved = skin_positions(skin, read_raw_mesh(kData + "/xr_tools_hand/hand_l.gltf").positions,
                                      skinning_matrices(skin.joints, c.pose));
    // hand_l_welded.obj is hand_l.gltf welded: match vertices by rest position.
    std::vector<Vec3> ref(c.mesh.num_vertices());
    const auto gw = g.welded(moved);
    for (int v = 0; v < c.mesh.num_vertices(); ++v) {
      int best = 0;
      double bd = 1e300;
      for (int u = 0; u < g.num_vertices(); ++u) {
        const double d = (g.positions[u] - c.mesh.positions[v]).squaredNorm();
        if (d < bd) {
          bd = d;
          best = u;
        }
      }
      ref[v] = gw[best];
    }
    c.lbs = ref;
    c.lbs_name = "the glTF's skin";
    cases.push_back(c);
  }
  {
    Case c;
    c.name = "90-degree tube bend";
    TubeSpec ts;
    ts.around = 32;
    ts.along = 48;
    ts.cap_rings = 6;
    ts.triangulate = true;
    c.mesh = make_surface_mesh(make_capped_tube(ts), "tube");
    c.rig = make_tube_net();
    c.pose["mid"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitZ()));
    // LBS with automatic (blend-zone) weights per vertex.
    const auto M = skinning_matrices(c.rig.joints, c.pose);
    c.lbs.resize(c.mesh.num_vertices());
    for (int v = 0; v < c.mesh.num_vertices(); ++v) {
      Eigen::Vector4d x = Eigen::Vector4d::Zero();
      for (const auto& [j, w] : auto_weights(c.rig.joints, c.mesh.positions[v]))
        x += w * (M[j] * c.mesh.positions[v].homogeneous());
      c.lbs[v] = x.head<3>();
    }
    c.lbs_name = "LBS, automatic weights";
    cases.push_back(c);
  }
  std::printf("| case | deformation | volume change | turned > 120 deg vs LBS | folded | area < 10%% of rest | detail "
              "change away from curves |\n|---|---|---|---|---|---|---|\n");
  for (const auto& c : cases) {
    const Tris t = triangles(c.mesh);
    const auto& rest = c.mesh.positions;
    const double v0 = volume(t, rest);
    const Binding hb = bind(c.mesh, c.rig, with(DeformMethod::Harmonic));
    const auto far = far_from_curves(rest, hb, 2 * c.mesh.mean_edge_length());
    // Each welded vertex's dominant joint (the largest harmonic weight).
    std::vector<int> joint_of(c.mesh.num_vertices(), 0);
    {
      const SkinWeights top = bake_weights(hb, 1);
      for (size_t i = 0; i < c.mesh.input_to_welded.size(); ++i)
        joint_of[c.mesh.input_to_welded[i]] = std::max(0, top.joint[i]);
    }
    const auto M = skinning_matrices(hb.joints(), c.pose);
    auto row = [&](const std::string& label, const std::vector<Vec3>& p) {
      const auto [turned, small] = inverted(t, rest, c.lbs, p);
      std::printf("| %s | %s | %+.2f%% | %d | %d | %d | %.1f%% |\n", c.name.c_str(), label.c_str(),
                  100 * (volume(t, p) / v0 - 1), turned, folded(t, rest, p, joint_of, M), small,
                  100 * detail_change(t, rest, p, far));
    };
    row(c.lbs_name, c.lbs);
    const char* names[] = {"dq (default)",
                           "harmonic",
                           "gradient (sections)",
                           "gradient without sections (polar)",
                           "gradient without sections (quaternion blend)",
                           "gradient, not cut-aware",
                           "gradient with curve frames"};
    for (const int variant : {0, 1, 2, 3, 4, 5, 6}) {
      BindOptions o = with(variant == 0   ? DeformMethod::DualQuaternion
                           : variant == 1 ? DeformMethod::Harmonic
                                          : DeformMethod::Gradient);
      o.sections = variant != 3 && variant != 4;
      if (variant == 4)
        o.rotation_blend = BindOptions::RotationBlend::Quaternion;
      if (variant == 5)
        o.cut_aware = false;
      if (variant == 6)
        o.curve_frames = true;
      const Binding b = variant == 1 ? hb : bind(c.mesh, c.rig, o);
      std::vector<Vec3> out(b.num_input_vertices());
      b.deform(skinning_matrices(b.joints(), c.pose), out);
      row(names[variant], c.mesh.welded(out));
    }
  }
}

void families() {
  std::printf("| family | mode | rows | mean posed mean | max posed mean | max posed max | rows within bound |\n"
              "|---|---|---|---|---|---|---|\n");
  for (const char* fam : {"hand", "spot", "penguin"}) {
    for (const int variant : {3, 0, 1, 2}) {
      BindOptions o = with(variant == 3   ? DeformMethod::DualQuaternion
                           : variant == 0 ? DeformMethod::Harmonic
                                          : DeformMethod::Gradient);
      o.curve_frames = variant == 2;
      const auto rows = check::run_family(fam, kData, {}, nullptr, o);
      double sum = 0, worst_mean = 0, worst_max = 0;
      int pass = 0;
      for (const auto& r : rows) {
        sum += r.rest.percent(r.posed.mean);
        worst_mean = std::max(worst_mean, r.rest.percent(r.posed.mean));
        worst_max = std::max(worst_max, r.rest.percent(r.posed.max));
        pass += r.pass_mean() && r.pass_max();
      }
      std::printf("| %s | %s | %zu | %.3f%% | %.3f%% | %.3f%% | %d |\n", fam,
                  variant == 3   ? "dq"
                  : variant == 0 ? "harmonic"
                  : variant == 1 ? "gradient"
                                 : "gradient with curve frames",
                  rows.size(), rows.empty() ? 0.0 : sum / rows.size(), worst_mean, worst_max, pass);
    }
  }
}

} // namespace

int main(int argc, char** argv) {
  const std::string what = argc > 1 ? argv[1] : "all";
  if (what == "quality" || what == "all")
    quality();
  if (what == "families" || what == "all")
    families();
  return 0;
}
