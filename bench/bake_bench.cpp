// Baked skins, measured (docs/bake.md).
//
//   build/bin/bake_bench fidelity   the shared hand's 35 clips: LBS with the baked weights (k = 4, 8, all) and
//                                   with fitted weights, against the full curvenet deformation and against the
//                                   hand's own artist skin
//   build/bin/bake_bench transfer   topology independence: curvenet baked on every tessellation of the hand, spot
//                                   and CesiumMan, against Robust Skin Weight Transfer (Abdrashitov et al. 2023)
//                                   of the source's skin to each of them; every result posed by the same poses
//                                   and compared with the posed source (surface distance, % of the diagonal)
//   build/bin/bake_bench anchor     the fit without clips against its anchor, the weights-only solve of smooth
//                                   skinning decomposition (Dem Bones'; weights_anchor.hpp), on the same
//                                   training poses of the skeleton, measured on the clips neither saw: the hand's
//                                   35, CesiumMan's walk and the four animals' walks, gallops and runs; fidelity,
//                                   time, sparsity
//   build/bin/bake_bench floor      the closest any linear skin can come to the rig on the same clips' frames
//                                   (the distance to the convex hull of where the vertex's joints carry it), beside
//                                   the fitted bake's worst vertex: where the worst-vertex goal is out of reach,
//                                   and how far helper joints keyed half way between two joints would bring it
//   build/bin/bake_bench helpers    those helpers fitted as the bake fits, measured on the clips (the dq rig)
//   build/bin/bake_bench speed      `curvenet bake` (harmonic and fitted) as a process, on all cores and on
//                                   one (taskset), on characters of 1.8k to 9k vertices; medians of 5
//
// One run on one machine; the anchor and speed tables report times (wall clock).

#include "core/convex_least_squares.hpp"
#include "core/dual_quaternion.hpp"
#include "core/polygon.hpp"
#include "curvenet/bake.hpp"
#include "curvenet/compare.hpp"
#include "curvenet/deform.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/subdivide.hpp"
#include "curvenet/transfer.hpp"
#include "cut/cut_mesh.hpp"
#include "trace/trace_mesh.hpp"
#include "transfer_check.hpp"
#include "weights_anchor.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <unistd.h>
#include <filesystem>
#include <memory>
#include <map>
#include <numbers>
#include <numeric>
#include <set>
#include <string>
#include <thread>
#include <vector>

using namespace curvenet;

namespace {

const std::string kData = CURVENET_DATA_DIR;
const std::string kOwn = CURVENET_OWN_DATA_DIR; // tests/data: meshes made here (scripts/make_decimated.py)

/// Dense per-vertex weights (rows: welded vertices of a mesh; columns: joints).
using Dense = Eigen::MatrixXd;

std::vector<Vec3> rest_of(const Binding& b) {
  std::vector<Vec3> rest(b.num_input_vertices());
  b.deform(std::vector<Mat4>(b.joints().size(), Mat4::Identity()), rest);
  return rest;
}

/// Per-vertex distances between two position sets on one topology: mean and max.
std::pair<double, double> vertex_gap(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  double sum = 0, mx = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double d = (a[i] - b[i]).norm();
    sum += d;
    mx = std::max(mx, d);
  }
  return {sum / std::max<size_t>(1, a.size()), mx};
}

/// LBS with all of each vertex's harmonic weights (no top-k).
std::vector<Vec3> lbs_all(const Binding& b, const std::vector<Vec3>& rest, const std::vector<Mat4>& M) {
  std::vector<Vec3> out(rest.size());
  std::vector<std::pair<int, double>> s;
  for (size_t v = 0; v < rest.size(); ++v) {
    b.harmonic_weights(static_cast<int>(v), s);
    Eigen::Vector4d x = Eigen::Vector4d::Zero();
    for (const auto& [j, w] : s)
      x += w * (M[j] * rest[v].homogeneous());
    out[v] = x.head<3>();
  }
  return out;
}

struct Stat {
  double mean = 0, max = 0;
  int n = 0;
  void add(std::pair<double, double> g) {
    mean += g.first;
    max = std::max(max, g.second);
    ++n;
  }
  [[nodiscard]] double mean_of() const { return n ? mean / n : 0; }
};

double influences(const SkinWeights& w, int* most = nullptr) {
  int used = 0, mx = 0;
  for (int v = 0; v < w.num_vertices(); ++v) {
    int c = 0;
    for (int i = 0; i < w.influences; ++i)
      c += w.joint[static_cast<size_t>(v) * w.influences + i] >= 0;
    used += c;
    mx = std::max(mx, c);
  }
  if (most)
    *most = mx;
  return static_cast<double>(used) / std::max(1, w.num_vertices());
}

