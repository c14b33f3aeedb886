// Binding: constraints on the CutChains, the factored harmonic system, and
// per input vertex the harmonic joint weights and rest terms. Deforming: a
// sum over each vertex's joints (docs/deform.md).

#include "core/fnv1a.hpp"
#include "curvenet/deform.hpp"

#include "bind/bone_heat.hpp"
#include "bind/constraints.hpp"
#include "bind/gradient.hpp"
#include "bind/laplacian.hpp"
#include "core/dual_quaternion.hpp"
#include "core/tolerances.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "embed/embedding_impl.hpp"
#include "trace/trace_mesh.hpp"

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <Eigen/SVD>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <optional>
#include <sstream>
#include <string_view>
#include <type_traits>

namespace curvenet {

using namespace detail;

struct Binding::Impl {
  std::uint64_t fingerprint = 0; ///< of the mesh, rig and options it was made from
  std::vector<Joint> joints;     ///< mesh space
  BindReport report;
  Embedding embedding{nullptr};
  std::map<std::string, std::map<std::string, double>> node_weights;
  std::vector<int> input_to_welded;
  RigidMode mode = RigidMode::PerVertex;
  double horn_tolerance = 0.1;
  // Per welded vertex: influences (joint, s_j, Y_j), and the detail delta = X - H p.
  std::vector<int> offset;
  std::vector<int> joint;
  std::vector<double> s;
  std::vector<Eigen::Vector3d> Y;
  std::vector<Eigen::Vector3d> delta;
  std::vector<Eigen::Vector3d> rest; ///< per welded vertex (the dual-quaternion mode)
  // Horn mode: the constraints (rest position, weights).
  std::vector<Eigen::Vector3d> c_rest;
  std::vector<int> c_offset, c_joint;
  std::vector<double> c_weight;
  // The gradient mode's tables (DeformMethod::Gradient).
  std::shared_ptr<const GradientBind> gradient;
  DeformMethod method = DeformMethod::DualQuaternion;
};

const char* to_string(DeformMethod method) {
  switch (method) {
  case DeformMethod::Harmonic:
    return "harmonic";
  case DeformMethod::Gradient:
    return "gradient";
  case DeformMethod::DualQuaternion:
    return "dq";
  }
  return "?";
}

bool parse_deform_method(const std::string& name, DeformMethod& method) {
  for (const DeformMethod m : {DeformMethod::DualQuaternion, DeformMethod::Harmonic, DeformMethod::Gradient})
    if (name == to_string(m)) {
      method = m;
      return true;
    }
  return false;
}

const char* to_string(InteriorWeights interior) {
  return interior == InteriorWeights::BoneHeat ? "bone-heat" : "harmonic";
}

bool parse_interior_weights(const std::string& name, InteriorWeights& interior) {
  for (const InteriorWeights i : {InteriorWeights::BoneHeat, InteriorWeights::Harmonic})
    if (name == to_string(i)) {
      interior = i;
      return true;
    }
  return false;
}

Binding::Binding(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}
const std::vector<Joint>& Binding::joints() const {
  return impl_->joints;
}
const BindReport& Binding::report() const {
  return impl_->report;
}
bool Binding::has_embedding() const {
  return impl_->embedding.has_impl();
}
const Embedding& Binding::embedding() const {
  if (!has_embedding())
    throw Error("this binding was read from a cache file and has no embedding");
  return impl_->embedding;
}
const std::map<std::string, std::map<std::string, double>>& Binding::node_weights() const {
  return impl_->node_weights;
}
int Binding::num_input_vertices() const {
  return static_cast<int>(impl_->input_to_welded.size());
}

Rig complete_weights(const Rig& rig, const AutoWeightOptions& options) {
  if (!rig.has_skeleton || rig.joints.empty())
    throw InputError("rig", "/skeleton", "binding needs a skeleton");
  Rig out = rig;
  out.weights.clear();
  for (const Node& n : rig.nodes) {
    std::map<std::string, double> w;
    auto it = rig.weights.find(n.id);
    // Normalised without overflow: {1e308, 1e308} is two halves.
    double largest = 0, sum = 0;
    if (it != rig.weights.end()) {
      for (const auto& [j, v] : it->second)
        largest = std::max(largest, v);
      if (largest > 0)
        for (const auto& [j, v] : it->second)
          sum += v / largest;
    }
    if (sum > 0) {
      for (const auto& [j, v] : it->second)
        if (v > 0)
          w[j] = (v / largest) / sum;
    } else {
      for (const auto& [j, v] : auto_weights(rig.joints, n.position, options))
        w[rig.joints[j].name] = v;
    }
    out.weights[n.id] = w;
  }
  return out;
}

namespace {

/// Interior weights under this are dropped (bone heat; the curves' own are kept).
constexpr double kInteriorFloor = 1e-3;

/// FNV-1a over the mesh, the rig as written, and the options.
std::uint64_t fingerprint(const SurfaceMesh& mesh, const Rig& rig, const BindOptions& opt) {
  detail::Fnv1a h;
  auto eat = [&](const void* data, size_t n) { h.eat(data, n); };
  for (const auto& p : mesh.positions)
    eat(p.data(), 3 * sizeof(double));
  eat(mesh.face_offsets.data(), mesh.face_offsets.size() * sizeof(int));
  eat(mesh.face_vertices.data(), mesh.face_vertices.size() * sizeof(int));
  eat(mesh.input_to_welded.data(), mesh.input_to_welded.size() * sizeof(int));
  const std::string text = rig_to_json(rig);
  eat(text.data(), text.size());
  const int options[] = {static_cast<int>(opt.laplacian),
                         static_cast<int>(opt.rigid),
                         static_cast<int>(opt.weights.rule),
                         static_cast<int>(opt.method),
                         opt.cut_aware ? 1 : 0,
                         static_cast<int>(opt.rotation_blend),
                         opt.curve_frames ? 1 : 0,
                         opt.sections ? 1 : 0,
                         opt.method == DeformMethod::DualQuaternion ? static_cast<int>(opt.interior) : 0};
  eat(options, sizeof(options));
  const double numbers[] = {opt.weights.blend, opt.horn_tolerance, opt.embed.density};
  eat(numbers, sizeof(numbers));
  return h.value;
}

constexpr char kMagic[8] = {'C', 'N', 'B', 'I', 'N', 'D', '0', '2'};

std::uint64_t checksum(const char* data, size_t n) {
  return detail::fnv1a({data, n});
}

template <class T> void put(std::string& out, const std::vector<T>& v) {
  const std::uint64_t n = v.size();
  out.append(reinterpret_cast<const char*>(&n), sizeof(n));
  out.append(reinterpret_cast<const char*>(v.data()), n * sizeof(T));
}

/// Reads a cache file from memory: every read is bounded by what is left.
class CacheReader {
public:
  explicit CacheReader(std::string_view data) : data_(data) {}
  template <class T> bool value(T& v) {
    if (data_.size() - at_ < sizeof(T))
      return false;
    std::memcpy(&v, data_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return true;
  }
  template <class T> bool vector(std::vector<T>& v) {
    std::uint64_t n = 0;
    if (!value(n) || n > (data_.size() - at_) / sizeof(T))
      return false;
    v.resize(n);
    if (n > 0) // an empty vector's data() may be null, which memcpy may not take even for 0 bytes
      std::memcpy(static_cast<void*>(v.data()), data_.data() + at_, n * sizeof(T));
    at_ += n * sizeof(T);
    return true;
  }

private:
  std::string_view data_;
  size_t at_ = 0;
};

/// The tables of a binding read from a cache are consistent with the mesh
/// and the rig: sizes, offsets, joint indices, finite numbers. A cache that
/// fails any of these is rebuilt.
bool consistent(const Binding::Impl& b, const SurfaceMesh& mesh, size_t joints) {
  const size_t nv = static_cast<size_t>(mesh.num_vertices());
  auto offsets_ok = [](const std::vector<int>& off, size_t rows, size_t items) {
    if (off.size() != rows + 1 || off.front() != 0 || static_cast<size_t>(off.back()) != items)
      return false;
    for (size_t i = 0; i + 1 < off.size(); ++i)
      if (off[i] > off[i + 1])
        return false;
    return true;
  };
  auto joints_ok = [joints](const std::vector<int>& js) {
    return std::all_of(js.begin(), js.end(), [joints](int j) { return j >= 0 && static_cast<size_t>(j) < joints; });
  };
  auto finite = [](const auto& v) {
    return std::all_of(v.begin(), v.end(), [](const auto& x) {
      if constexpr (std::is_same_v<std::decay_t<decltype(x)>, double>)
        return std::isfinite(x);
      else
        return x.allFinite();
    });
  };
  const size_t nc = b.c_rest.size();
  return b.input_to_welded == mesh.input_to_welded && offsets_ok(b.offset, nv, b.joint.size()) &&
         b.s.size() == b.joint.size() && b.Y.size() == b.joint.size() && b.delta.size() == nv && joints_ok(b.joint) &&
         finite(b.s) && finite(b.Y) && finite(b.delta) && std::isfinite(b.horn_tolerance) &&
         (nc == 0 ? b.c_offset.size() <= 1 : offsets_ok(b.c_offset, nc, b.c_joint.size())) &&
         b.c_weight.size() == b.c_joint.size() && joints_ok(b.c_joint) && finite(b.c_rest) && finite(b.c_weight);
}

/// The joints whose bones heat the inside of the regions: those the rig's
/// nodes name, and their descendants inside the mesh (the joint, or the
/// middle of the bone to it): a bone that bends an ear or a toe which the
/// net gives no ring. Helpers outside the body (IK poles and targets, a
/// root on the floor) are left out unless a node names them.
std::vector<char> deforming_joints(const SurfaceMesh& mesh, const Rig& rig, const std::vector<Joint>& joints,
                                   const std::map<std::string, int>& joint_index) {
  const int nj = static_cast<int>(joints.size());
  std::vector<char> named(nj, 0), out(nj, 0);
  for (const auto& [node, w] : rig.weights)
    for (const auto& [name, x] : w)
      if (x > 0)
        named[joint_index.at(name)] = 1;
  const std::vector<int> parent = joint_parents(joints);
  auto origin = [&](int j) -> Eigen::Vector3d { return joints[j].bind.block<3, 1>(0, 3); };
  for (int j = 0; j < nj; ++j) { // parents come before children (the rig's rule)
    out[j] = named[j];
    if (out[j] || parent[j] < 0)
      continue;
    bool below_named = false;
    for (int a = parent[j]; a >= 0 && !below_named; a = parent[a])
      below_named = named[a] != 0;
    out[j] = below_named &&
             (mesh.winding_number(origin(j)) >= 0.5 || mesh.winding_number((origin(j) + origin(parent[j])) / 2) >= 0.5);
  }
  return out;
}

} // namespace

std::string report_to_json(const BindReport& r) {
  nlohmann::ordered_json j;
  j["vertices"] = r.vertices;
  j["constrained"] = r.constrained;
  j["free"] = r.free;
  j["rigid"] = r.rigid;
  j["influences"] = r.influences;
  j["mean_influences"] = r.mean_influences;
  j["negative_weights_before"] = r.negative_weights_before;
  j["negative_weights_after"] = r.negative_weights_after;
  j["negative_weights_solved"] = r.negative_weights_solved;
  j["flips"] = r.flips;
  nlohmann::ordered_json t = nlohmann::ordered_json::object();
  for (const auto& [stage, ms] : r.timings_ms)
    t[stage] = ms;
  j["timings_ms"] = t;
  j["notes"] = r.notes;
  return j.dump(2);
}

DeformMethod Binding::method() const {
  return impl_->method;
}

void Binding::save(const std::string& path) const {
  write_file_atomic(path, cache_bytes(path));
}

std::string Binding::cache_bytes(const std::string& path) const {
  const Impl& b = *impl_;
  if (b.gradient)
    throw Error("binding cache " + path + ": a binding in the gradient mode is not cached (bind it again instead)");
  std::string out(kMagic, sizeof(kMagic));
  out.append(reinterpret_cast<const char*>(&b.fingerprint), sizeof(b.fingerprint));
  const int mode = static_cast<int>(b.mode);
  out.append(reinterpret_cast<const char*>(&mode), sizeof(mode));
  out.append(reinterpret_cast<const char*>(&b.horn_tolerance), sizeof(double));
  std::vector<double> binds;
  for (const auto& j : b.joints)
    for (int k = 0; k < 16; ++k)
      binds.push_back(j.bind(k / 4, k % 4));
  put(out, binds);
  put(out, b.input_to_welded);
  put(out, b.offset);
  put(out, b.joint);
  put(out, b.s);
  put(out, b.Y);
  put(out, b.delta);
  put(out, b.c_rest);
  put(out, b.c_offset);
  put(out, b.c_joint);
  put(out, b.c_weight);
  // A checksum of everything before it, last.
  const std::uint64_t sum = checksum(out.data(), out.size());
  out.append(reinterpret_cast<const char*>(&sum), sizeof(sum));
  return out;
}

Binding bind_cached(const SurfaceMesh& mesh, const Rig& rig, const BindOptions& opt, const std::string& path,
                    bool* reused, OutputFiles* outputs) {
  if (opt.method == DeformMethod::Gradient)
    throw InputError(path, "", "the gradient mode keeps no binding cache: bind without one");
  // A cache is read back and replaced: a FIFO would block the read, and a
  // device or a folder is not a place to keep one.
  std::error_code ec;
  if (const auto st = std::filesystem::status(path, ec);
      !ec && st.type() != std::filesystem::file_type::not_found && st.type() != std::filesystem::file_type::regular)
    throw InputError(path, "",
                     "a binding cache is read back and rewritten: give a regular file, not a device, a FIFO "
                     "or a folder");
  const std::uint64_t fp = fingerprint(mesh, rig, opt);
  std::string note;
  if (std::ifstream in{path, std::ios::binary}) {
    std::ostringstream text;
    text << in.rdbuf();
    const std::string data = text.str();
    auto impl = std::make_shared<Binding::Impl>();
    char magic[sizeof(kMagic)];
    std::uint64_t file_fp = 0, sum = 0;
    int mode = 0;
    std::vector<double> binds;
    // The fingerprint as written, to tell a damaged cache from another one.
    if (data.size() >= sizeof(kMagic) + sizeof(file_fp))
      std::memcpy(&file_fp, data.data() + sizeof(kMagic), sizeof(file_fp));
    const std::uint64_t written_fp = file_fp;
    bool ok = data.size() > sizeof(sum);
    if (ok) {
      std::memcpy(&sum, data.data() + data.size() - sizeof(sum), sizeof(sum));
      ok = sum == checksum(data.data(), data.size() - sizeof(sum));
    }
    CacheReader r(std::string_view(data).substr(0, ok ? data.size() - sizeof(sum) : 0));
    ok = ok && r.value(magic) && std::memcmp(magic, kMagic, sizeof(kMagic)) == 0 && r.value(file_fp) && file_fp == fp &&
         r.value(mode) && (mode == 0 || mode == 1) && r.value(impl->horn_tolerance) && r.vector(binds) &&
         r.vector(impl->input_to_welded) && r.vector(impl->offset) && r.vector(impl->joint) && r.vector(impl->s) &&
         r.vector(impl->Y) && r.vector(impl->delta) && r.vector(impl->c_rest) && r.vector(impl->c_offset) &&
         r.vector(impl->c_joint) && r.vector(impl->c_weight);
    ok = ok && binds.size() == 16 * rig.joints.size() &&
         std::all_of(binds.begin(), binds.end(), [](double x) { return std::isfinite(x); }) &&
         consistent(*impl, mesh, rig.joints.size());
    if (ok) {
      impl->fingerprint = fp;
      impl->method = opt.method;
      impl->rest = mesh.positions;
      impl->mode = static_cast<RigidMode>(mode);
      for (size_t j = 0; j < rig.joints.size(); ++j) {
        Joint jt = rig.joints[j];
        for (int k = 0; k < 16; ++k)
          jt.bind(k / 4, k % 4) = binds[16 * j + k];
        impl->joints.push_back(jt);
      }
      impl->report.vertices = mesh.num_vertices();
      impl->report.influences = static_cast<int>(impl->joint.size());
      impl->report.mean_influences =
          mesh.num_vertices() > 0 ? static_cast<double>(impl->joint.size()) / mesh.num_vertices() : 0;
      impl->report.notes.push_back("read from the binding cache " + path);
      impl->node_weights = complete_weights(rig, opt.weights).weights;
      if (reused)
        *reused = true;
      return Binding(impl);
    }
    // Another mesh, rig or options, or a damaged file: bind afresh.
    note = written_fp == fp
               ? "the binding cache " + path + " was damaged (its checksum or tables are wrong); rebuilt it"
               : "the binding cache " + path + " was made for another mesh, rig or options; rebuilt it";
  }
  Binding b = bind(mesh, rig, opt);
  if (outputs)
    outputs->add(path, b.cache_bytes(path)); // written with the command's other outputs, or not at all
  else
    b.save(path);
  if (!note.empty())
    std::const_pointer_cast<Binding::Impl>(b.impl_)->report.notes.push_back(note);
  if (reused)
    *reused = false;
  return b;
}

ChainConstraints detail::chain_constraints(const Embedding::Impl& emb, const Rig& rig,
                                           const std::map<std::string, int>& joint_index) {
  const int nc = emb.cut.num_vertices();
  ChainConstraints out;
  out.constrained.assign(nc, 0);
  out.cw.resize(nc);
  out.nodes.assign(nc, {-1, -1});
  out.t.assign(nc, 0.0);
  auto node_w = [&](int node) {
    std::map<int, double> w;
    for (const auto& [name, v] : rig.weights.at(rig.nodes[node].id))
      w[joint_index.at(name)] = v;
    return w;
  };
  for (size_t p = 0; p < emb.result.chains.size(); ++p) {
    const auto& chain = emb.result.chains[p];
    const int na = emb.input.profile_from[p], nb = emb.input.profile_to[p];
    const auto wa = node_w(na), wb = node_w(nb);
    for (size_t i = 0; i < chain.vertices.size(); ++i) {
      const int v = chain.vertices[i].idx;
      if (out.constrained[v])
        continue; // a node, already set (nodes come first and last in their chains)
      out.constrained[v] = 1;
      out.nodes[v] = {na, nb};
      std::map<int, double> w;
      if (i == 0) {
        w = wa;
      } else if (i + 1 == chain.vertices.size()) {
        w = wb;
        out.t[v] = 1;
      } else {
        const double t = emb.chain_t(static_cast<int>(p), i);
        out.t[v] = t;
        for (const auto& [j, x] : wa)
          w[j] += (1 - t) * x;
        for (const auto& [j, x] : wb)
          w[j] += t * x;
        double sum = 0;
        for (const auto& [j, x] : w)
          sum += x;
        for (auto& [j, x] : w)
          x /= sum;
      }
      out.cw[v] = std::move(w);
    }
  }
  return out;
}

Binding bind(const SurfaceMesh& mesh, const Rig& input_rig, const BindOptions& opt) {
  auto impl = std::make_shared<Binding::Impl>();
  impl->fingerprint = fingerprint(mesh, input_rig, opt);
  impl->method = opt.method;
  impl->rest = mesh.positions;
  BindReport& rep = impl->report;
  auto t0 = std::chrono::steady_clock::now();
  auto lap = [&](const char* stage) {
    const auto now = std::chrono::steady_clock::now();
    rep.timings_ms.emplace_back(stage, std::chrono::duration<double, std::milli>(now - t0).count());
    t0 = now;
  };
  const Rig rig = complete_weights(input_rig, opt.weights);
  impl->node_weights = rig.weights;
  std::map<std::string, int> joint_index;
  for (size_t j = 0; j < rig.joints.size(); ++j) {
    joint_index[rig.joints[j].name] = static_cast<int>(j);
    Joint jt = rig.joints[j];
    jt.bind = rig.frame * jt.bind; // into mesh space
    impl->joints.push_back(jt);
  }
  const int nj = static_cast<int>(rig.joints.size());
  lap("weights");

  // Bone heat is a field of the input surface, whatever the net: it is
  // solved on the mesh while the rig is embedded in it (on the same trace
  // mesh, whose rays tell which bones a vertex sees).
  const bool bone_interior = opt.method == DeformMethod::DualQuaternion && opt.interior == InteriorWeights::BoneHeat;
  BoneHeat heat;
  std::optional<CutMesh> base;
  std::optional<TraceMesh> surface;
  std::vector<char> deforming;
  // Runs beside the embedding and the harmonic factor, and is waited for
  // where its weights are read (declared after what it reads, so that an
  // exception waits for it before those go).
  tbb::task_group heat_task;
  if (bone_interior) {
    base.emplace(CutMesh::from_surface(mesh));
    surface.emplace(mesh, *base);
    deforming = deforming_joints(mesh, rig, impl->joints, joint_index);
    heat_task.run([&] {
      const Eigen::SparseMatrix<double> Lb = cut_mesh_laplacian(
          *base, opt.laplacian == LaplacianChoice::Uniform ? LaplacianKind::Uniform : LaplacianKind::IntrinsicDelaunay);
      BoneHeatInput bi;
      bi.cut = &*base;
      bi.laplacian = &Lb;
      bi.surface = &*surface;
      bi.joints = &impl->joints;
      bi.rule = opt.weights;
      bi.deforming = deforming;
      heat = bone_heat(bi);
    });
    impl->embedding = embed_on(mesh, *surface, rig, opt.embed);
  } else {
    impl->embedding = embed(mesh, rig, opt.embed);
  }
  const EmbedReport& er = impl->embedding.report();
  if (!er.ok)
    throw EmbedError("bind: the rig does not embed on " + mesh.source + ": " +
                     (er.problems.empty() ? std::string("not ok") : er.problems[0]));
  lap("embed");
  const Embedding::Impl& emb = impl->embedding.impl();
  const CutMesh& cut = emb.cut;
  const int nc = cut.num_vertices();

  // Constraints: every CutChain vertex, with its profile's interpolated weights.
  const ChainConstraints constraints = chain_constraints(emb, rig, joint_index);
  const std::vector<char>& constrained = constraints.constrained;
  const std::vector<std::map<int, double>>& cw = constraints.cw;
  for (int v = 0; v < nc; ++v)
    rep.constrained += constrained[v];
  lap("constraints");

  LaplacianStats ls;
  const Eigen::SparseMatrix<double> L = cut_mesh_laplacian(
      cut, opt.laplacian == LaplacianChoice::Uniform ? LaplacianKind::Uniform : LaplacianKind::IntrinsicDelaunay, &ls);
  rep.negative_weights_before = ls.negative_before;
  rep.negative_weights_after = ls.negative_after;
  rep.flips = ls.flips;
  for (int c = 0; c < L.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, c); it; ++it)
      if (it.row() < c && it.value() > 0.5 * Tolerances::cot_weight_zero &&
          (!constrained[it.row()] || !constrained[c])) // L_ij = -w_ij
        ++rep.negative_weights_solved;
  lap("laplacian");

