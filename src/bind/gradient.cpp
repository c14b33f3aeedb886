#include "bind/gradient.hpp"

#include "core/polygon.hpp"
#include "curvenet/errors.hpp"

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>

namespace curvenet::detail {

std::map<std::string, std::pair<double, double>> side_scales_of(const Rig& rig) {
  std::map<std::string, std::pair<double, double>> out;
  const auto it = rig.extensions.find("x_side_scales");
  if (it == rig.extensions.end())
    return out;
  const auto j = nlohmann::json::parse(it->second, nullptr, false);
  if (!j.is_object())
    throw InputError("rig", "/x_side_scales", "expected an object of profile id -> [left, right]");
  for (auto p = j.begin(); p != j.end(); ++p) {
    const std::string path = "/x_side_scales/" + p.key();
    if (!p->is_array() || p->size() != 2 || !(*p)[0].is_number() || !(*p)[1].is_number())
      throw InputError("rig", path, "expected [left, right], two numbers");
    const double l = (*p)[0].get<double>(), r = (*p)[1].get<double>();
    if (!(l > 0 && r > 0 && std::isfinite(l) && std::isfinite(r) && l < 1e3 && r < 1e3))
      throw InputError("rig", path, "side scales must be finite and in (0, 1000)");
    if (std::none_of(rig.profiles.begin(), rig.profiles.end(), [&](const Profile& q) { return q.id == p.key(); }))
      throw InputError("rig", path, "names profile '" + p.key() + "', which the rig lacks");
    out[p.key()] = {l, r};
  }
  return out;
}

namespace {

using Sparse = Eigen::SparseMatrix<double>;

/// The side (profile, left?) of the curve that bounds face f's sector at
/// vertex c, found by turning about c from f until a curve edge; false when
/// the sector reaches a boundary or no curve edge.
bool sector_side(const CutMesh& cut, Face f, Vertex c, int& profile, bool& left) {
  Halfedge out;
  for (Halfedge h : cut.face_loop(f))
    if (cut.from(h) == c)
      out = h;
  if (!out.is_valid())
    return false;
  for (int guard = 0; guard < 64; ++guard) {
    const CurveTag& t = cut.tag(out);
    if (t.is_curve()) {
      profile = t.profile;
      left = t.forward; // the face of a half-edge along the profile lies on its left
      return true;
    }
    const Halfedge tw = CutMesh::twin(out);
    if (cut.is_boundary(tw))
      return false;
    out = cut.next(tw); // the next face about c, across `out`
  }
  return false;
}

} // namespace

std::shared_ptr<const GradientBind> build_gradient(const GradientInput& in) {
  const CutMesh& cut = *in.cut;
  const int nc = cut.num_vertices(), nfaces = cut.num_faces();
  auto out = std::make_shared<GradientBind>();
  GradientBind& g = *out;
  g.num_cut_vertices = nc;
  g.rotation = in.rotation;
  g.rest.resize(nc);
  for (int v = 0; v < nc; ++v)
    g.rest[v] = cut.position(Vertex(v));

  // Each vertex's joint weights: harmonic, constrained, or one rigid joint.
  const int nj = static_cast<int>(in.harmonic->size());
  auto vertex_weights = [&](int v, std::map<int, double>& w) {
    w.clear();
    if ((*in.constrained)[v]) {
      w = (*in.constraint_weights)[v];
    } else if ((*in.rigid_joint)[v] >= 0) {
      w[(*in.rigid_joint)[v]] = 1;
    } else if ((*in.free_index)[v] >= 0) {
      const int k = (*in.free_index)[v];
      for (int j = 0; j < nj; ++j)
        if ((*in.harmonic)[j].size() > 0 && (*in.harmonic)[j][k] > 0)
          w[j] = (*in.harmonic)[j][k];
    }
  };
  // Pins: CutChain vertices and rigid parts.
  g.unknown.assign(nc, -1);
  g.pin_offset.push_back(0);
  std::map<int, double> w;
  for (int v = 0; v < nc; ++v) {
    const bool pinned = (*in.constrained)[v] || (*in.rigid_joint)[v] >= 0;
    if (!pinned)
      g.unknown[v] = g.num_unknowns++;
    else {
      vertex_weights(v, w);
      for (const auto& [j, x] : w) {
        g.pin_joint.push_back(j);
        g.pin_weight.push_back(x);
      }
    }
    g.pin_offset.push_back(static_cast<int>(g.pin_joint.size()));
  }

  // Per face: its corners, and the average of their weights.
  g.face_corner_offset.push_back(0);
  for (int f = 0; f < nfaces; ++f) {
    for (Halfedge h : cut.face_loop(Face(f)))
      g.face_corner.push_back(cut.from(h).idx);
    g.face_corner_offset.push_back(static_cast<int>(g.face_corner.size()));
  }
  g.face_offset.push_back(0);
  std::map<int, double> acc;
  for (int f = 0; f < nfaces; ++f) {
    acc.clear();
    const auto loop = cut.face_loop(Face(f));
    for (Halfedge h : loop) {
      vertex_weights(cut.from(h).idx, w);
      for (const auto& [j, x] : w)
        acc[j] += x / static_cast<double>(loop.size());
    }
    double sum = 0;
    for (const auto& [j, x] : acc)
      sum += x;
    for (const auto& [j, x] : acc) {
      g.face_joint.push_back(j);
      g.face_weight.push_back(sum > 0 ? x / sum : x);
    }
    g.face_offset.push_back(static_cast<int>(g.face_joint.size()));
  }

  // The sides' stretch: across each profile, its side's width scale.
  g.face_stretch.assign(nfaces, Eigen::Matrix3d::Identity());
  if (!in.side_scales.empty()) {
    g.stretched = true;
    const auto& ids = *in.profile_ids;
    std::vector<std::pair<double, double>> scale(ids.size(), {1.0, 1.0});
    for (size_t p = 0; p < ids.size(); ++p)
      if (auto it = in.side_scales.find(ids[p]); it != in.side_scales.end())
        scale[p] = it->second;
    // A side's scale applies to its frame as a whole (Pixar's length l,
    // width w and h = sqrt(l w) alike): the stretch s I.
    auto side_tensor = [&](int p, bool left) {
      return Eigen::Matrix3d((left ? scale[p].first : scale[p].second) * Eigen::Matrix3d::Identity());
    };
    // Per face corner at a chain vertex: its sector's side; per vertex, the
    // average of its sides (the value without the cut-aware discretisation).
    std::vector<std::map<int, std::pair<Eigen::Matrix3d, int>>> by_region(nc); // region -> (sum, count)
    std::vector<std::pair<Eigen::Matrix3d, int>> vertex_avg(nc, {Eigen::Matrix3d::Zero(), 0});
    std::vector<std::vector<std::pair<int, Eigen::Matrix3d>>> corner_value(nfaces); // (vertex, value)
    for (int f = 0; f < nfaces; ++f)
      for (Halfedge h : cut.face_loop(Face(f))) {
        const int c = cut.from(h).idx;
        if (!(*in.constrained)[c])
          continue;
        int p = -1;
        bool left = true;
        const Eigen::Matrix3d value = sector_side(cut, Face(f), Vertex(c), p, left) ? side_tensor(p, left)
                                                                                    : Eigen::Matrix3d::Identity();
        corner_value[f].emplace_back(c, value);
        const int r = (*in.face_region)[f];
        auto& slot = by_region[c][r];
        if (slot.second == 0)
          slot.first.setZero();
        slot.first += value;
        ++slot.second;
        vertex_avg[c].first += value;
        ++vertex_avg[c].second;
      }
    auto averaged = [](const std::pair<Eigen::Matrix3d, int>& s) {
      return s.second > 0 ? Eigen::Matrix3d(s.first / s.second) : Eigen::Matrix3d::Identity();
    };
    // Harmonic interpolation of the stretch to the free vertices (6 channels).
    const auto& fv = *in.free_vertices;
    const int nf = static_cast<int>(fv.size());
    std::vector<int> free_region(nf, -1);
    for (int f = 0; f < nfaces; ++f)
      for (Halfedge h : cut.face_loop(Face(f))) {
        const int v = cut.from(h).idx;
        if ((*in.free_index)[v] >= 0)
          free_region[(*in.free_index)[v]] = (*in.face_region)[f];
      }
    std::vector<Eigen::Matrix3d> free_stretch(nf, Eigen::Matrix3d::Identity());
    if (nf > 0) {
      Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nf, 6);
      const int rows[6] = {0, 1, 2, 0, 0, 1}, cols[6] = {0, 1, 2, 1, 2, 2};
      for (int k = 0; k < nf; ++k)
        for (const auto& [c, l] : (*in.harmonic_fc)[k]) {
          Eigen::Matrix3d value = averaged(vertex_avg[c]);
          if (in.cut_aware)
            if (auto it = by_region[c].find(free_region[k]); it != by_region[c].end())
              value = averaged(it->second);
          for (int q = 0; q < 6; ++q)
            rhs(k, q) -= l * value(rows[q], cols[q]);
        }
      const Eigen::MatrixXd sol = in.harmonic_solver->solve(rhs);
      for (int k = 0; k < nf; ++k)
        for (int q = 0; q < 6; ++q) {
          free_stretch[k](rows[q], cols[q]) = sol(k, q);
          free_stretch[k](cols[q], rows[q]) = sol(k, q);
        }
    }
    for (int f = 0; f < nfaces; ++f) {
      Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
      int n = 0;
      for (Halfedge h : cut.face_loop(Face(f))) {
        const int v = cut.from(h).idx;
        ++n;
        if ((*in.free_index)[v] >= 0) {
          sum += free_stretch[(*in.free_index)[v]];
        } else if ((*in.constrained)[v]) {
          Eigen::Matrix3d value = averaged(vertex_avg[v]);
          if (in.cut_aware)
            for (const auto& [c, x] : corner_value[f])
              if (c == v)
                value = x;
          sum += value;
        } else {
          sum += Eigen::Matrix3d::Identity();
        }
      }
      g.face_stretch[f] = sum / std::max(n, 1);
    }
  }