void fidelity() {
  const std::string d = kData + "/xr_tools_hand/";
  const std::string mesh_file = d + "hand_l.gltf";
  const SurfaceMesh mesh = load_mesh(mesh_file);
  const SkinnedMesh file_skin = load_skinned_mesh(mesh_file);
  const SkinnedMesh clips = load_skinned_mesh(d + "hand_l_poses.glb");
  const double diag = mesh.bbox_diagonal();
  const RawMesh raw = read_raw_mesh(mesh_file);
  std::printf(
      "Fidelity of the bake: hand_l.gltf (%d faces), %d clips (each clip's last key), distances per vertex as %% "
      "of the diagonal; mean is the mean over clips of the mean over vertices, max the largest\n\n",
      mesh.num_faces(), clips.num_clips());
  struct RigCase {
    const char* name;
    Rig rig;
  };
  std::vector<RigCase> rigs = {{"example rig", read_rig(d + "example/hand_l.cnrig.json")},
                               {"starter net", make_starter(mesh, file_skin.joints).rig}};
  for (auto& rc : rigs) {
    const Binding b = bind(mesh, rc.rig);
    const auto rest = rest_of(b);
    std::vector<std::vector<Mat4>> poses, even;
    std::vector<int> odd_index;
    for (int c = 0; c < clips.num_clips(); ++c) {
      poses.push_back(clip_skinning_matrices(b.joints(), clips, c, clips.clip_range(c).second));
      (c % 2 == 0 ? static_cast<void>(even.push_back(poses.back())) : static_cast<void>(odd_index.push_back(c)));
    }
    const SkinWeights w4 = bake_weights(b, 4), w8 = bake_weights(b, 8);
    const SkinWeights fit_all = fit_weights(b, poses, 4), fit_even = fit_weights(b, even, 4);
    std::printf("%s (%zu nodes, %zu profiles): harmonic influences per vertex %.2f\n", rc.name, rc.rig.nodes.size(),
                rc.rig.profiles.size(), b.report().mean_influences);
    std::printf(
        "| skin | joints per vertex (mean / max) | vs full curvenet: mean | max | vs artist skin: mean | max |\n"
        "|---|---|---|---|---|---|\n");
    auto row = [&](const char* label, auto&& positions, double infl, int most, const std::vector<int>* only) {
      Stat full, artist;
      for (int c = 0; c < clips.num_clips(); ++c) {
        if (only && std::find(only->begin(), only->end(), c) == only->end())
          continue;
        std::vector<Vec3> cn(rest.size());
        b.deform(poses[c], cn);
        const auto p = positions(c);
        full.add(vertex_gap(p, cn));
        // The artist skin in the same pose: the file's joints, the clip's pose by name.
        const auto art = skin_positions(file_skin, raw.positions,
                                        clip_skinning_matrices(file_skin.joints, clips, c, clips.clip_range(c).second));
        artist.add(vertex_gap(p, art));
      }
      std::printf("| %s | %.2f / %d | %.3f%% | %.3f%% | %.3f%% | %.3f%% |\n", label, infl, most,
                  100 * full.mean_of() / diag, 100 * full.max / diag, 100 * artist.mean_of() / diag,
                  100 * artist.max / diag);
    };
    int most = 0, hmax = 0;
    {
      std::vector<std::pair<int, double>> sv;
      for (int v = 0; v < b.num_input_vertices(); ++v) {
        b.harmonic_weights(v, sv);
        hmax = std::max(hmax, static_cast<int>(sv.size()));
      }
    }
    row(
        "full curvenet deformation",
        [&](int c) {
          std::vector<Vec3> cn(rest.size());
          b.deform(poses[c], cn);
          return cn;
        },
        b.report().mean_influences, hmax, nullptr);
    row(
        "LBS, all harmonic weights", [&](int c) { return lbs_all(b, rest, poses[c]); }, b.report().mean_influences,
        hmax, nullptr);
    double i8 = influences(w8, &most);
    row(
        "LBS, baked k = 8", [&](int c) { return skin_positions(w8, rest, poses[c]); }, i8, most, nullptr);
    double i4 = influences(w4, &most);
    row(
        "LBS, baked k = 4", [&](int c) { return skin_positions(w4, rest, poses[c]); }, i4, most, nullptr);
    double ia = influences(fit_all, &most);
    row(
        "LBS, fitted k = 4, on all clips (in sample)", [&](int c) { return skin_positions(fit_all, rest, poses[c]); },
        ia, most, nullptr);
    double ie = influences(fit_even, &most);
    row(
        "LBS, fitted k = 4 on the even clips, on the odd ones",
        [&](int c) { return skin_positions(fit_even, rest, poses[c]); }, ie, most, &odd_index);
    row(
        "LBS, baked k = 4, on the odd clips", [&](int c) { return skin_positions(w4, rest, poses[c]); }, i4, most,
        &odd_index);
    {
      // The artist skin itself, against the full deformation.
      Stat full;
      for (int c = 0; c < clips.num_clips(); ++c) {
        std::vector<Vec3> cn(rest.size());
        b.deform(poses[c], cn);
        full.add(
            vertex_gap(skin_positions(file_skin, raw.positions,
                                      clip_skinning_matrices(file_skin.joints, clips, c, clips.clip_range(c).second)),
                       cn));
      }
      std::printf("| the file's artist skin | %.2f / 4 | %.3f%% | %.3f%% | 0 | 0 |\n\n", 4.0,
                  100 * full.mean_of() / diag, 100 * full.max / diag);
    }
  }
}

// --- Robust Skin Weight Transfer (Abdrashitov, Raichstat, Monsen, Hill: SIGGRAPH Asia 2023) ---

struct Tri {
  std::vector<std::array<int, 3>> t;
};

Tri triangles(const SurfaceMesh& m) {
  Tri out;
  std::vector<Vec3> corners;
  for (int f = 0; f < m.num_faces(); ++f) {
    const auto face = m.face(f);
    corners.clear();
    for (int v : face)
      corners.push_back(m.positions[v]);
    for (const auto& t : detail::triangulate_polygon(corners))
      out.t.push_back({face[t[0]], face[t[1]], face[t[2]]});
  }
  return out;
}

std::vector<Vec3> vertex_normals(const SurfaceMesh& m, const Tri& tri) {
  std::vector<Vec3> n(m.num_vertices(), Vec3::Zero());
  for (const auto& t : tri.t) {
    const Vec3 fn = (m.positions[t[1]] - m.positions[t[0]]).cross(m.positions[t[2]] - m.positions[t[0]]);
    for (int v : t)
      n[v] += fn;
  }
  for (auto& x : n)
    if (x.norm() > 0)
      x.normalize();
  return n;
}