  // Free vertices; those in parts that touch no constraint follow one joint rigidly.
  std::vector<int> comp(nc, -1);
  std::vector<char> comp_constrained;
  for (int s0 = 0; s0 < nc; ++s0) {
    if (constrained[s0] || comp[s0] >= 0)
      continue;
    const int c = static_cast<int>(comp_constrained.size());
    comp_constrained.push_back(0);
    std::vector<int> stack{s0};
    comp[s0] = c;
    while (!stack.empty()) {
      const int v = stack.back();
      stack.pop_back();
      for (Eigen::SparseMatrix<double>::InnerIterator it(L, v); it; ++it) {
        const int u = static_cast<int>(it.row());
        if (u == v || it.value() == 0)
          continue;
        if (constrained[u])
          comp_constrained[c] = 1;
        else if (comp[u] < 0) {
          comp[u] = c;
          stack.push_back(u);
        }
      }
    }
  }
  std::vector<int> free_index(nc, -1), free_vertices;
  std::map<int, int> rigid_joint_of_comp;
  int named_rigid = -1;
  if (auto it = rig.extensions.find("x_rigid_joint"); it != rig.extensions.end()) {
    std::string name = it->second;
    if (name.size() >= 2 && name.front() == '"')
      name = name.substr(1, name.size() - 2);
    auto j = joint_index.find(name);
    if (j == joint_index.end())
      throw InputError("rig", "/x_rigid_joint", "names joint '" + name + "', which the skeleton lacks");
    named_rigid = j->second;
  }
  for (int v = 0; v < nc; ++v) {
    if (constrained[v])
      continue;
    if (comp_constrained[comp[v]]) {
      free_index[v] = static_cast<int>(free_vertices.size());
      free_vertices.push_back(v);
    } else if (!rigid_joint_of_comp.count(comp[v])) {
      int best = named_rigid;
      if (best < 0) {
        double bd = std::numeric_limits<double>::infinity();
        for (int j = 0; j < nj; ++j) {
          const double d = (impl->joints[j].bind.block<3, 1>(0, 3) - cut.position(Vertex(v))).norm();
          if (d < bd) {
            bd = d;
            best = j;
          }
        }
      }
      rigid_joint_of_comp[comp[v]] = best;
      rep.notes.push_back("a part of the mesh that no profile touches follows joint '" + impl->joints[best].name +
                          "' rigidly");
    }
  }
  const int nf = static_cast<int>(free_vertices.size());
  rep.free = nf;

