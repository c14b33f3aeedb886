// Curvenet as a layer over a skin, or over its own deformation: the base
// surface's chains taken to the posed curves (and their nodes' offsets),
// the displacement extended harmonically over each region, scaled by an
// envelope and a mask (docs/deform.md).

#include "curvenet/layer.hpp"

#include "bind/constraints.hpp"
#include "bind/laplacian.hpp"
#include "core/dual_quaternion.hpp"
#include "curvenet/errors.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/LU>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <functional>
#include <limits>
#include <queue>

namespace curvenet {

using namespace detail;

struct CurveLayer::Impl {
  explicit Impl(Binding b) : binding(std::move(b)) {}
  Binding binding;
  bool over_skin = false;
  SkinnedMesh skin;               ///< the base skin (over_skin)
  std::vector<int> skin_to_joint; ///< skin joint -> binding joint (-1: unweighted, left at rest)
  Skinning skinning = Skinning::Linear;
  bool dual = true;             ///< the curves are posed as dual quaternions (else linearly)
  std::vector<Vec3> input_rest; ///< per input vertex
  std::vector<int> input_to_welded;
  std::vector<int> welded_input; ///< per welded vertex, one of its input vertices
  // The chains: per constrained cut vertex.
  struct Chain {
    int vertex; ///< cut-mesh vertex
    Vec3 rest;
    std::vector<std::pair<int, double>> joints;  ///< (binding joint, weight)
    std::vector<std::pair<int, double>> surface; ///< (welded vertex, weight): where it lies on the input surface
    int node_a, node_b;                          ///< rig node indices
    double t;
  };
  std::vector<Chain> chains;
  std::vector<std::string> node_ids;
  // The harmonic extension: L_ff d_f = -L_fc d_c.
  std::vector<std::vector<std::pair<int, double>>> cut_surface; ///< per cut vertex: where it lies on the input surface
  std::vector<int> free_index;                                  ///< per cut vertex, -1 off the solve
  std::vector<int> chain_index;                                 ///< per cut vertex, -1 off the chains
  std::vector<std::vector<std::pair<int, double>>> fc;          ///< free row -> (chain index, L entry)
  /// The free vertices fall into parts that the chains separate (the
  /// regions, where the net closes them): L_ff is block diagonal, so each
  /// part has its own factor, solved on its own (in parallel) and only when
  /// a chain around it moves. Each part's free rows are contiguous.
  struct Part {
    int begin = 0, size = 0; ///< free rows
    std::vector<int> chains; ///< the chain indices its rows reach
    std::unique_ptr<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>> solver;
  };
  std::vector<Part> parts;
  int num_welded = 0, num_free = 0;
  /// Over a linear skin, with the curves posed linearly (the harmonic
  /// method), the displacement on the chains is linear in the joints'
  /// matrices, and so is its harmonic extension: the correction at a
  /// vertex is a sum over joints of M_j times a homogeneous vector, solved
  /// for once at bind time (joint -1: the identity, for the skin's vertices
  /// that no joint of the rig moves). A frame is then a skin-like sum, not a
  /// solve. Node offsets and the posed cut mesh still solve.
  struct LinearSum {
    // Per input vertex, in one pass: the skin's influences on the rig's
    // joints, then the correction's terms.
    std::vector<int> skin_begin; ///< per input vertex, and one past the last
    std::vector<int> skin_joint; ///< the rig's joint; -1: none of the rig's (the identity)
    std::vector<double> skin_weight;
    std::vector<int> begin; ///< per input vertex, and one past the last
    std::vector<int> joint;
    std::vector<Eigen::Vector4d> vector;
  };
  std::unique_ptr<LinearSum> linear;
};

CurveLayer::CurveLayer(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}

namespace {
/// The mask checked against the mesh file's `vertices`: one number from 0 to 1 each.
std::shared_ptr<const std::vector<double>> checked_mask(std::vector<double> mask, size_t vertices) {
  if (mask.empty())
    return nullptr;
  if (mask.size() != vertices)
    throw InputError("mask", "",
                     std::to_string(mask.size()) + " values for " + std::to_string(vertices) +
                         " vertices: give one per vertex of the mesh file");
  for (size_t i = 0; i < vertices; ++i)
    if (!(mask[i] >= 0 && mask[i] <= 1))
      throw InputError("mask", "vertex " + std::to_string(i), "expected a number from 0 to 1");
  return std::make_shared<const std::vector<double>>(std::move(mask));
}
} // namespace

CurveLayer CurveLayer::with_mask(std::vector<double> mask) const {
  CurveLayer out(impl_);
  out.mask_ = checked_mask(std::move(mask), impl_->input_to_welded.size());
  return out;
}

std::span<const double> CurveLayer::mask() const {
  return mask_ ? std::span<const double>(*mask_) : std::span<const double>();
}
std::vector<double> CurveLayer::region_mask(const std::map<std::string, double>& values, double others,
                                            double falloff) const {
  const Binding& b = impl_->binding;
  if (!b.has_embedding())
    throw Error("region_mask: the layer's binding has no embedding");
  if (!(others >= 0 && others <= 1))
    throw InputError("mask", "other regions", "expected a number from 0 to 1");
  if (!(falloff >= 0 && falloff <= 1))
    throw InputError("mask", "falloff", "expected a fraction of the bounding-box diagonal from 0 to 1");
  const Embedding& e = b.embedding();
  const auto& list = e.report().region_list;
  std::map<std::string, int> by_key;
  for (size_t r = 0; r < list.size(); ++r)
    by_key.emplace(list[r].key(), static_cast<int>(r));
  std::vector<double> value(list.size(), others);
  for (const auto& [key, x] : values) {
    const auto it = by_key.find(key);
    if (it == by_key.end())
      throw InputError("mask", "region '" + key + "'",
                       "no region of the net has this key (the embed report lists them, as "
                       "\"profile:L|profile:R\")");
    if (!(x >= 0 && x <= 1))
      throw InputError("mask", "region '" + key + "'", "expected a number from 0 to 1");
    value[it->second] = x;
  }
  // Per cut vertex, the largest and the smallest value of the faces around
  // it (outside a local net, `others`); a welded vertex takes the largest.
  const RawMesh cut = e.cut_mesh();
  const std::vector<int>& region = e.face_regions();
  const size_t nv = cut.positions.size(), welded = impl_->welded_input.size();
  std::vector<double> high(nv, -1), low(nv, 2);
  for (size_t f = 0; f + 1 < cut.face_offsets.size(); ++f) {
    const double x = region[f] >= 0 ? value[region[f]] : others;
    for (int k = cut.face_offsets[f]; k < cut.face_offsets[f + 1]; ++k) {
      const auto v = static_cast<size_t>(cut.face_vertices[k]);
      high[v] = std::max(high[v], x);
      low[v] = std::min(low[v], x);
    }
  }
  std::vector<double> at(high.begin(), high.begin() + static_cast<std::ptrdiff_t>(welded));
  if (falloff > 0) {
    // From every vertex where two values meet (a curve between them), the
    // nearest such vertex along the cut mesh's edges (Dijkstra, up to the
    // falloff's distance), and its larger value.
    Eigen::AlignedBox3d box;
    for (const Vec3& p : cut.positions)
      box.extend(p);
    const double reach = falloff * box.diagonal().norm();
    std::vector<std::vector<int>> next(nv);
    for (size_t f = 0; f + 1 < cut.face_offsets.size(); ++f)
      for (int k = cut.face_offsets[f]; k < cut.face_offsets[f + 1]; ++k) {
        const int a = cut.face_vertices[k];
        const int c = cut.face_vertices[k + 1 < cut.face_offsets[f + 1] ? k + 1 : cut.face_offsets[f]];
        next[a].push_back(c);
        next[c].push_back(a);
      }
    std::vector<double> dist(nv, std::numeric_limits<double>::infinity()), from(nv, 0);
    using Item = std::pair<double, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    for (size_t v = 0; v < nv; ++v)
      if (high[v] > low[v]) {
        dist[v] = 0;
        from[v] = high[v];
        queue.emplace(0.0, static_cast<int>(v));
      }
    while (!queue.empty()) {
      const auto [d, v] = queue.top();
      queue.pop();
      if (d > dist[v])
        continue;
      for (const int w : next[v]) {
        const double dw = d + (cut.positions[w] - cut.positions[v]).norm();
        if (dw < dist[w] && dw < reach) {
          dist[w] = dw;
          from[w] = from[v];
          queue.emplace(dw, w);
        }
      }
    }
    for (size_t v = 0; v < welded; ++v)
      if (dist[v] < reach && from[v] > at[v]) {
        const double t = dist[v] / reach, fade = 1 - t * t * (3 - 2 * t); // smoothstep down to 0 at the reach
        at[v] = at[v] + (from[v] - at[v]) * fade;
      }
  }
  std::vector<double> mask(impl_->input_to_welded.size());
  for (size_t i = 0; i < mask.size(); ++i) {
    const double x = at[impl_->input_to_welded[i]];
    mask[i] = x >= 0 ? x : others;
  }
  return mask;
}

const std::vector<Joint>& CurveLayer::joints() const {
  return impl_->binding.joints();
}
int CurveLayer::num_input_vertices() const {
  return static_cast<int>(impl_->input_to_welded.size());
}
const Binding& CurveLayer::binding() const {
  return impl_->binding;
}
bool CurveLayer::over_skin() const {
  return impl_->over_skin;
}

void CurveLayer::base_weights(int v, std::vector<std::pair<int, double>>& out) const {
  const Impl& L = *impl_;
  if (!L.over_skin)
    return L.binding.harmonic_weights(v, out);
  out.clear();
  for (int k = 0; k < 4; ++k) {
    const int j = L.skin.vertex_joint.at(static_cast<size_t>(v))[k];
    const double w = L.skin.vertex_weight[v][k];
    if (j >= 0 && w > 0 && L.skin_to_joint[j] >= 0)
      out.emplace_back(L.skin_to_joint[j], w);
  }
}

namespace {

/// Over a skin, the rig on the skin's own skeleton: the same joints by
/// name, whose bind matrices agree to 1e-6 (the rig's file keeps fewer
/// digits), so that the base is the skin exactly.
Rig on_skin_skeleton(const Rig& rig, const SkinnedMesh& skin) {
  std::map<std::string, const Joint*> by_name;
  for (const Joint& j : rig.joints)
    by_name[j.name] = &j;
  const std::set<std::string> weighted = weighted_joints(skin);
  for (const Joint& sj : skin.joints) {
    const auto it = by_name.find(sj.name);
    if (it == by_name.end()) {
      if (weighted.count(sj.name))
        throw InputError(skin.source, "joint '" + sj.name + "'",
                         "the skin weights this joint, which the rig's skeleton lacks: a layer over the skin needs "
                         "the rig on the skin's own skeleton (--skeleton)");
      continue;
    }
    const Mat4 rb = rig.frame * it->second->bind;
    const double scale = 1 + rb.block<3, 1>(0, 3).norm();
    if (weighted.count(sj.name) && (rb - sj.bind).cwiseAbs().maxCoeff() > 1e-6 * scale)
      throw InputError(skin.source, "joint '" + sj.name + "'",
                       "its bind matrix differs from the rig's: a layer over the skin needs the rig on the skin's "
                       "own skeleton (--skeleton)");
  }
  // The skin's joints are in the mesh's space, the rig's in its own.
  std::vector<Joint> joints = skin.joints;
  if (rig.frame != Mat4::Identity()) {
    const Mat4 to_rig = rig.frame.inverse();
    for (Joint& j : joints)
      j.bind = to_rig * j.bind;
  }
  return with_skeleton(rig, std::move(joints), skin.source);
}

/// The displacement on a chain vertex as a sum over joints of M_j times a
/// homogeneous vector (joint -1: the identity): the curve, posed linearly
/// by the chain's weights, minus the linear skin at the input vertices
/// around it.
std::vector<std::pair<int, Eigen::Vector4d>> chain_terms(const CurveLayer::Impl& L, const CurveLayer::Impl::Chain& c) {
  std::vector<std::pair<int, Eigen::Vector4d>> terms;
  auto add = [&](int j, const Eigen::Vector4d& x) {
    for (auto& [k, y] : terms)
      if (k == j) {
        y += x;
        return;
      }
    terms.emplace_back(j, x);
  };
  for (const auto& [j, w] : c.joints)
    add(j, w * c.rest.homogeneous());
  for (const auto& [u, w] : c.surface) {
    const int i = L.welded_input[u];
    const Eigen::Vector4d x = L.input_rest[i].homogeneous();
    double total = 0;
    for (int k = 0; k < 4; ++k) { // as skin_positions() blends them
      const int j = L.skin.vertex_joint[i][k];
      const double s = L.skin.vertex_weight[i][k];
      if (j < 0 || !(s > 0))
        continue;
      add(L.skin_to_joint[j], -w * s * x);
      total += s;
    }
    if (!(total > 0))
      add(-1, -w * x); // a vertex no joint moves stays at rest
  }
  std::sort(terms.begin(), terms.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return terms;
}

/// The correction's precomputed sum (CurveLayer::Impl::LinearSum): each
/// part solved once for the joints its chains name, four columns each.
std::unique_ptr<CurveLayer::Impl::LinearSum> linear_sum(const CurveLayer::Impl& L) {
  using Terms = std::vector<std::pair<int, Eigen::Vector4d>>;
  std::vector<Terms> on_chain(L.chains.size());
  tbb::parallel_for(size_t{0}, L.chains.size(), [&](size_t ci) { on_chain[ci] = chain_terms(L, L.chains[ci]); });
  std::vector<Terms> on_free(static_cast<size_t>(L.num_free));
  tbb::parallel_for(size_t{0}, L.parts.size(), [&](size_t pi) {
    const CurveLayer::Impl::Part& part = L.parts[pi];
    std::vector<int> joints;
    for (const int ci : part.chains)
      for (const auto& [j, x] : on_chain[ci])
        joints.push_back(j);
    std::sort(joints.begin(), joints.end());
    joints.erase(std::unique(joints.begin(), joints.end()), joints.end());
    if (joints.empty())
      return;
    const auto column = [&](int j) {
      return 4 * static_cast<Eigen::Index>(std::lower_bound(joints.begin(), joints.end(), j) - joints.begin());
    };
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(part.size, 4 * static_cast<Eigen::Index>(joints.size()));
    for (int k = 0; k < part.size; ++k)
      for (const auto& [ci, l] : L.fc[part.begin + k])
        for (const auto& [j, x] : on_chain[ci])
          rhs.row(k).segment<4>(column(j)) -= l * x.transpose();
    const Eigen::MatrixXd sol = part.solver->solve(rhs);
    for (int k = 0; k < part.size; ++k)
      for (size_t a = 0; a < joints.size(); ++a) {
        const Eigen::Vector4d x = sol.row(k).segment<4>(4 * static_cast<Eigen::Index>(a)).transpose();
        if (x != Eigen::Vector4d::Zero())
          on_free[part.begin + k].emplace_back(joints[a], x);
      }
  });
  auto sum = std::make_unique<CurveLayer::Impl::LinearSum>();
  sum->begin.push_back(0);
  sum->skin_begin.push_back(0);
  for (size_t i = 0; i < L.input_to_welded.size(); ++i) {
    for (int k = 0; k < 4; ++k) { // in skin_positions()'s order
      const int j = L.skin.vertex_joint[i][k];
      const double w = L.skin.vertex_weight[i][k];
      if (j < 0 || !(w > 0))
        continue;
      sum->skin_joint.push_back(L.skin_to_joint[j]);
      sum->skin_weight.push_back(w);
    }
    sum->skin_begin.push_back(static_cast<int>(sum->skin_joint.size()));
    const int v = L.input_to_welded[i];
    const Terms* t = L.chain_index[v] >= 0  ? &on_chain[L.chain_index[v]]
                     : L.free_index[v] >= 0 ? &on_free[L.free_index[v]]
                                            : nullptr;
    if (t)
      for (const auto& [j, x] : *t) {
        sum->joint.push_back(j);
        sum->vector.push_back(x);
      }
    sum->begin.push_back(static_cast<int>(sum->joint.size()));
  }
  return sum;
}

} // namespace

CurveLayer bind_layer(const SurfaceMesh& mesh, const Rig& rig, const SkinnedMesh* skin, const LayerOptions& opt,
                      const Binding* bound) {
  const bool reuse = bound && !skin && bound->has_embedding() &&
                     bound->num_input_vertices() == static_cast<int>(mesh.input_to_welded.size());
  auto impl = std::make_shared<CurveLayer::Impl>(
      reuse ? *bound : bind(mesh, skin ? on_skin_skeleton(rig, *skin) : rig, opt.bind));
  CurveLayer::Impl& L = *impl;
  const Binding& b = L.binding;
  const std::vector<Joint>& joints = b.joints();
  std::map<std::string, int> joint_index;
  for (size_t j = 0; j < joints.size(); ++j)
    joint_index[joints[j].name] = static_cast<int>(j);
  L.input_to_welded = mesh.input_to_welded;
  L.num_welded = mesh.num_vertices();
  L.welded_input.assign(mesh.num_vertices(), -1);
  for (size_t i = 0; i < mesh.input_to_welded.size(); ++i) {
    L.input_rest.push_back(mesh.positions[mesh.input_to_welded[i]]);
    if (L.welded_input[mesh.input_to_welded[i]] < 0)
      L.welded_input[mesh.input_to_welded[i]] = static_cast<int>(i);
  }
  const int ni = static_cast<int>(L.input_to_welded.size());
  L.dual = opt.bind.method != DeformMethod::Harmonic;
  L.skinning = opt.skinning;
  if (skin) {
    L.over_skin = true;
    L.skin = *skin;
    if (L.skin.vertex_joint.size() != static_cast<size_t>(ni))
      throw InputError(skin->source, "skin",
                       std::to_string(L.skin.vertex_joint.size()) + " skinned vertices for a mesh of " +
                           std::to_string(ni) + ": the skin is not this mesh's");
    for (const Joint& sj : L.skin.joints)
      L.skin_to_joint.push_back(joint_index.at(sj.name)); // the rig is on the skin's skeleton
  }

  // The chains and where each lies on the input surface.
  Rig completed = rig;
  completed.weights = b.node_weights();
  for (const Node& n : completed.nodes)
    L.node_ids.push_back(n.id);
  const Embedding::Impl& emb = b.embedding().impl();
  const CutMesh& cut = emb.cut;
  const int nc = cut.num_vertices();
  const ChainConstraints cc = chain_constraints(emb, completed, joint_index);
  L.chain_index.assign(nc, -1);
  L.cut_surface.resize(nc);
  for (int v = 0; v < nc; ++v)
    L.cut_surface[v] = cut.input_weights(Vertex(v));
  for (int v = 0; v < nc; ++v) {
    if (!cc.constrained[v])
      continue;
    CurveLayer::Impl::Chain c{v,      cut.position(Vertex(v)), {}, L.cut_surface[v], cc.nodes[v][0], cc.nodes[v][1],
                              cc.t[v]};
    for (const auto& [j, w] : cc.cw[v])
      c.joints.emplace_back(j, w);
    L.chain_index[v] = static_cast<int>(L.chains.size());
    L.chains.push_back(std::move(c));
  }

  // The harmonic extension over the parts the chains reach; elsewhere no
  // correction.
  const Eigen::SparseMatrix<double> lap = cut_mesh_laplacian(
      cut, opt.bind.laplacian == LaplacianChoice::Uniform ? LaplacianKind::Uniform : LaplacianKind::IntrinsicDelaunay);
  std::vector<char> reached(nc, 0);
  std::vector<int> stack;
  for (const auto& c : L.chains)
    stack.push_back(c.vertex);
  for (int v : stack)
    reached[v] = 1;
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    for (Eigen::SparseMatrix<double>::InnerIterator it(lap, v); it; ++it) {
      const int u = static_cast<int>(it.row());
      if (it.value() != 0 && !reached[u]) {
        reached[u] = 1;
        stack.push_back(u);
      }
    }
  }
  // The parts: the free vertices joined by nonzero Laplacian entries,
  // numbered part by part.
  L.free_index.assign(nc, -1);
  std::vector<int> free_vertex; // free row -> cut vertex
  for (int seed = 0; seed < nc; ++seed) {
    if (!reached[seed] || cc.constrained[seed] || L.free_index[seed] >= 0)
      continue;
    CurveLayer::Impl::Part part;
    part.begin = L.num_free;
    L.free_index[seed] = L.num_free++;
    free_vertex.push_back(seed);
    for (size_t k = static_cast<size_t>(part.begin); k < free_vertex.size(); ++k)
      for (Eigen::SparseMatrix<double>::InnerIterator it(lap, free_vertex[k]); it; ++it) {
        const int u = static_cast<int>(it.row());
        if (it.value() != 0 && reached[u] && !cc.constrained[u] && L.free_index[u] < 0) {
          L.free_index[u] = L.num_free++;
          free_vertex.push_back(u);
        }
      }
    part.size = L.num_free - part.begin;
    L.parts.push_back(std::move(part));
  }
  L.fc.resize(L.num_free);
  // Each part's L_ff block, factored on its own (in parallel: the parts are
  // independent).
  tbb::parallel_for(size_t{0}, L.parts.size(), [&](size_t pi) {
    CurveLayer::Impl::Part& part = L.parts[pi];
    std::vector<Eigen::Triplet<double>> ff;
    for (int k = part.begin; k < part.begin + part.size; ++k)
      for (Eigen::SparseMatrix<double>::InnerIterator it(lap, free_vertex[k]); it; ++it) {
        const int u = static_cast<int>(it.row());
        if (L.free_index[u] >= 0)
          ff.emplace_back(k - part.begin, L.free_index[u] - part.begin, it.value());
        else if (L.chain_index[u] >= 0) {
          L.fc[k].emplace_back(L.chain_index[u], it.value());
          part.chains.push_back(L.chain_index[u]);
        }
      }
    std::sort(part.chains.begin(), part.chains.end());
    part.chains.erase(std::unique(part.chains.begin(), part.chains.end()), part.chains.end());
    Eigen::SparseMatrix<double> Lff(part.size, part.size);
    Lff.setFromTriplets(ff.begin(), ff.end());
    part.solver = std::make_unique<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>(Lff);
  });
  for (const auto& part : L.parts)
    if (part.solver->info() != Eigen::Success)
      throw EmbedError("layer: the harmonic system could not be factored on " + mesh.source);
  if (L.over_skin && L.skinning == Skinning::Linear && !L.dual && opt.precompute_linear)
    L.linear = linear_sum(L);
  return CurveLayer(impl).with_mask(opt.mask);
}

void CurveLayer::deform(std::span<const Mat4> M, std::span<Vec3> out, double envelope,
                        const NodeOffsets* offsets) const {
  deform_impl(M, out, envelope, offsets, nullptr);
}

void CurveLayer::deform_cut(std::span<const Mat4> M, std::vector<Vec3>& cut, double envelope,
                            const NodeOffsets* offsets) const {
  std::vector<Vec3> out(static_cast<size_t>(num_input_vertices()));
  deform_impl(M, out, envelope, offsets, &cut);
}

void CurveLayer::deform_impl(std::span<const Mat4> M, std::span<Vec3> out, double envelope, const NodeOffsets* offsets,
                             std::vector<Vec3>* cut) const {
  const Impl& L = *impl_;
  const std::vector<Joint>& joints = L.binding.joints();
  const size_t ni = L.input_to_welded.size();
  if (M.size() != joints.size() || out.size() != ni)
    throw Error("layer: expected " + std::to_string(joints.size()) + " skinning matrices and room for " +
                std::to_string(ni) + " positions, got " + std::to_string(M.size()) + " and " +
                std::to_string(out.size()));
  if (L.linear && envelope != 0 && !cut && !(offsets && !offsets->empty())) {
    linear_frame(M, out, envelope);
    return;
  }
  // The base.
  if (L.over_skin) {
    std::vector<Mat4> skin_matrices(L.skin_to_joint.size(), Mat4::Identity());
    for (size_t k = 0; k < L.skin_to_joint.size(); ++k)
      if (L.skin_to_joint[k] >= 0)
        skin_matrices[k] = M[L.skin_to_joint[k]];
    const std::vector<Vec3> base = skin_positions(L.skin, L.input_rest, skin_matrices, L.skinning);
    std::copy(base.begin(), base.end(), out.begin());
  } else {
    L.binding.deform(M, out);
  }
  const bool offset = offsets && !offsets->empty();
  if (cut) { // the cut mesh on the base surface, corrected below
    cut->assign(L.cut_surface.size(), Vec3::Zero());
    for (size_t v = 0; v < L.cut_surface.size(); ++v)
      for (const auto& [u, w] : L.cut_surface[v])
        (*cut)[v] += w * out[L.welded_input[u]];
  }
  // Over the net's own deformation the cut mesh's chains go to the posed
  // curves whatever the envelope: the net's deformation puts them there, and
  // the base gives only the chords between the input vertices.
  const bool cut_curves = cut && !L.over_skin && !L.chains.empty();
  const bool correct = envelope != 0 && (L.over_skin || offset) && !L.chains.empty();
  if (!correct && !cut_curves)
    return; // the base exactly
  std::vector<Vec3> node_offset;
  if (offset) {
    node_offset.assign(L.node_ids.size(), Vec3::Zero());
    for (const auto& [id, o] : *offsets) {
      const auto it = std::find(L.node_ids.begin(), L.node_ids.end(), id);
      if (it == L.node_ids.end())
        throw InputError("pose", "/nodes/" + id, "the rig has no node of this id");
      if (!o.allFinite())
        throw InputError("pose", "/nodes/" + id, "the offset is not finite");
      node_offset[it - L.node_ids.begin()] = o;
    }
  }
  // The displacement on the chains: from the base surface to the posed
  // curve (over a skin), plus the posed offsets.
  std::vector<DualJoint> dj(M.size());
  for (size_t j = 0; j < M.size(); ++j)
    dj[j] = split_joint(M[j]);
  auto base_at = [&](const std::vector<std::pair<int, double>>& surface) {
    Vec3 p = Vec3::Zero();
    for (const auto& [v, w] : surface)
      p += w * out[L.welded_input[v]];
    return p;
  };
  Eigen::MatrixXd dc(static_cast<Eigen::Index>(L.chains.size()), 3);
  Eigen::MatrixXd dk(cut_curves ? static_cast<Eigen::Index>(L.chains.size()) : 0, 3); // chords to curves
  // Each chain vertex on its own (the same on any thread count).
  tbb::parallel_for(tbb::blocked_range<size_t>(0, L.chains.size(), 512), [&](const tbb::blocked_range<size_t>& r) {
    DualBlend blend;
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const Impl::Chain& c = L.chains[i];
      auto posed = [&](const Vec3& x) {
        if (L.dual) {
          blend.clear();
          for (const auto& [j, w] : c.joints)
            blend.add(dj[j], w);
          if (blend.valid())
            return blend.apply(x);
        }
        Vec3 p = Vec3::Zero();
        for (const auto& [j, w] : c.joints)
          p += w * (M[j] * x.homogeneous()).head<3>();
        return p;
      };
      const Vec3 curve = posed(c.rest);
      Vec3 d = L.over_skin ? Vec3(curve - base_at(c.surface)) : Vec3::Zero();
      if (cut_curves)
        dk.row(static_cast<Eigen::Index>(i)) = (curve - base_at(c.surface)).transpose();
      if (offset) {
        const Vec3 o = (1 - c.t) * node_offset[c.node_a] + c.t * node_offset[c.node_b];
        if (o != Vec3::Zero())
          d += posed(c.rest + o) - curve;
      }
      dc.row(static_cast<Eigen::Index>(i)) = d.transpose();
    }
  });
  // The harmonic extension of chain values: each part whose chains move
  // solves for its free vertices; the others stay where the base puts them.
  auto extend = [&](const Eigen::MatrixXd& on_chains) {
    Eigen::MatrixXd free = Eigen::MatrixXd::Zero(L.num_free, 3);
    tbb::parallel_for(size_t{0}, L.parts.size(), [&](size_t pi) {
      const Impl::Part& part = L.parts[pi];
      if (std::none_of(part.chains.begin(), part.chains.end(),
                       [&](int ci) { return on_chains.row(ci).squaredNorm() != 0; }))
        return;
      Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(part.size, 3);
      for (int k = 0; k < part.size; ++k)
        for (const auto& [ci, l] : L.fc[part.begin + k])
          rhs.row(k) -= l * on_chains.row(ci);
      free.middleRows(part.begin, part.size) = part.solver->solve(rhs);
    });
    return free;
  };
  auto at = [&](const Eigen::MatrixXd& on_chains, const Eigen::MatrixXd& free, int v) {
    return L.chain_index[v] >= 0  ? Vec3(on_chains.row(L.chain_index[v]).transpose())
           : L.free_index[v] >= 0 ? Vec3(free.row(L.free_index[v]).transpose())
                                  : Vec3::Zero();
  };
  if (cut_curves) {
    const Eigen::MatrixXd fk = extend(dk);
    for (size_t v = 0; v < cut->size(); ++v)
      (*cut)[v] += at(dk, fk, static_cast<int>(v));
  }
  if (!correct)
    return;
  const Eigen::MatrixXd df = extend(dc);
  for (size_t i = 0; i < ni; ++i) {
    const int v = L.input_to_welded[i];
    const double s = envelope * (mask_ ? (*mask_)[i] : 1.0);
    if (s == 0)
      continue;
    out[i] += s * at(dc, df, v);
  }
  if (cut) // the mask is per input vertex: the cut mesh takes the whole correction
    for (size_t v = 0; v < cut->size(); ++v)
      (*cut)[v] += envelope * at(dc, df, static_cast<int>(v));
  for (size_t i = 0; i < ni; ++i)
    if (!out[i].allFinite())
      throw InputError("pose", "vertex " + std::to_string(i),
                       "the pose moves it out of range (not a finite number); nothing was written");
}