/// RSWT: closest-point matching (distance and normal-angle thresholds), then
/// inpainting the unmatched vertices by minimising trace(W^T Q W) with
/// Q = -L + L M^-1 L (cotangent Laplacian L, lumped mass M), matched rows fixed.
/// Returns per target welded vertex weights, and the matched fraction.
Dense rswt(const SurfaceMesh& source, const Dense& source_w, const SurfaceMesh& target, double* matched_fraction) {
  const double dist_max = 0.05 * target.bbox_diagonal();
  const double cos_max = std::cos(30.0 * std::numbers::pi / 180);
  const detail::CutMesh cut = detail::CutMesh::from_surface(source);
  const detail::TraceMesh tm(source, cut);
  const Tri stri = triangles(source), ttri = triangles(target);
  const auto sn = vertex_normals(source, stri), tn = vertex_normals(target, ttri);
  const int n = target.num_vertices(), J = static_cast<int>(source_w.cols());
  Dense W = Dense::Zero(n, J);
  std::vector<bool> known(n, false);
  int matched = 0;
  for (int v = 0; v < n; ++v) {
    const auto near = tm.nearest(target.positions[v]);
    const auto& t = tm.tri(near.tri);
    Vec3 normal = Vec3::Zero();
    Eigen::RowVectorXd w = Eigen::RowVectorXd::Zero(J);
    for (int c = 0; c < 3; ++c) {
      normal += near.bary[c] * sn[t[c]];
      w += near.bary[c] * source_w.row(t[c]);
    }
    if (near.distance(target.positions[v]) <= dist_max && normal.norm() > 0 &&
        normal.normalized().dot(tn[v]) >= cos_max) {
      W.row(v) = w;
      known[v] = true;
      ++matched;
    } else {
      W.row(v) = w; // the fallback where no matched vertex reaches
    }
  }
  *matched_fraction = static_cast<double>(matched) / std::max(1, n);
  if (matched == n || matched == 0)
    return W;
  // Cotangent Laplacian and lumped mass of the target.
  std::vector<Eigen::Triplet<double>> lt;
  Eigen::VectorXd mass = Eigen::VectorXd::Zero(n);
  for (const auto& t : ttri.t) {
    const Vec3 &a = target.positions[t[0]], &b = target.positions[t[1]], &c = target.positions[t[2]];
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) {
      const int i = t[k], j = t[(k + 1) % 3], o = t[(k + 2) % 3];
      const Vec3 u = target.positions[i] - target.positions[o], w = target.positions[j] - target.positions[o];
      const double cr = u.cross(w).norm();
      const double cot = cr > 0 ? u.dot(w) / cr : 0;
      lt.emplace_back(i, j, 0.5 * cot);
      lt.emplace_back(j, i, 0.5 * cot);
      lt.emplace_back(i, i, -0.5 * cot);
      lt.emplace_back(j, j, -0.5 * cot);
      mass[t[k]] += area / 3;
    }
  }
  Eigen::SparseMatrix<double> L(n, n);
  L.setFromTriplets(lt.begin(), lt.end());
  Eigen::SparseMatrix<double> Minv(n, n);
  for (int i = 0; i < n; ++i)
    Minv.insert(i, i) = 1.0 / std::max(mass[i], 1e-300);
  const Eigen::SparseMatrix<double> Q = -L + L * Minv * L;
  std::vector<int> unknown_index(n, -1), unknowns;
  for (int v = 0; v < n; ++v)
    if (!known[v]) {
      unknown_index[v] = static_cast<int>(unknowns.size());
      unknowns.push_back(v);
    }
  const int u = static_cast<int>(unknowns.size());
  std::vector<Eigen::Triplet<double>> qt;
  Dense rhs = Dense::Zero(u, J);
  for (int k = 0; k < Q.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(Q, k); it; ++it) {
      const int r = static_cast<int>(it.row()), c = static_cast<int>(it.col());
      if (unknown_index[r] < 0)
        continue;
      if (unknown_index[c] >= 0)
        qt.emplace_back(unknown_index[r], unknown_index[c], it.value());
      else
        rhs.row(unknown_index[r]) -= it.value() * W.row(c);
    }
  Eigen::SparseMatrix<double> Quu(u, u);
  Quu.setFromTriplets(qt.begin(), qt.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(Quu);
  if (solver.info() == Eigen::Success) {
    const Dense sol = solver.solve(rhs);
    if (solver.info() == Eigen::Success && sol.allFinite())
      for (int i = 0; i < u; ++i)
        W.row(unknowns[i]) = sol.row(i);
  }
  // Clamp to [0, 1] and normalise, as the paper does before use.
  for (int v = 0; v < n; ++v) {
    for (int j = 0; j < J; ++j)
      W(v, j) = std::clamp(W(v, j), 0.0, 1.0);
    const double s = W.row(v).sum();
    if (s > 0)
      W.row(v) /= s;
  }
  return W;
}

/// Top-4 of dense weights, renormalised, as SkinWeights per input vertex.
SkinWeights top4(const Dense& W, const SurfaceMesh& m, const std::vector<std::string>& names) {
  SkinWeights s;
  s.influences = 4;
  s.joints = names;
  const size_t n = m.input_to_welded.size();
  s.joint.assign(n * 4, -1);
  s.weight.assign(n * 4, 0);
  for (size_t i = 0; i < n; ++i) {
    const int v = m.input_to_welded[i];
    std::vector<std::pair<double, int>> row;
    for (int j = 0; j < W.cols(); ++j)
      if (W(v, j) > 0)
        row.emplace_back(W(v, j), j);
    std::sort(row.rbegin(), row.rend());
    if (row.size() > 4)
      row.resize(4);
    double sum = 0;
    for (const auto& [w, j] : row)
      sum += w;
    for (size_t k = 0; k < row.size(); ++k) {
      s.joint[i * 4 + k] = row[k].second;
      s.weight[i * 4 + k] = row[k].first / sum;
    }
  }
  return s;
}

Dense dense_of(const SkinWeights& w, const SurfaceMesh& m) {
  Dense D = Dense::Zero(m.num_vertices(), static_cast<int>(w.joints.size()));
  for (size_t i = 0; i < m.input_to_welded.size(); ++i)
    for (int k = 0; k < w.influences; ++k) {
      const int j = w.joint[i * w.influences + k];
      if (j >= 0)
        D(m.input_to_welded[i], j) = w.weight[i * w.influences + k];
    }
  return D;
}

SurfaceMesh posed(const SurfaceMesh& m, const SkinWeights& w, const std::vector<Vec3>& rest,
                  const std::vector<Mat4>& M) {
  const auto p = skin_positions(w, rest, M);
  SurfaceMesh out = m;
  for (size_t i = 0; i < p.size(); ++i)
    out.positions[m.input_to_welded[i]] = p[i];
  return out;
}

std::vector<Vec3> input_rest(const SurfaceMesh& m) {
  std::vector<Vec3> r(m.input_to_welded.size());
  for (size_t i = 0; i < r.size(); ++i)
    r[i] = m.positions[m.input_to_welded[i]];
  return r;
}

/// How far each posed target vertex lies from the posed source at the point
/// that corresponds to it at rest (its closest point on the source): the
/// gap a surface distance cannot see when the two slide along each other.
struct Correspondence {
  std::vector<int> tri;
  std::vector<std::array<double, 3>> bary;
  std::vector<std::array<int, 3>> verts;
};
Correspondence correspond(const SurfaceMesh& source, const SurfaceMesh& target) {
  const detail::CutMesh cut = detail::CutMesh::from_surface(source);
  const detail::TraceMesh tm(source, cut);
  Correspondence c;
  for (int v = 0; v < target.num_vertices(); ++v) {
    const auto near = tm.nearest(target.positions[v]);
    c.bary.push_back(near.bary);
    c.verts.push_back(tm.tri(near.tri));
  }
  return c;
}
double corresponding_gap(const Correspondence& c, const SurfaceMesh& posed_source, const SurfaceMesh& posed_target) {
  double sum = 0;
  for (int v = 0; v < posed_target.num_vertices(); ++v) {
    Vec3 q = Vec3::Zero();
    for (int k = 0; k < 3; ++k)
      q += c.bary[v][k] * posed_source.positions[c.verts[v][k]];
    sum += (posed_target.positions[v] - q).norm();
  }
  return sum / std::max(1, posed_target.num_vertices());
}