  // H: the harmonic extension of constraint values, L_ff x_f = -L_fc x_c.
  std::vector<Eigen::Triplet<double>> ff;
  std::vector<std::vector<std::pair<int, double>>> fc(nf); // free row -> (constrained vertex, L entry)
  for (int k = 0; k < nf; ++k) {
    const int v = free_vertices[k];
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, v); it; ++it) {
      const int u = static_cast<int>(it.row());
      if (free_index[u] >= 0)
        ff.emplace_back(k, free_index[u], it.value());
      else if (constrained[u])
        fc[k].emplace_back(u, it.value());
    }
  }
  Eigen::SparseMatrix<double> Lff(nf, nf);
  Lff.setFromTriplets(ff.begin(), ff.end());
  // Shared, so that the gradient mode can solve with it per frame.
  auto solver_ptr = std::make_shared<Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>>();
  auto& solver = *solver_ptr;
  if (nf > 0) {
    solver.compute(Lff);
    if (solver.info() != Eigen::Success)
      throw EmbedError("bind: the harmonic system could not be factored (the Laplacian is singular on " + mesh.source +
                       ")");
  }
  lap("factor");

  heat_task.wait();
  if (heat.blind > 0)
    rep.notes.push_back(std::to_string(heat.blind) +
                        " vertices see no bone through the surface and take bone heat from the nearest bone");
  // Bone heat at the cut mesh's vertices (a curve's vertex inside an input
  // edge or face: interpolated there). The inside of each region is then
  // B_j + H(w_j - B_j), which is w_j on the curves.
  if (!heat.weight.empty()) {
    for (auto& w : heat.weight) {
      if (w.size() == 0)
        continue;
      Eigen::VectorXd at_cut(nc);
      for (int v = 0; v < nc; ++v) {
        double x = 0;
        for (const auto& [i, b] : cut.input_weights(Vertex(v)))
          x += b * w[i];
        at_cut[v] = x;
      }
      w = std::move(at_cut);
    }
    lap("bone heat");
  }
  auto has_heat = [&](int j) { return !heat.weight.empty() && heat.weight[j].size() > 0; };

  // Right-hand sides per joint: w_j and w_j p on the constraints (w_j - B_j with bone heat).
  std::vector<std::vector<std::pair<int, double>>> joint_constraints(nj); // joint -> (vertex, weight)
  for (int v = 0; v < nc; ++v)
    for (const auto& [j, w] : cw[v])
      joint_constraints[j].emplace_back(v, w);
  std::vector<Eigen::VectorXd> sj(nj), yj[3];
  for (auto& y : yj)
    y.resize(nj);
  // Only the harmonic mode reads Y_j = H(w_j p); the others need s_j alone.
  const bool positions = opt.method == DeformMethod::Harmonic;
  Eigen::MatrixXd rhs(nf, positions ? 4 : 1), sol;
  for (int j = 0; j < nj; ++j) {
    if (nf == 0 || (joint_constraints[j].empty() && !has_heat(j)))
      continue;
    rhs.setZero();
    std::vector<double> wv(nc, 0.0);
    for (const auto& [v, w] : joint_constraints[j])
      wv[v] = w;
    if (has_heat(j))
      for (int v = 0; v < nc; ++v)
        if (constrained[v])
          wv[v] -= heat.weight[j][v];
    for (int k = 0; k < nf; ++k)
      for (const auto& [u, l] : fc[k]) {
        if (wv[u] == 0)
          continue;
        const Eigen::Vector3d& p = cut.position(Vertex(u));
        rhs(k, 0) -= l * wv[u];
        if (positions) {
          rhs(k, 1) -= l * wv[u] * p.x();
          rhs(k, 2) -= l * wv[u] * p.y();
          rhs(k, 3) -= l * wv[u] * p.z();
        }
      }
    sol = solver.solve(rhs);
    if (solver.info() != Eigen::Success || !sol.allFinite())
      throw EmbedError("bind: the harmonic solve failed for joint '" + impl->joints[j].name + "'");
    sj[j] = sol.col(0);
    if (has_heat(j))
      for (int k = 0; k < nf; ++k)
        sj[j][k] += heat.weight[j][free_vertices[k]];
    if (positions)
      for (int c = 0; c < 3; ++c)
        yj[c][j] = sol.col(c + 1);
  }
  lap("solve");
  // Per input (welded) vertex: influences and detail.
  const int nv = mesh.num_vertices();
  impl->input_to_welded = mesh.input_to_welded;
  impl->offset.push_back(0);
  impl->delta.assign(nv, Eigen::Vector3d::Zero());
  for (int v = 0; v < nv; ++v) {
    const Eigen::Vector3d X = cut.position(Vertex(v));
    if (constrained[v]) {
      for (const auto& [j, w] : cw[v]) {
        impl->joint.push_back(j);
        impl->s.push_back(w);
        impl->Y.push_back(w * X);
      }
    } else if (free_index[v] < 0) {
      impl->joint.push_back(rigid_joint_of_comp.at(comp[v]));
      impl->s.push_back(1.0);
      impl->Y.push_back(X);
      ++rep.rigid;
    } else if (!heat.weight.empty()) {
      // B_j + H(w_j - B_j) sums to 1 but may dip below 0 where a joint's
      // heat meets a curve that does not name it: clamped, the small ones
      // dropped, renormalised.
      const int k = free_index[v];
      double sum = 0;
      for (int j = 0; j < nj; ++j)
        if (sj[j].size() > 0 && sj[j][k] >= kInteriorFloor)
          sum += sj[j][k];
      for (int j = 0; j < nj; ++j)
        if (sj[j].size() > 0 &&
            (sum > 0 ? sj[j][k] >= kInteriorFloor : heat.weight[j].size() > 0 && heat.weight[j][v] > 0)) {
          const double x = sum > 0 ? sj[j][k] / sum : heat.weight[j][v];
          impl->joint.push_back(j);
          impl->s.push_back(x);
          impl->Y.push_back(x * X);
        }
    } else {
      const int k = free_index[v];
      Eigen::Vector3d Hp = Eigen::Vector3d::Zero();
      for (int j = 0; j < nj; ++j) {
        if (sj[j].size() == 0 || sj[j][k] == 0)
          continue; // exactly zero: joint j bounds none of this vertex's region
        // Without the harmonic mode's positions, Y_j = s_j X, so that the detail is zero.
        const Eigen::Vector3d y =
            positions ? Eigen::Vector3d(yj[0][j][k], yj[1][j][k], yj[2][j][k]) : Eigen::Vector3d(sj[j][k] * X);
        impl->joint.push_back(j);
        impl->s.push_back(sj[j][k]);
        impl->Y.push_back(y);
        Hp += y;
      }
      impl->delta[v] = X - Hp;
    }
    impl->offset.push_back(static_cast<int>(impl->joint.size()));
  }
  rep.vertices = nv;
  rep.influences = static_cast<int>(impl->joint.size());
  rep.mean_influences = nv > 0 ? static_cast<double>(rep.influences) / nv : 0;
  // Horn mode needs the constraints themselves.
  impl->mode = opt.rigid;
  impl->horn_tolerance = opt.horn_tolerance;
  impl->c_offset.push_back(0);
  for (int v = 0; v < nc; ++v)
    if (constrained[v]) {
      impl->c_rest.push_back(cut.position(Vertex(v)));
      for (const auto& [j, w] : cw[v]) {
        impl->c_joint.push_back(j);
        impl->c_weight.push_back(w);
      }
      impl->c_offset.push_back(static_cast<int>(impl->c_joint.size()));
    }
  lap("tables");
  if (opt.method == DeformMethod::Gradient) {
    std::vector<int> rigid_joint(nc, -1);
    for (int v = 0; v < nc; ++v)
      if (!constrained[v] && free_index[v] < 0 && comp[v] >= 0)
        rigid_joint[v] = rigid_joint_of_comp.at(comp[v]);
    std::vector<std::vector<Vertex>> chain_vertices;
    for (const auto& c : emb.result.chains) {
      chain_vertices.push_back(c.vertices);
    }
    GradientInput gi;
    gi.cut = &cut;
    gi.face_region = &emb.regions.face_region;
    gi.chain_vertices = &chain_vertices;
    gi.profile_ids = &emb.input.profile_ids;
    gi.constrained = &constrained;
    gi.constraint_weights = &cw;
    gi.free_index = &free_index;
    gi.rigid_joint = &rigid_joint;
    gi.harmonic = &sj;
    gi.harmonic_solver = solver_ptr;
    gi.harmonic_fc = &fc;
    gi.free_vertices = &free_vertices;
    gi.side_scales = side_scales_of(rig);
    gi.cut_aware = opt.cut_aware;
    gi.curve_frames = opt.curve_frames;
    gi.sections = opt.sections;
    gi.joints = &impl->joints;
    gi.rotation =
        opt.rotation_blend == BindOptions::RotationBlend::Quaternion ? RotationBlend::Quaternion : RotationBlend::Polar;
    impl->gradient = build_gradient(gi);
    lap("gradient");
  }
  return Binding(impl);
}