  // Curve frames: the chain vertices between two others, and the harmonic
  // system that spreads their turn.
  g.sample_of.assign(nc, -1);
  if (in.curve_frames && in.harmonic_solver && !in.free_vertices->empty()) {
    for (const auto& cv : *in.chain_vertices)
      for (size_t i = 1; i + 1 < cv.size(); ++i) {
        const int c = cv[i].idx;
        if (g.sample_of[c] >= 0)
          continue;
        const Eigen::Vector3d t = g.rest[cv[i + 1].idx] - g.rest[cv[i - 1].idx];
        if (!(t.norm() > 0))
          continue;
        g.sample_of[c] = static_cast<int>(g.frames.size());
        g.frames.push_back({c, cv[i - 1].idx, cv[i + 1].idx, t.normalized()});
      }
    g.harmonic = in.harmonic_solver;
    g.harmonic_index = *in.free_index;
    g.harmonic_fc = *in.harmonic_fc;
  }

  // The Poisson system: cotangent weights of each face's triangles (ear
  // clipping), per edge, with the triangle it belongs to.
  std::vector<Eigen::Triplet<double>> kt;
  std::vector<Eigen::Vector3d> corners;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> bones;
  g.sections = in.sections && in.joints && !in.joints->empty();
  if (g.sections) {
    std::map<std::string, int> index;
    for (size_t j = 0; j < in.joints->size(); ++j)
      index[(*in.joints)[j].name] = static_cast<int>(j);
    for (const Joint& jt : *in.joints)
      if (jt.parent)
        if (auto it = index.find(*jt.parent); it != index.end())
          bones.emplace_back((*in.joints)[it->second].bind.block<3, 1>(0, 3), jt.bind.block<3, 1>(0, 3));
    if (bones.empty())
      for (const Joint& jt : *in.joints)
        bones.emplace_back(jt.bind.block<3, 1>(0, 3), jt.bind.block<3, 1>(0, 3));
    g.tri_grad_offset.push_back(0);
  }
  std::map<int, double> corner_w[3];
  for (int f = 0; f < nfaces; ++f) {
    const auto loop = cut.face_loop(Face(f));
    corners.clear();
    std::vector<int> ids;
    for (Halfedge h : loop) {
      ids.push_back(cut.from(h).idx);
      corners.push_back(g.rest[ids.back()]);
    }
    for (const auto& t : triangulate_polygon(corners)) {
      const int tri = static_cast<int>(g.tri_face.size());
      g.tri_face.push_back(f);
      if (g.sections) {
        const Eigen::Vector3d A = g.rest[ids[t[0]]], B = g.rest[ids[t[1]]], C = g.rest[ids[t[2]]];
        const Eigen::Vector3d centroid = (A + B + C) / 3;
        double best = INFINITY;
        Eigen::Vector3d at = centroid;
        for (const auto& [a, b] : bones) {
          const Eigen::Vector3d d = b - a;
          const double l2 = d.squaredNorm();
          const Eigen::Vector3d q = a + (l2 > 0 ? std::clamp((centroid - a).dot(d) / l2, 0.0, 1.0) : 0.0) * d;
          if ((q - centroid).norm() < best) {
            best = (q - centroid).norm();
            at = q;
          }
        }
        g.tri_offset.push_back(centroid - at);
        // Gradients of the face's joint weights on this triangle: grad phi_k = n x (opposite edge) / (2 area).
        const Eigen::Vector3d n2 = (B - A).cross(C - A); // 2 area times the unit normal
        const double a2 = n2.squaredNorm();
        for (int k = 0; k < 3; ++k)
          vertex_weights(ids[t[k]], corner_w[k]);
        for (int q = g.face_offset[f]; q < g.face_offset[f + 1]; ++q) {
          const int j = g.face_joint[q];
          Eigen::Vector3d grad = Eigen::Vector3d::Zero();
          if (a2 > 0) {
            const Eigen::Vector3d P[3] = {A, B, C};
            for (int k = 0; k < 3; ++k) {
              const auto it = corner_w[k].find(j);
              if (it != corner_w[k].end())
                grad += it->second * n2.cross(P[(k + 2) % 3] - P[(k + 1) % 3]) / a2;
            }
          }
          g.tri_grad.push_back(grad);
        }
        g.tri_grad_offset.push_back(static_cast<int>(g.tri_grad.size()));
      }
      for (int k = 0; k < 3; ++k) {
        const int i = ids[t[k]], j = ids[t[(k + 1) % 3]], o = ids[t[(k + 2) % 3]];
        const Eigen::Vector3d a = g.rest[i] - g.rest[o], b = g.rest[j] - g.rest[o];
        const double cr = a.cross(b).norm();
        if (!(cr > 0))
          continue;
        const double wgt = 0.5 * a.dot(b) / cr;
        g.edges.push_back({i, j, tri, wgt, g.rest[j] - g.rest[i]});
        const int ui = g.unknown[i], uj = g.unknown[j];
        if (ui >= 0)
          kt.emplace_back(ui, ui, wgt);
        if (uj >= 0)
          kt.emplace_back(uj, uj, wgt);
        if (ui >= 0 && uj >= 0) {
          kt.emplace_back(ui, uj, -wgt);
          kt.emplace_back(uj, ui, -wgt);
        }
      }
    }
  }
  if (g.num_unknowns > 0) {
    Sparse K(g.num_unknowns, g.num_unknowns);
    K.setFromTriplets(kt.begin(), kt.end());
    g.solver.compute(K);
    if (g.solver.info() != Eigen::Success)
      throw EmbedError("bind: the gradient mode's Poisson system could not be factored");
  }
  return out;
}