void transfer_table() {
  std::printf("Topology independence of baked skins: curvenet (the rig transferred and baked on every mesh, k = 4) "
              "against RSWT (the source's baked skin transferred to every mesh: closest points within 5%% of the "
              "diagonal and 30 degrees, the rest inpainted, top 4). Each target posed by the family's poses and "
              "compared with the posed source: surface distance as %% of the source's diagonal, mean over poses of "
              "the mean, and the largest max.\n\n");
  std::printf(
      "| family | target | faces | rest mean | curvenet mean | refined x2 mean | RSWT mean | rest max | curvenet max "
      "| refined x2 max | RSWT max | onto, curvenet max | refined x2 | RSWT | curvenet corr. | RSWT corr. | "
      "RSWT matched |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  struct Fam {
    std::string name;
    check::Family f;
  };
  std::vector<Fam> fams;
  {
    check::Family hand = check::make_family("hand", kData, {});
    // Our decimations of it (tests/data/hand), down to 610 faces.
    hand.targets.push_back({kOwn + "/hand/hand_l_924.glb"});
    hand.targets.push_back({kOwn + "/hand/hand_l_decimated.glb"});
    fams.push_back({"hand", hand});
  }
  {
    check::Family spot = check::make_family("spot", kData, {});
    spot.targets.resize(2); // the triangulated and low-resolution spot (the bare cage is not a surface to skin)
    fams.push_back({"spot", spot});
  }
  {
    check::Family c;
    const std::string d = kData + "/cesium_man/";
    c.source = d + "variants/cesium_man_a_welded.obj";
    for (const char* v : {"cesium_man_b_remesh.obj", "cesium_man_d_loop.obj", "cesium_man_c_decimated.obj",
                          "cesium_man_e_decimated_326.obj"})
      c.targets.push_back({d + "variants/" + v});
    const SkinnedMesh glb = load_skinned_mesh(d + "CesiumMan.glb");
    c.joints = glb.joints;
    const auto [t0, t1] = glb.clip_range(0);
    for (int k = 0; k < 6; ++k) {
      const double t = t0 + (t1 - t0) * k / 5.0;
      c.poses.emplace_back("walk " + std::to_string(k), pose_from_clip(glb, 0, t));
    }
    fams.push_back({"CesiumMan", c});
  }
  for (const auto& [name, f] : fams) {
    const SurfaceMesh source = load_mesh(f.source);
    const Rig rig = make_starter(source, f.joints, f.starter).rig;
    const Binding sb = bind(source, rig);
    const SkinWeights sw = bake_weights(sb, 4);
    const auto srest = input_rest(source);
    std::vector<std::vector<Mat4>> M;
    for (const auto& [pn, p] : f.poses)
      M.push_back(skinning_matrices(sb.joints(), p));
    std::vector<SurfaceMesh> sposed;
    for (const auto& m : M)
      sposed.push_back(posed(source, sw, srest, m));
    const Dense sdense = dense_of(sw, source);
    for (const auto& t : f.targets) {
      const SurfaceMesh target = load_mesh(t.path);
      const auto trest = input_rest(target);
      const SurfaceDistance rest = surface_distance(source, target);
      const Correspondence corr = correspond(source, target);
      // A target skin posed by every pose, against the posed source: the
      // surface distance (mean of the means, largest max) and the gap at
      // corresponding points.
      struct Agreement {
        Stat surface, onto; ///< onto: the target's posed surface onto the source's (one way)
        double corresponding = 0;
      };
      auto agreement = [&](const SkinWeights& w) {
        Agreement a;
        for (size_t k = 0; k < M.size(); ++k) {
          const SurfaceMesh pt = posed(target, w, trest, M[k]);
          const SurfaceDistance d = surface_distance(sposed[k], pt);
          a.surface.add({d.mean, d.max});
          a.onto.add({d.b_to_a.mean, d.b_to_a.max});
          a.corresponding += corresponding_gap(corr, sposed[k], pt) / M.size();
        }
        return a;
      };
      auto percent = [&](double x) {
        char text[32];
        std::snprintf(text, sizeof text, "%.3f%%", rest.percent(x));
        return std::string(text);
      };
      std::string cn_mean = "refused", cn_max = "refused", cn_corr = "refused", rf_mean = "refused", rf_max = "refused",
                  cn_onto = "refused", rf_onto = "refused";
      try {
        const TransferResult tr = transfer(rig, source, target);
        if (tr.report.ok) {
          const Agreement c = agreement(bake_weights(bind(target, tr.rig), 4));
          cn_mean = percent(c.surface.mean_of());
          cn_max = percent(c.surface.max);
          cn_corr = percent(c.corresponding);
          cn_onto = percent(c.onto.max);
          // Solved on the target refined twice by midpoint subdivision (the
          // same surface), read at the target's own vertices.
          const SurfaceMesh fine = midpoint_subdivide(target, 2);
          const SkinWeights fw = bake_weights(bind(fine, tr.rig), 4);
          std::vector<int> input_of(fine.num_vertices(), -1);
          for (size_t i = 0; i < fine.input_to_welded.size(); ++i)
            if (input_of[fine.input_to_welded[i]] < 0)
              input_of[fine.input_to_welded[i]] = static_cast<int>(i);
          SkinWeights rw = fw;
          rw.joint.assign(target.input_to_welded.size() * 4, -1);
          rw.weight.assign(target.input_to_welded.size() * 4, 0.0);
          for (size_t i = 0; i < target.input_to_welded.size(); ++i)
            for (int k = 0; k < 4; ++k) {
              const int f = input_of[target.input_to_welded[i]]; // the refinement keeps the vertices first
              rw.joint[i * 4 + k] = fw.joint[f * 4 + k];
              rw.weight[i * 4 + k] = fw.weight[f * 4 + k];
            }
          const Agreement rf = agreement(rw);
          rf_mean = percent(rf.surface.mean_of());
          rf_max = percent(rf.surface.max);
          rf_onto = percent(rf.onto.max);
        }
      } catch (const Error& e) {
        std::fprintf(stderr, "%s: %s\n", t.path.c_str(), e.what());
      }
      double matched = 0;
      const Agreement r = agreement(top4(rswt(source, sdense, target, &matched), target, sw.joints));
      std::printf("| %s | %s | %d | %.3f%% | %s | %s | %.3f%% | %.3f%% | %s | %s | %.3f%% | %s | %s | %.3f%% | %s | "
                  "%.3f%% | %.1f%% |\n",
                  name.c_str(), check::short_name(t.path).c_str(), target.num_faces(), rest.percent(rest.mean),
                  cn_mean.c_str(), rf_mean.c_str(), rest.percent(r.surface.mean_of()), rest.percent(rest.max),
                  cn_max.c_str(), rf_max.c_str(), rest.percent(r.surface.max), cn_onto.c_str(), rf_onto.c_str(),
                  rest.percent(r.onto.max), cn_corr.c_str(), rest.percent(r.corresponding), 100 * matched);
    }
  }
}


// --- The fit without clips against its anchor (issue 26) ---

/// The mesh's faces as lists of welded vertices.
std::vector<std::vector<int>> face_lists(const SurfaceMesh& mesh) {
  std::vector<std::vector<int>> faces(mesh.num_faces());
  for (int f = 0; f < mesh.num_faces(); ++f)
    faces[f].assign(mesh.face(f).begin(), mesh.face(f).end());
  return faces;
}