void Binding::harmonic_weights(int input_vertex, std::vector<std::pair<int, double>>& out) const {
  const Impl& b = *impl_;
  out.clear();
  const int v = b.input_to_welded.at(static_cast<size_t>(input_vertex));
  for (int k = b.offset[v]; k < b.offset[v + 1]; ++k)
    if (b.s[k] > 0)
      out.emplace_back(b.joint[k], b.s[k]);
}

void Binding::deform_frames(std::span<const Mat4> M, std::span<Eigen::Vector3d> out) const {
  const size_t nj = impl_->joints.size(), nv = impl_->input_to_welded.size();
  const size_t frames = nj ? M.size() / nj : 0;
  if (nj == 0 || M.size() % nj != 0 || out.size() != frames * nv)
    throw Error("deform_frames: " + std::to_string(M.size()) + " matrices and " + std::to_string(out.size()) +
                " positions do not make whole frames of " + std::to_string(nj) + " joints and " + std::to_string(nv) +
                " vertices");
  tbb::parallel_for(size_t{0}, frames, [&](size_t f) { deform(M.subspan(f * nj, nj), out.subspan(f * nv, nv)); });
}

void Binding::deform(std::span<const Mat4> M, std::span<Eigen::Vector3d> out) const {
  const Impl& b = *impl_;
  if (M.size() != b.joints.size() || out.size() != b.input_to_welded.size())
    throw Error("deform: expected " + std::to_string(b.joints.size()) + " skinning matrices and room for " +
                std::to_string(b.input_to_welded.size()) + " positions, got " + std::to_string(M.size()) + " and " +
                std::to_string(out.size()));
  if (b.method == DeformMethod::DualQuaternion) {
    // Per welded vertex, its harmonic weights' blend of the joints' rigid
    // motions (after their stretches), as dual quaternions.
    thread_local std::vector<DualJoint> joints;
    thread_local std::vector<Eigen::Vector3d> welded;
    joints.resize(M.size());
    for (size_t j = 0; j < M.size(); ++j)
      joints[j] = split_joint(M[j]);
    welded.resize(b.rest.size());
    // Each vertex on its own, so the result does not depend on how the range
    // is split. Isolated: a waiting thread must not start another frame of
    // deform_frames, which would reuse its buffers.
    const std::vector<DualJoint>& dj = joints;
    std::vector<Eigen::Vector3d>& w = welded;
    tbb::this_task_arena::isolate([&] {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, b.rest.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        DualBlend blend;
        for (size_t v = r.begin(); v < r.end(); ++v) {
          blend.clear();
          for (int k = b.offset[v]; k < b.offset[v + 1]; ++k)
            blend.add(dj[b.joint[k]], b.s[k]);
          w[v] = blend.valid() ? blend.apply(b.rest[v]) : b.rest[v];
        }
      });
    });
    for (size_t i = 0; i < out.size(); ++i)
      out[i] = welded[b.input_to_welded[i]];
    return;
  }
  if (b.gradient) {
    thread_local std::vector<Eigen::Vector3d> cut_positions;
    cut_positions.resize(static_cast<size_t>(b.gradient->num_cut_vertices));
    deform_gradient(*b.gradient, M, cut_positions);
    for (size_t i = 0; i < out.size(); ++i)
      out[i] = cut_positions[b.input_to_welded[i]];
    return;
  }
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  if (b.mode == RigidMode::Horn && !b.c_rest.empty()) {
    // Fit one rotation to the whole net (Horn / Kabsch), rest -> posed.
    const size_t n = b.c_rest.size();
    Eigen::Vector3d pc = Eigen::Vector3d::Zero(), qc = Eigen::Vector3d::Zero();
    auto posed = [&](size_t c) {
      Eigen::Vector3d q = Eigen::Vector3d::Zero();
      for (int k = b.c_offset[c]; k < b.c_offset[c + 1]; ++k)
        q += b.c_weight[k] * (M[b.c_joint[k]].topLeftCorner<3, 3>() * b.c_rest[c] + M[b.c_joint[k]].block<3, 1>(0, 3));
      return q;
    };
    for (size_t c = 0; c < n; ++c) {
      pc += b.c_rest[c];
      qc += posed(c);
    }
    pc /= static_cast<double>(n);
    qc /= static_cast<double>(n);
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    double spread = 0;
    for (size_t c = 0; c < n; ++c) {
      const Eigen::Vector3d p = b.c_rest[c] - pc, q = posed(c) - qc;
      H += p * q.transpose();
      spread += p.squaredNorm();
    }
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
    D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
    R = svd.matrixV() * D * svd.matrixU().transpose();
    double residual = 0;
    for (size_t c = 0; c < n; ++c)
      residual += (R * (b.c_rest[c] - pc) - (posed(c) - qc)).squaredNorm();
    if (spread > 0 && std::sqrt(residual / spread) > b.horn_tolerance)
      R.setIdentity(); // a poor fit: the thesis switches the rigid part off
  }
  const size_t nin = b.input_to_welded.size();
  for (size_t i = 0; i < nin; ++i) {
    const int v = b.input_to_welded[i];
    const Eigen::Vector3d& d = b.delta[v];
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    if (b.mode == RigidMode::PerVertex) {
      for (int k = b.offset[v]; k < b.offset[v + 1]; ++k) {
        const Mat4& m = M[b.joint[k]];
        x.noalias() += m.topLeftCorner<3, 3>() * (b.Y[k] + b.s[k] * d) + b.s[k] * m.block<3, 1>(0, 3);
      }
    } else {
      for (int k = b.offset[v]; k < b.offset[v + 1]; ++k) {
        const Mat4& m = M[b.joint[k]];
        x.noalias() += m.topLeftCorner<3, 3>() * b.Y[k] + b.s[k] * m.block<3, 1>(0, 3);
      }
      x.noalias() += R * d;
    }
    out[i] = x;
  }
}

} // namespace curvenet