void CurveLayer::linear_frame(std::span<const Mat4> M, std::span<Vec3> out, double envelope) const {
  // The skin and the precomputed sum, vertex by vertex in one pass. The
  // skin is blended with skin_positions()'s arithmetic, in its order, so
  // that a vertex masked with 0 is the skin.
  const Impl& L = *impl_;
  const Impl::LinearSum& sum = *L.linear;
  const size_t ni = L.input_to_welded.size();
  std::atomic<size_t> first_bad = ni;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ni, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const Eigen::Vector4d x = L.input_rest[i].homogeneous();
      Eigen::Vector4d acc = Eigen::Vector4d::Zero();
      for (int k = sum.skin_begin[i]; k < sum.skin_begin[i + 1]; ++k) {
        const int j = sum.skin_joint[k];
        acc += sum.skin_weight[k] * (j >= 0 ? Eigen::Vector4d(M[j] * x) : x);
      }
      Vec3 p = sum.skin_begin[i] < sum.skin_begin[i + 1] ? Vec3(acc.head<3>()) : L.input_rest[i];
      const double s = envelope * (mask_ ? (*mask_)[i] : 1.0);
      if (s != 0 && sum.begin[i] != sum.begin[i + 1]) {
        Vec3 d = Vec3::Zero();
        for (int k = sum.begin[i]; k < sum.begin[i + 1]; ++k) {
          const int j = sum.joint[k];
          d += j < 0 ? Vec3(sum.vector[k].head<3>()) : Vec3(M[j].topRows<3>() * sum.vector[k]);
        }
        p += s * d;
      }
      out[i] = p;
      if (!p.allFinite()) {
        size_t seen = first_bad.load();
        while (i < seen && !first_bad.compare_exchange_weak(seen, i)) {
        }
      }
    }
  });
  if (first_bad < ni)
    throw InputError("pose", "vertex " + std::to_string(first_bad.load()),
                     "the pose moves it out of range (not a finite number); nothing was written");
}