/// The anchor's weights on the binding's input vertices: solved once per
/// welded vertex (duplicates of a point move alike), on the mesh's faces.
SkinWeights anchor_skin(const Binding& b, const SurfaceMesh& mesh, const std::vector<Vec3>& rest,
                        const std::vector<std::vector<Mat4>>& poses, const std::vector<std::vector<Vec3>>& targets,
                        int nnz, bool grow_labels) {
  const std::vector<Vec3> wrest = mesh.welded(rest);
  std::vector<std::vector<Vec3>> wframes;
  for (const auto& t : targets)
    wframes.push_back(mesh.welded(t));
  bench::AnchorOptions o;
  o.nnz = nnz;
  o.grow_labels = grow_labels;
  const auto w = bench::anchor_weights(wrest, face_lists(mesh), poses, wframes, o);
  SkinWeights out;
  out.influences = nnz;
  for (const auto& j : b.joints())
    out.joints.push_back(j.name);
  out.joint.assign(rest.size() * nnz, -1);
  out.weight.assign(rest.size() * nnz, 0.0);
  for (size_t i = 0; i < rest.size(); ++i) {
    auto inf = w[mesh.input_to_welded[i]];
    std::sort(inf.begin(), inf.end(), [](const auto& a, const auto& c) { return a.second > c.second; });
    for (size_t k = 0; k < inf.size() && static_cast<int>(k) < nnz; ++k) {
      out.joint[i * nnz + k] = inf[k].first;
      out.weight[i * nnz + k] = inf[k].second;
    }
  }
  return out;
}

struct AnchorCase {
  std::string name;
  SurfaceMesh mesh;
  Rig rig;
  const SkinnedMesh* clips = nullptr;
  std::vector<std::pair<int, double>> clip_times; ///< the frames measured
  Mat4 normalise = Mat4::Identity();              ///< the file's armature placement, undone
};

std::vector<AnchorCase> anchor_cases(std::vector<std::unique_ptr<SkinnedMesh>>& keep) {
  std::vector<AnchorCase> cases;
  const std::string d = kData + "/xr_tools_hand/";
  keep.push_back(std::make_unique<SkinnedMesh>(load_skinned_mesh(d + "hand_l_poses.glb")));
  const SkinnedMesh* hand_clips = keep.back().get();
  {
    AnchorCase c;
    c.name = "hand, example rig, 35 clips";
    c.mesh = load_mesh(d + "hand_l.gltf");
    c.rig = read_rig(d + "example/hand_l.cnrig.json");
    c.clips = hand_clips;
    for (int k = 0; k < hand_clips->num_clips(); ++k)
      c.clip_times.emplace_back(k, hand_clips->clip_range(k).second);
    cases.push_back(std::move(c));
  }
  auto skinned = [&](const std::string& name, const std::string& path, const std::vector<std::string>& clip_names,
                     int frames_per_clip, const SkinnedMesh* clips) {
    keep.push_back(std::make_unique<SkinnedMesh>(load_skinned_mesh(path)));
    const SkinnedMesh& s = *keep.back();
    AnchorCase c;
    c.name = name;
    c.mesh = load_mesh(path);
    StarterOptions so;
    so.deforming = weighted_joints(s);
    so.skin = &s; // as `curvenet starter` does with a skinned file
    c.rig = make_starter(c.mesh, s.joints, so).rig;
    c.clips = clips ? clips : &s;
    if (!clips)
      c.normalise = s.skinning_matrices(-1, 0)[0].inverse();
    for (const auto& n : clip_names) {
      int clip = c.clips->find_clip(n);
      // By the name after an armature's prefix ("AnimalArmature|Walk", "Armature|TRex_Walk").
      for (int k = 0; k < c.clips->num_clips() && clip < 0; ++k) {
        const std::string& cn = c.clips->clip_names[k];
        for (const std::string tail : {"|" + n, "_" + n})
          if (cn.size() > tail.size() && cn.compare(cn.size() - tail.size(), tail.size(), tail) == 0)
            clip = k;
      }
      if (clip < 0)
        throw Error(path + ": no clip named " + n);
      const auto [t0, t1] = c.clips->clip_range(clip);
      for (int k = 0; k < frames_per_clip; ++k)
        c.clip_times.emplace_back(clip, frames_per_clip == 1 ? t1 : t0 + (t1 - t0) * k / frames_per_clip);
    }
    cases.push_back(std::move(c));
  };
  {
    std::vector<std::string> all;
    for (int k = 0; k < hand_clips->num_clips(); ++k)
      all.push_back(std::to_string(k));
    skinned("hand, starter net, 35 clips", d + "hand_l.gltf", all, 1, hand_clips);
  }
  skinned("CesiumMan, starter net, walk", kData + "/cesium_man/CesiumMan.glb", {"0"}, 24, nullptr);
  skinned("horse, starter net, walk and gallop", kData + "/quaternius/Horse.glb", {"Walk", "Gallop"}, 12, nullptr);
  skinned("wolf, starter net, walk and gallop", kData + "/quaternius/Wolf.glb", {"Walk", "Gallop"}, 12, nullptr);
  skinned("T-rex, starter net, walk and run", kData + "/quaternius/Trex.glb", {"Walk", "Run"}, 12, nullptr);
  skinned("Apatosaurus, starter net, walk", kData + "/quaternius/Apatosaurus.glb", {"Walk"}, 24, nullptr);
  return cases;
}