namespace {
struct Scratch {
  const GradientBind* owner = nullptr;
  std::vector<Eigen::Matrix3d> rotation, stretch, face, tri;
  std::vector<Eigen::Vector3d> turn_rate; ///< per face joint entry: the blend's turn per unit of its weight
  std::vector<Eigen::Quaterniond> real, dual; ///< each joint's rigid part as a dual quaternion
  std::vector<Eigen::Vector3d> turn;          ///< per frame sample: the curve frame's turn (axis times angle)
  Eigen::MatrixXd hx, hy;                     ///< the turn's harmonic solve
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> rhs;
  Eigen::MatrixXd x, y;
};
} // namespace

void deform_gradient(const GradientBind& g, std::span<const Mat4> M, std::span<Eigen::Vector3d> out) {
  thread_local Scratch scratch;
  Scratch& s = scratch; // this thread's: the parallel loop below runs on others
  const int nfaces = static_cast<int>(g.face_stretch.size());
  if (s.owner != &g || static_cast<int>(s.face.size()) != nfaces || s.rhs.rows() != g.num_unknowns) {
    s.owner = &g;
    s.face.resize(nfaces);
    s.tri.resize(g.tri_face.size());
    s.turn_rate.resize(g.face_joint.size());
    s.rhs.resize(g.num_unknowns, 3);
    s.x.resize(g.num_unknowns, 3);
    s.y.resize(g.num_unknowns, 3);
  }
  s.rotation.resize(M.size());
  s.stretch.resize(M.size());
  s.real.resize(M.size());
  s.dual.resize(M.size());
  for (size_t j = 0; j < M.size(); ++j) {
    const Eigen::Matrix3d a = M[j].topLeftCorner<3, 3>();
    s.rotation[j] = nearest_rotation(a);
    s.stretch[j] = s.rotation[j].transpose() * a;
    // M = [R S | t]: the rigid part (R, t) as a dual quaternion q0 + e q1, q1 = t q0 / 2.
    s.real[j] = Eigen::Quaterniond(s.rotation[j]).normalized();
    const Eigen::Vector3d t = M[j].block<3, 1>(0, 3);
    s.dual[j].coeffs() = 0.5 * (Eigen::Quaterniond(0, t.x(), t.y(), t.z()) * s.real[j]).coeffs();
  }
  // Pinned vertices: the net's curves, moved by their weights' blend of the
  // joints' rigid motions (dual quaternions, which turn a twist instead of
  // shrinking it), after the blend of the joints' stretches.
  for (int v = 0; v < g.num_cut_vertices; ++v) {
    if (g.unknown[v] >= 0)
      continue;
    const int k0 = g.pin_offset[v], k1 = g.pin_offset[v + 1];
    if (k1 - k0 == 1) {
      out[v] = (M[g.pin_joint[k0]] * g.rest[v].homogeneous()).head<3>();
      continue;
    }
    Eigen::Vector4d b0 = Eigen::Vector4d::Zero(), b1 = Eigen::Vector4d::Zero();
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    const Eigen::Quaterniond& pivot = s.real[g.pin_joint[k0]];
    for (int k = k0; k < k1; ++k) {
      const int j = g.pin_joint[k];
      const double w = pivot.dot(s.real[j]) < 0 ? -g.pin_weight[k] : g.pin_weight[k]; // the short way round
      b0 += w * s.real[j].coeffs();
      b1 += w * s.dual[j].coeffs();
      x += g.pin_weight[k] * (s.stretch[j] * g.rest[v]);
    }
    const double n = b0.norm();
    if (!(n > 1e-12)) { // opposite rotations cancel: fall back to the linear blend
      Eigen::Vector3d p = Eigen::Vector3d::Zero();
      for (int k = k0; k < k1; ++k)
        p += g.pin_weight[k] * (M[g.pin_joint[k]] * g.rest[v].homogeneous()).head<3>();
      out[v] = p;
      continue;
    }
    Eigen::Quaterniond q0, q1;
    q0.coeffs() = b0 / n;
    q1.coeffs() = b1 / n;
    const Eigen::Quaterniond tq = q1 * q0.conjugate();
    out[v] = q0 * x + 2 * Eigen::Vector3d(tq.x(), tq.y(), tq.z());
  }
  // Curve frames: how far each posed curve turns from where its joints would
  // carry its tangent (the smallest rotation between the two), spread over
  // the surface harmonically.
  const bool frames = !g.frames.empty();
  if (frames) {
    s.turn.resize(g.frames.size());
    for (size_t i = 0; i < g.frames.size(); ++i) {
      const auto& fs = g.frames[i];
      Eigen::Vector4d b0 = Eigen::Vector4d::Zero();
      Eigen::Matrix3d stretch = Eigen::Matrix3d::Zero();
      const int k0 = g.pin_offset[fs.vertex], k1 = g.pin_offset[fs.vertex + 1];
      for (int k = k0; k < k1; ++k) {
        const Eigen::Quaterniond& q = s.real[g.pin_joint[k]];
        b0 += (s.real[g.pin_joint[k0]].dot(q) < 0 ? -g.pin_weight[k] : g.pin_weight[k]) * q.coeffs();
        stretch += g.pin_weight[k] * s.stretch[g.pin_joint[k]];
      }
      Eigen::Quaterniond q;
      q.coeffs() = b0;
      // Where the joints carry the rest tangent: their blended stretch, then rotation.
      const Eigen::Vector3d carried =
          ((b0.norm() > 1e-12 ? q.normalized() : Eigen::Quaterniond::Identity()) * (stretch * fs.tangent)).normalized();
      Eigen::Vector3d posed = out[fs.next] - out[fs.prev];
      s.turn[i].setZero();
      if (posed.norm() > 0) {
        posed.normalize();
        const Eigen::Vector3d axis = carried.cross(posed);
        const double sn = axis.norm();
        if (sn > 1e-15)
          s.turn[i] = axis / sn * std::atan2(sn, carried.dot(posed));
      }
    }
    const int nf = static_cast<int>(g.harmonic_fc.size());
    s.hx.resize(nf, 3);
    s.hy.resize(nf, 3);
    s.hy.setZero();
    for (int k = 0; k < nf; ++k)
      for (const auto& [c, l] : g.harmonic_fc[k])
        if (g.sample_of[c] >= 0)
          s.hy.row(k) -= l * s.turn[g.sample_of[c]].transpose();
    const auto& h = *g.harmonic;
    s.hx = h.permutationP() * s.hy;
    h.matrixL().solveInPlace(s.hx);
    s.hx.array().colwise() /= h.vectorD().array();
    h.matrixU().solveInPlace(s.hx);
    s.hy = h.permutationPinv() * s.hx;
  }
  auto turn_at = [&](int v) -> Eigen::Vector3d {
    if (g.sample_of[v] >= 0)
      return s.turn[g.sample_of[v]];
    const int k = g.harmonic_index[v];
    return k >= 0 ? Eigen::Vector3d(s.hy.row(k).transpose()) : Eigen::Vector3d::Zero();
  };
  // Per face: the rotation of the blend, times the blended stretch, times the sides' stretch.
  // Isolated: while it waits, this thread must not pick up another frame of
  // deform_frames, which would reuse this thread's scratch mid-frame.
  tbb::this_task_arena::isolate([&] {
  tbb::parallel_for(tbb::blocked_range<int>(0, nfaces, 4096), [&](const tbb::blocked_range<int>& range) {
    for (int f = range.begin(); f < range.end(); ++f) {
      const int k0 = g.face_offset[f], k1 = g.face_offset[f + 1];
      Eigen::Matrix3d st = Eigen::Matrix3d::Zero(), rot;
      for (int k = k0; k < k1; ++k)
        st += g.face_weight[k] * s.stretch[g.face_joint[k]];
      if (k1 - k0 == 1) {
        rot = s.rotation[g.face_joint[k0]];
      } else if (g.rotation == RotationBlend::Quaternion || g.sections) {
        Eigen::Vector4d q = Eigen::Vector4d::Zero();
        const Eigen::Quaterniond& pivot = s.real[g.face_joint[k0]];
        for (int k = k0; k < k1; ++k) {
          const Eigen::Quaterniond& qj = s.real[g.face_joint[k]];
          q += (pivot.dot(qj) < 0 ? -g.face_weight[k] : g.face_weight[k]) * qj.coeffs();
        }
        const double norm = q.norm();
        Eigen::Quaterniond qq;
        qq.coeffs() = norm > 1e-12 ? Eigen::Vector4d(q / norm) : s.real[g.face_joint[k0]].coeffs();
        rot = qq.toRotationMatrix();
        if (g.sections)
          for (int k = k0; k < k1; ++k) {
            // d(q)/d(w_k) = (q_k - (q . q_k) q) / |b|, and the turn it makes: 2 vec(dq q*).
            if (!(norm > 1e-12)) {
              s.turn_rate[k].setZero();
              continue;
            }
            const Eigen::Quaterniond& qj = s.real[g.face_joint[k]];
            const Eigen::Vector4d qk = pivot.dot(qj) < 0 ? Eigen::Vector4d(-qj.coeffs()) : Eigen::Vector4d(qj.coeffs());
            Eigen::Quaterniond dq;
            dq.coeffs() = (qk - qq.coeffs().dot(qk) * qq.coeffs()) / norm;
            s.turn_rate[k] = 2 * (dq * qq.conjugate()).vec();
          }
      } else {
        Eigen::Matrix3d r = Eigen::Matrix3d::Zero();
        for (int k = k0; k < k1; ++k)
          r += g.face_weight[k] * s.rotation[g.face_joint[k]];
        // Joints that turn alike blend to a rotation already.
        rot = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-13 ? r : nearest_rotation(r);
      }
      if (frames) {
        Eigen::Vector3d w = Eigen::Vector3d::Zero();
        int corners = 0;
        for (int c = g.face_corner_offset[f]; c < g.face_corner_offset[f + 1]; ++c, ++corners)
          w += turn_at(g.face_corner[c]);
        w /= std::max(corners, 1);
        const double angle = w.norm();
        if (angle > 1e-15)
          rot = Eigen::AngleAxisd(angle, w / angle).toRotationMatrix() * rot;
      }
      s.face[f] = g.stretched ? Eigen::Matrix3d(rot * st * g.face_stretch[f]) : Eigen::Matrix3d(rot * st);
    }
  });
  });
  const int ntris = static_cast<int>(g.tri_face.size());
  tbb::this_task_arena::isolate([&] {
  tbb::parallel_for(tbb::blocked_range<int>(0, ntris, 8192), [&](const tbb::blocked_range<int>& range) {
    for (int t = range.begin(); t < range.end(); ++t) {
      const int f = g.tri_face[t];
      s.tri[t] = s.face[f];
      const int k0 = g.face_offset[f], k1 = g.face_offset[f + 1];
      if (!g.sections || k1 - k0 < 2)
        continue;
      // The section's turn: each weight's gradient times how the blend turns the triangle's offset from its bone.
      const Eigen::Vector3d rr = s.face[f] * g.tri_offset[t];
      for (int k = k0, q = g.tri_grad_offset[t]; k < k1; ++k, ++q)
        s.tri[t].noalias() += s.turn_rate[k].cross(rr) * g.tri_grad[q].transpose();
    }
  });
  });
  if (g.num_unknowns == 0)
    return;
  s.rhs.setZero();
  for (const auto& e : g.edges) {
    const Eigen::Vector3d d = s.tri[e.tri] * e.e; // the target x_j - x_i
    const int ui = g.unknown[e.i], uj = g.unknown[e.j];
    if (ui >= 0) {
      s.rhs.row(ui) -= e.w * d.transpose();
      if (uj < 0)
        s.rhs.row(ui) += e.w * out[e.j].transpose();
    }
    if (uj >= 0) {
      s.rhs.row(uj) += e.w * d.transpose();
      if (ui < 0)
        s.rhs.row(uj) += e.w * out[e.i].transpose();
    }
  }
  // Back-substitution with the factor, in place: x = P^-1 L^-T D^-1 L^-1 P b.
  s.y = s.rhs;
  s.x = g.solver.permutationP() * s.y;
  g.solver.matrixL().solveInPlace(s.x);
  s.x.array().colwise() /= g.solver.vectorD().array();
  g.solver.matrixU().solveInPlace(s.x);
  s.y = g.solver.permutationPinv() * s.x;
  for (int v = 0; v < g.num_cut_vertices; ++v)
    if (g.unknown[v] >= 0)
      out[v] = s.y.row(g.unknown[v]).transpose();
}

} // namespace curvenet::detail