void CurveLayer::rest_correction(std::span<const Mat4> M, std::span<Vec3> out, double envelope,
                                 const NodeOffsets* offsets) const {
  const Impl& L = *impl_;
  if (!L.over_skin)
    throw Error("rest_correction: the layer is not over a skin");
  const size_t ni = L.input_to_welded.size();
  std::vector<Vec3> layered(ni);
  deform(M, layered, envelope, offsets);
  if (out.size() != ni)
    throw Error("rest_correction: room for " + std::to_string(out.size()) + " positions, not " + std::to_string(ni));
  std::vector<Mat4> skin_matrices(L.skin_to_joint.size(), Mat4::Identity());
  for (size_t k = 0; k < L.skin_to_joint.size(); ++k)
    if (L.skin_to_joint[k] >= 0)
      skin_matrices[k] = M[L.skin_to_joint[k]];
  // The skin at each vertex is affine in the rest position: its linear part
  // from the images of the rest position moved along each axis.
  const std::vector<Vec3> base = skin_positions(L.skin, L.input_rest, skin_matrices, L.skinning);
  std::array<std::vector<Vec3>, 3> moved;
  for (int k = 0; k < 3; ++k) {
    std::vector<Vec3> shifted = L.input_rest;
    for (Vec3& p : shifted)
      p[k] += 1;
    moved[k] = skin_positions(L.skin, shifted, skin_matrices, L.skinning);
  }
  for (size_t i = 0; i < ni; ++i) {
    Eigen::Matrix3d A;
    for (int k = 0; k < 3; ++k)
      A.col(k) = moved[k][i] - base[i];
    const Vec3 d = layered[i] - base[i];
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(A);
    out[i] = lu.isInvertible() ? Vec3(lu.solve(d)) : d;
  }
}

void CurveLayer::deform_frames(std::span<const Mat4> M, std::span<Vec3> out, double envelope) const {
  const size_t nj = joints().size(), nv = static_cast<size_t>(num_input_vertices());
  const size_t frames = nj ? M.size() / nj : 0;
  if (nj == 0 || M.size() % nj != 0 || out.size() != frames * nv)
    throw Error("layer: " + std::to_string(M.size()) + " matrices and " + std::to_string(out.size()) +
                " positions do not make whole frames");
  tbb::parallel_for(size_t{0}, frames,
                    [&](size_t f) { deform(M.subspan(f * nj, nj), out.subspan(f * nv, nv), envelope); });
}

} // namespace curvenet