/// The anchor, checked: fit to frames that the hand's own artist skin makes
/// (4 influences, linear) over the training poses, it must play that skin's
/// 35 clips back. False when it does not.
bool anchor_self_check() {
  const std::string d = kData + "/xr_tools_hand/";
  const SkinnedMesh skin = load_skinned_mesh(d + "hand_l.gltf");
  const SkinnedMesh clips = load_skinned_mesh(d + "hand_l_poses.glb");
  const RawMesh raw = read_raw_mesh(d + "hand_l.gltf");
  const SurfaceMesh mesh = load_mesh(d + "hand_l.gltf");
  const double diag = mesh.bbox_diagonal();
  // On the welded mesh, as the table runs it (a file's UV seams would cut the
  // surface into islands that the labels cannot grow across).
  const auto train = training_poses(skin.joints);
  std::vector<std::vector<Vec3>> frames;
  for (const auto& M : train)
    frames.push_back(mesh.welded(skin_positions(skin, raw.positions, M)));
  const auto faces = face_lists(mesh);
  bool ok = true;
  for (const bool grow : {true, false}) {
    bench::AnchorOptions o;
    o.grow_labels = grow;
    const auto w = bench::anchor_weights(mesh.positions, faces, train, frames, o);
    Stat s;
    for (int c = 0; c < clips.num_clips(); ++c) {
      const auto M = clip_skinning_matrices(skin.joints, clips, c, clips.clip_range(c).second);
      const auto truth = mesh.welded(skin_positions(skin, raw.positions, M));
      std::vector<Vec3> p(truth.size());
      for (size_t i = 0; i < p.size(); ++i) {
        Eigen::Vector4d x = Eigen::Vector4d::Zero();
        for (const auto& [j, wj] : w[i])
          x += wj * (M[j] * mesh.positions[i].homogeneous());
        p[i] = x.head<3>();
      }
      s.add(vertex_gap(p, truth));
    }
    std::printf("The anchor (%s), checked: fit to the hand's own artist skin (4 influences, linear) over the %zu "
                "training poses, it plays the skin's %d clips back within %.4f%% of the diagonal on average and "
                "%.4f%% at worst.\n",
                grow ? "labels grown" : "labels not grown", train.size(), clips.num_clips(),
                100 * s.mean_of() / diag, 100 * s.max / diag);
    // Loose bounds: a wrong solve misses by whole bones (tens of per cent).
    ok = ok && s.mean_of() / diag < 1e-3 && (grow || s.max / diag < 0.02);
  }
  std::printf("\n");
  return ok;
}

void anchor_table() {
  if (!anchor_self_check()) {
    std::fprintf(stderr, "bake_bench: the anchor does not recover a linear skin; its table would mean nothing\n");
    std::exit(1);
  }
  std::vector<std::unique_ptr<SkinnedMesh>> keep;
  const auto cases = anchor_cases(keep);
  std::printf("The fit without clips against its anchor: both fit to the same training poses of the skeleton "
              "(training_poses, the defaults), measured on the clips' frames, which neither saw. Distances per "
              "vertex against the full curvenet deformation, %% of the diagonal: mean over frames of the mean over "
              "vertices, and the largest. Times: wall clock on all cores, the training frames' deformation "
              "included.\n\n");
  std::printf("| case | rig's mode | frames fitted / measured | weights | joints per vertex (mean / max) | mean | max | "
              "time |\n|---|---|---|---|---|---|---|---|\n");
  using Clock = std::chrono::steady_clock;
  auto seconds = [](Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); };
  for (const auto& c : cases) {
    for (const DeformMethod method : {DeformMethod::DualQuaternion, DeformMethod::Harmonic}) {
      BindOptions bo;
      bo.method = method;
      const Binding b = bind(c.mesh, c.rig, bo);
      const auto rest = rest_of(b);
      const double diag = c.mesh.bbox_diagonal();
      std::vector<std::vector<Mat4>> measured;
      for (const auto& [clip, t] : c.clip_times) {
        auto M = clip_skinning_matrices(b.joints(), *c.clips, clip, t);
        for (auto& x : M)
          x = c.normalise * x;
        measured.push_back(std::move(M));
      }
      std::vector<std::vector<Vec3>> truth(measured.size(), std::vector<Vec3>(rest.size()));
      for (size_t f = 0; f < measured.size(); ++f)
        b.deform(measured[f], truth[f]);
      const auto train = training_poses(b.joints());
      auto row = [&](const std::string& label, const SkinWeights& w, double secs) {
        Stat s;
        for (size_t f = 0; f < measured.size(); ++f)
          s.add(vertex_gap(skin_positions(w, rest, measured[f]), truth[f]));
        int most = 0;
        const double infl = influences(w, &most);
        std::printf("| %s | %s | %zu / %zu | %s | %.2f / %d | %.3f%% | %.3f%% | %s |\n", c.name.c_str(),
                    method == DeformMethod::DualQuaternion ? "dq" : "harmonic", train.size(), measured.size(),
                    label.c_str(), infl, most, 100 * s.mean_of() / diag, 100 * s.max / diag,
                    secs > 0 ? (std::to_string(static_cast<int>(std::lround(1000 * secs))) + " ms").c_str() : "-");
      };
      row("harmonic, top 4", bake_weights(b, 4), 0);
      {
        // The training poses before they were made moderate: each joint bent
        // by 45 and 90 degrees and twisted by 45, every joint at once by up to
        // 60 and 30.
        TrainingPoses wide;
        wide.bends = {45, 90};
        wide.twist = 45;
        wide.random_bend = 60;
        wide.random_twist = 30;
        const auto t0 = Clock::now();
        const SkinWeights w = fit_weights(b, training_poses(b.joints(), wide), 4);
        row("fitted (curvenet), k = 4, over wide poses (45 and 90 degrees)", w,
            std::chrono::duration<double>(Clock::now() - t0).count());
      }
      for (const int k : {4, 8}) {
        auto t0 = Clock::now();
        const SkinWeights ours = fit_weights(b, train, k);
        auto t1 = Clock::now();
        row("fitted (curvenet), k = " + std::to_string(k), ours, seconds(t0, t1));
        t0 = Clock::now();
        std::vector<Mat4> all;
        for (const auto& p : train)
          all.insert(all.end(), p.begin(), p.end());
        std::vector<Vec3> flat(train.size() * rest.size());
        b.deform_frames(all, flat);
        std::vector<std::vector<Vec3>> targets(train.size());
        for (size_t f = 0; f < train.size(); ++f)
          targets[f].assign(flat.begin() + static_cast<std::ptrdiff_t>(f * rest.size()),
                            flat.begin() + static_cast<std::ptrdiff_t>((f + 1) * rest.size()));
        const auto t_targets = Clock::now() - t0;
        for (const bool grow : {true, false}) {
          t0 = Clock::now();
          const SkinWeights anchor = anchor_skin(b, c.mesh, rest, train, targets, k, grow);
          t1 = Clock::now() + t_targets;
          row(std::string("anchor (Dem Bones' weights-only solve") + (grow ? "" : ", labels not grown") +
                  "), nnz = " + std::to_string(k),
              anchor, seconds(t0, t1));
        }
      }
    }
  }
  std::printf("\n");
}


// --- The floor of any linear skin (issue 26's worst-vertex goal) ---

/// A case bound in one mode and measured on its clips: the rig's positions at
/// each measured frame (the file's armature placement undone).
struct MeasuredCase {
  Binding binding;
  std::vector<Vec3> rest;
  double diag = 0;
  std::vector<std::vector<Mat4>> frames;
  std::vector<std::vector<Vec3>> truth;
};

MeasuredCase measure(const AnchorCase& c, DeformMethod method) {
  BindOptions bo;
  bo.method = method;
  MeasuredCase m{bind(c.mesh, c.rig, bo), {}, c.mesh.bbox_diagonal(), {}, {}};
  m.rest = rest_of(m.binding);
  for (const auto& [clip, t] : c.clip_times) {
    auto M = clip_skinning_matrices(m.binding.joints(), *c.clips, clip, t);
    for (auto& x : M)
      x = c.normalise * x;
    m.frames.push_back(std::move(M));
  }
  m.truth.assign(m.frames.size(), std::vector<Vec3>(m.rest.size()));
  for (size_t f = 0; f < m.frames.size(); ++f)
    m.binding.deform(m.frames[f], m.truth[f]);
  return m;
}

/// How close a linear skin can come at all. At each measured frame, a
/// vertex's skin position is a convex blend of where its joints carry it, so
/// its distance from the rig is at least the distance from the rig's
/// position to the convex hull of those points (detail::nearest_in_hull),
/// whatever the weights and even with weights chosen anew for every frame.
/// With the joints that move the vertex in the rig, and with every joint of
/// the skeleton.
void floor_table() {
  std::vector<std::unique_ptr<SkinnedMesh>> keep;
  const auto cases = anchor_cases(keep);
  std::printf("The floor of any linear skin on the clips' frames: at each frame and vertex, the distance from the "
              "rig's position to the convex hull of where the vertex's joints carry it (a skin's vertex is a convex "
              "blend of those points, whatever its weights, even weights chosen anew for each frame). Largest over "
              "the vertices and frames, %% of the diagonal, beside the fitted bake's worst vertex (the training "
              "poses' fit, as in the anchor table).\n\n");
  std::printf("| case | rig's mode | frames | fitted k = 4: max | fitted k = 8: max | floor, the joints that move "
              "the vertex: max | floor, any of the skeleton's joints: max | vertices whose floor is over 1.5 %% | floor, "
              "the vertex's joints and a helper half way round each of their bones: max | the same, a helper half "
              "way between each two of its joints: max |\n"
              "|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& c : cases) {
    for (const DeformMethod method : {DeformMethod::DualQuaternion, DeformMethod::Harmonic}) {
      const MeasuredCase mc = measure(c, method);
      if (mc.rest.empty() || mc.frames.empty())
        continue;
      const auto& [b, rest, diag, measured, truth] = mc;
      const size_t n = rest.size(), nj = b.joints().size();
      const auto train = training_poses(b.joints());
      double fitted_max[2] = {0, 0};
      for (const int k : {4, 8}) {
        const SkinWeights w = fit_weights(b, train, k);
        Stat s;
        for (size_t f = 0; f < measured.size(); ++f)
          s.add(vertex_gap(skin_positions(w, rest, measured[f]), truth[f]));
        fitted_max[k == 8] = s.max / diag;
      }
      // Per vertex, its worst frame's floor with its own joints, then with all
      // of them (only where that can still raise the maximum: it is never above
      // the floor with fewer joints).
      std::vector<double> own(n, 0.0), helped(n, 0.0), paired(n, 0.0);
      // Helper joints, as a skin could have them: for each bone whose joint
      // and parent both move the vertex, one keyed half way round between
      // them (the dual-quaternion mean of the two, a rotation multiplier of
      // one half on the child), whose carried point joins the hull.
      std::map<std::string, int> index;
      for (size_t j = 0; j < nj; ++j)
        index[b.joints()[j].name] = static_cast<int>(j);
      std::vector<int> parent(nj, -1);
      for (size_t j = 0; j < nj; ++j)
        if (b.joints()[j].parent && index.count(*b.joints()[j].parent))
          parent[j] = index.at(*b.joints()[j].parent);
      std::vector<std::vector<detail::DualJoint>> dual(measured.size());
      for (size_t f = 0; f < measured.size(); ++f)
        for (const Mat4& M : measured[f])
          dual[f].push_back(detail::split_joint(M));
      tbb::parallel_for(size_t{0}, n, [&](size_t v) {
        std::vector<std::pair<int, double>> inf;
        b.harmonic_weights(static_cast<int>(v), inf);
        std::vector<Vec3> carried(inf.size());
        detail::DualBlend half;
        for (size_t f = 0; f < measured.size(); ++f) {
          for (size_t i = 0; i < inf.size(); ++i)
            carried[i] = (measured[f][static_cast<size_t>(inf[i].first)] * rest[v].homogeneous()).head<3>();
          const double d = detail::nearest_in_hull(carried, truth[f][v]).distance;
          own[v] = std::max(own[v], d);
          for (const bool any_pair : {false, true}) {
            std::vector<Vec3> more = carried;
            for (const auto& [ja, wa] : inf)
              for (const auto& [jb, wb] : inf)
                if (any_pair ? ja < jb : parent[static_cast<size_t>(ja)] == jb) {
                  half.clear();
                  half.add(dual[f][static_cast<size_t>(ja)], 0.5);
                  half.add(dual[f][static_cast<size_t>(jb)], 0.5);
                  if (half.valid())
                    more.push_back(half.apply(rest[v]));
                }
            double& h = any_pair ? paired[v] : helped[v];
            h = std::max(h, detail::nearest_in_hull(more, truth[f][v]).distance);
          }
        }
      });
      std::vector<size_t> order(n);
      std::iota(order.begin(), order.end(), size_t{0});
      std::sort(order.begin(), order.end(), [&](size_t a, size_t q) { return own[a] > own[q]; });
      double any = 0;
      std::vector<Vec3> carried(nj);
      for (const size_t v : order) {
        if (own[v] <= any)
          break;
        for (size_t f = 0; f < measured.size(); ++f) {
          for (size_t j = 0; j < nj; ++j)
            carried[j] = (measured[f][j] * rest[v].homogeneous()).head<3>();
          any = std::max(any, detail::nearest_in_hull(carried, truth[f][v]).distance);
        }
      }
      const auto over = std::count_if(own.begin(), own.end(), [&](double d) { return d > 0.015 * diag; });
      const double with_helpers = *std::max_element(helped.begin(), helped.end());
      const double with_pairs = *std::max_element(paired.begin(), paired.end());
      std::printf("| %s | %s | %zu | %.2f%% | %.2f%% | %.2f%% | %.2f%% | %ld of %zu | %.2f%% | %.2f%% |\n", c.name.c_str(),
                  method == DeformMethod::DualQuaternion ? "dq" : "harmonic", measured.size(), 100 * fitted_max[0],
                  100 * fitted_max[1], 100 * own[order.front()] / diag, 100 * any / diag, static_cast<long>(over), n,
                  100 * with_helpers / diag, 100 * with_pairs / diag);
      std::fflush(stdout);
    }
  }
  std::printf("\n");
}

// --- Helper joints, fitted (what the floor table's last column would buy) ---

/// A skin with helper joints (fit_weights with `helpers`, as `bake --helpers`
/// fits): each helper the dual-quaternion mean of two joints that move a
/// vertex together, the pairs ranked by what they buy over the training
/// poses and the best kept, measured on the clips that the fit never saw.
/// The default `dq` rig only.
void helpers_table() {
  std::vector<std::unique_ptr<SkinnedMesh>> keep;
  const auto cases = anchor_cases(keep);
  std::printf("Helper joints, fitted (fit_weights with helpers, as bake --helpers): each vertex may take, besides its "
              "own joints, a helper half way between two of them (their dual-quaternion mean); the pairs are "
              "ranked over the training poses and the best H kept. Measured on the clips' frames, which the fit "
              "never saw; the default dq rig. %% of the diagonal, mean and worst vertex; time: the fit, all cores.\n\n");
  const std::vector<int> budgets{0, 8, 16, 32, 10000};
  std::printf("| case | joints | k |");
  for (const int h : budgets)
    std::printf(h == 10000 ? " H = all pairs |" : " H = %d |", h);
  std::printf("\n|---|---|---|");
  for (size_t i = 0; i < budgets.size(); ++i)
    std::printf("---|");
  std::printf("\n");
  for (const auto& c : cases) {
    const MeasuredCase mc = measure(c, DeformMethod::DualQuaternion);
    if (mc.rest.empty() || mc.frames.empty())
      continue;
    const auto& [b, rest, diag, measured, truth] = mc;
    const auto train = training_poses(b.joints());
    for (const int k : {4, 8}) {
      std::printf("| %s | %zu | %d |", c.name.c_str(), b.joints().size(), k);
      for (const int h : budgets) {
        const auto t0 = std::chrono::steady_clock::now();
        const SkinWeights w = fit_weights(b, train, k, h);
        const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        Stat gap;
        for (size_t f = 0; f < measured.size(); ++f)
          gap.add(vertex_gap(skin_positions(w, rest, measured[f]), truth[f]));
        std::printf(" %.3f / %.2f%%", 100 * gap.mean_of() / diag, 100 * gap.max / diag);
        if (h > 0)
          std::printf(" (%zu used)", w.helpers.size());
        std::printf(", %.1f s |", secs);
        std::fflush(stdout);
      }
      std::printf("\n");
    }
  }
  std::printf("\n");
}

// --- Baking as a user runs it (issue 26: under 5 s for a 5k-vertex character on one core, fit included) ---

double process_ms(const std::string& command, int reps = 5) {
  std::vector<double> ms;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    if (std::system((command + " > /dev/null 2>&1").c_str()) != 0) {
      std::fprintf(stderr, "bake_bench: failed, so its time would mean nothing: %s\n", command.c_str());
      std::exit(1);
    }
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

void speed_table() {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("curvenet_bake_bench_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string d = kData + "/xr_tools_hand/";
  struct Case {
    std::string name, mesh, rig, clips;
    int vertices = 0, faces = 0;
  };
  std::vector<Case> cases;
  auto starter_of = [&](const std::string& mesh_path, const std::string& skeleton_path, const std::string& out) {
    const SurfaceMesh m = load_mesh(mesh_path);
    const SkinnedMesh s = load_skinned_mesh(skeleton_path);
    StarterOptions so;
    so.deforming = weighted_joints(s);
    if (mesh_path == skeleton_path)
      so.skin = &s;
    write_rig(make_starter(m, s.joints, so).rig, out);
    return m;
  };
  {
    const SurfaceMesh m = load_mesh(d + "hand_l.gltf");
    cases.push_back({"hand, example rig", d + "hand_l.gltf", d + "example/hand_l.cnrig.json", d + "hand_l_poses.glb",
                     static_cast<int>(m.input_to_welded.size()), m.num_faces()});
    // The same surface, each triangle split into three quads (OpenSubdiv's bilinear scheme): the example rig
    // embeds on it as it is.
    const SurfaceMesh fine = midpoint_subdivide(m, 1);
    const std::string path = (dir / "hand_midpoint_1.obj").string();
    write_file_atomic(path, mesh_to_obj(fine.positions, fine.face_offsets, fine.face_vertices));
    cases.push_back({"hand, midpoint-subdivided once, example rig", path, d + "example/hand_l.cnrig.json",
                     d + "hand_l_poses.glb", fine.num_vertices(), fine.num_faces()});
    const SurfaceMesh smooth = catmull_clark(m, 1);
    const std::string cc = (dir / "hand_catmull_clark_1.obj").string();
    write_file_atomic(cc, mesh_to_obj(smooth.positions, smooth.face_offsets, smooth.face_vertices));
    const std::string rig = (dir / "hand_catmull_clark_1.cnrig.json").string();
    starter_of(cc, d + "hand_l.gltf", rig);
    cases.push_back({"hand, Catmull-Clark once, its starter net", cc, rig, d + "hand_l_poses.glb",
                     smooth.num_vertices(), smooth.num_faces()});
  }
  {
    const std::string cm = kData + "/cesium_man/CesiumMan.glb";
    const std::string rig = (dir / "cesium_man.cnrig.json").string();
    const SurfaceMesh m = starter_of(cm, cm, rig);
    cases.push_back({"CesiumMan, its starter net", cm, rig, cm, static_cast<int>(m.input_to_welded.size()),
                     m.num_faces()});
  }
  std::printf("`curvenet bake MESH RIG -o OUT.glb --weights WEIGHTS --clip CLIPS` as a process (bind, fit, the "
              "GLB and the fidelity report over every clip), medians of 5; all cores (%u here), and one "
              "(taskset -c 0)\n\n| mesh | vertices of the file | faces | weights | all cores | one core |\n|---|---|---|---|---|---|\n",
              std::thread::hardware_concurrency());
  const std::string cli = CURVENET_CLI;
  for (const auto& c : cases)
    for (const char* weights : {"harmonic", "fitted"}) {
      const std::string out = (dir / "out.glb").string();
      const std::string command = cli + " bake '" + c.mesh + "' '" + c.rig + "' -o '" + out + "' --weights " +
                                  weights + " --clip '" + c.clips + "'";
      const double all = process_ms(command), one = process_ms("taskset -c 0 " + command);
      std::printf("| %s | %d | %d | %s | %.0f ms | %.0f ms |\n", c.name.c_str(), c.vertices, c.faces, weights, all,
                  one);
    }
  std::printf("\n");
  fs::remove_all(dir);
}

} // namespace

int main(int argc, char** argv) {
  const std::string what = argc > 1 ? argv[1] : "all";
  if (what == "fidelity" || what == "all")
    fidelity();
  if (what == "transfer" || what == "all")
    transfer_table();
  if (what == "anchor" || what == "all")
    anchor_table();
  if (what == "floor" || what == "all")
    floor_table();
  if (what == "helpers" || what == "all")
    helpers_table();
  if (what == "speed" || what == "all")
    speed_table();
  return 0;
}
