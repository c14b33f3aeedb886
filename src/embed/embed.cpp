// The embedding pipeline: sample -> project and trace -> cut -> regions.

#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "embed/embedding_impl.hpp"
#include "embed/fidelity.hpp"
#include "sample/sampling.hpp"
#include "trace/tracer.hpp"

#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <exception>
#include <functional>
#include <iomanip>
#include <map>
#include <mutex>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>

namespace curvenet {

using namespace detail;

std::string RegionInfo::key() const {
  std::string k;
  for (const auto& [id, side] : boundary) {
    if (!k.empty())
      k += '|';
    k += id + ':' + side;
  }
  return k;
}

Embedding::Embedding(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}

double Embedding::Impl::chain_t(int p, size_t i) const {
  const auto& chain = result.chains[p];
  const auto& pts = input.traces[p].points;
  const int k = chain.point[i];
  if (k == 0)
    return 0.0;
  if (k + 1 == static_cast<int>(pts.size()))
    return 1.0;
  // Between the samples the walk went from and to.
  const int s = std::clamp(pts[k].sample, 1, static_cast<int>(samples[p].size()) - 1);
  const Vec3 a = samples[p][s - 1], b = samples[p][s], q = pts[k].at.pos;
  const double len2 = (b - a).squaredNorm();
  const double lambda = len2 > 0 ? std::clamp((q - a).dot(b - a) / len2, 0.0, 1.0) : 0.0;
  return sample_t[p][s - 1] + lambda * (sample_t[p][s] - sample_t[p][s - 1]);
}
const EmbedReport& Embedding::report() const {
  return impl_->report;
}
const std::vector<int>& Embedding::face_regions() const {
  return impl_->regions.face_region;
}

namespace {

class Stopwatch {
public:
  explicit Stopwatch(EmbedReport& r) : report_(r), start_(std::chrono::steady_clock::now()) {}
  void lap(const char* stage) {
    const auto now = std::chrono::steady_clock::now();
    report_.timings_ms.emplace_back(stage, std::chrono::duration<double, std::milli>(now - start_).count());
    start_ = now;
  }

private:
  EmbedReport& report_;
  std::chrono::steady_clock::time_point start_;
};

Vec3 apply(const Mat4& m, const Vec3& p) {
  return (m * p.homogeneous()).head<3>();
}

int net_components(const Rig& rig) {
  std::vector<int> parent(rig.nodes.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[x] != x)
      x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const auto& p : rig.profiles)
    parent[find(rig.node_index(p.from))] = find(rig.node_index(p.to));
  int c = 0;
  for (size_t i = 0; i < parent.size(); ++i)
    c += find(static_cast<int>(i)) == static_cast<int>(i);
  return c;
}

} // namespace

/// How far off, in words: a percentage of the diagonal, or, past what a
/// double holds (a point at 1e308), that it is further than 1e300 diagonals.
std::string how_far(double off, double diagonal) {
  std::ostringstream s;
  const double r = off / diagonal;
  if (r < 1e300)
    s << std::setprecision(3) << 100 * r << "% of the diagonal";
  else
    s << "more than 1e300 diagonals";
  return s.str();
}

/// The nodes placed on the surface and every profile sampled and traced
/// (the paths the cut follows), in `in` and `traced`.
struct Traced {
  std::vector<TraceInput> tin;
  std::vector<ProfileCurve> curves; ///< tin[p] points at curves[p]
};

void place_and_trace(const TraceMesh& tm, const Rig& rig, const EmbedOptions& options, const Tolerances& tol, bool cage,
                     Embedding::Impl& impl, Traced& traced, EmbedReport& rep,
                     const std::function<void(std::string_view, double)>& progress) {
  const double h = tm.mean_edge_length();
  std::vector<TraceInput>& tin = traced.tin;
  std::vector<ProfileCurve>& curves = traced.curves;
  // Nodes, in the mesh's object space.
  CutInput& in = impl.input;
  for (const auto& n : rig.nodes) {
    in.node_ids.push_back(n.id);
    in.node_points.push_back(place_node(tm, apply(rig.frame, n.position), tol));
  }
  // A rig for another mesh, or in other units, says by how much it is off.
  for (size_t i = 0; i < rig.nodes.size(); ++i) {
    const double off = (apply(rig.frame, rig.nodes[i].position) - in.node_points[i].pos).stableNorm();
    if (!(off <= Tolerances::max_node_offset_rel * tol.diagonal)) {
      std::ostringstream msg;
      msg << "embed: node '" << rig.nodes[i].id << "' lies " << how_far(off, tol.diagonal)
          << " off the surface (is the rig made for this mesh, in its units and space?)";
      throw EmbedError(msg.str());
    }
  }
  // A rig in other units can sit within the mesh and still be wrong: its
  // nodes huddle in a speck of it (or the mesh in a speck of the rig).
  if (!rig.profiles.empty()) {
    Eigen::AlignedBox3d box;
    for (const auto& n : rig.nodes)
      box.extend(apply(rig.frame, n.position));
    for (const auto& pr : rig.profiles)
      for (const auto& q : pr.curve.points)
        box.extend(apply(rig.frame, q));
    const double extent = box.diagonal().stableNorm(); // (norm() squares 1e-166 to nothing)
    if (extent > 0 && !(extent >= Tolerances::min_rig_extent_rel * tol.diagonal)) { // (no extent at all: see trace)
      std::ostringstream msg;
      msg << "embed: the rig spans " << std::setprecision(3) << extent / tol.diagonal
          << " of the mesh's diagonal (is the rig made for this mesh, in its units and space?)";
      throw EmbedError(msg.str());
    }
  }
  const int np = static_cast<int>(rig.profiles.size());
  if (!(options.density > 0 && options.density <= 1000))
    throw InputError("density", std::to_string(options.density), "must be a finite number in (0, 1000]");
  tin.resize(np);
  curves.resize(np);
  impl.sample_t.resize(np);
  impl.samples.resize(np);
  for (int p = 0; p < np; ++p) {
    const Profile& pr = rig.profiles[p];
    in.profile_ids.push_back(pr.id);
    in.profile_from.push_back(rig.node_index(pr.from));
    in.profile_to.push_back(rig.node_index(pr.to));
    Curve curve = pr.curve;
    for (auto& q : curve.points)
      q = apply(rig.frame, q);
    curves[p] = ProfileCurve(curve, in.node_points[in.profile_from[p]].pos, in.node_points[in.profile_to[p]].pos);
  }
  // Every point of a profile near the surface, as its nodes are: a point far
  // off it would be silently pulled back.
  std::vector<std::string> far_off(np); // the first fault of each profile, reported in profile order
  tbb::parallel_for(0, np, [&](int p) {
    const auto& points = rig.profiles[p].curve.points;
    for (size_t k = 0; k < points.size(); ++k) {
      const Vec3 q = apply(rig.frame, points[k]);
      const double off = q.allFinite() ? (q - tm.nearest(q).point).stableNorm() : HUGE_VAL;
      if (!(off <= Tolerances::max_node_offset_rel * tol.diagonal)) {
        std::ostringstream msg;
        msg << "embed: point " << k << " of profile '" << rig.profiles[p].id << "' lies " << how_far(off, tol.diagonal)
            << " off the surface (more than "
            << 100 * Tolerances::max_node_offset_rel << "%: is the rig made for this mesh?)";
        far_off[p] = msg.str();
        return;
      }
    }
  });
  for (const std::string& fault : far_off)
    if (!fault.empty())
      throw EmbedError(fault);
  {
    // The work up front: about length * density / mean edge samples.
    double estimate = 0;
    for (const ProfileCurve& c : curves)
      estimate += c.length() * options.density / h + static_cast<double>(c.size());
    if (estimate > static_cast<double>(options.max_samples))
      throw InputError("density", std::to_string(options.density),
                       "the profiles would take about " + std::to_string(static_cast<long long>(estimate)) +
                           " samples, more than the limit of " + std::to_string(options.max_samples) +
                           " (--max-samples)");
  }
  // The sample spacing follows the edge length of the surface near each sample.
  const double density = options.density;
  // (On a cage, whose faces are not the surface, the mean edge length.)
  auto spacing = [&](const Vec3& q) { return cage ? h / density : tm.edge_length(tm.nearest(q).tri) / density; };
  in.traces.resize(np);
  std::vector<std::exception_ptr> errors(np);
  std::atomic<int> done{0};
  // Profiles finish on any thread: one report at a time, never going back.
  std::mutex progress_mutex;
  double reported = -1;
  auto report = [&](double f) {
    std::lock_guard lock(progress_mutex);
    if (f > reported)
      progress("trace", reported = f);
  };
  report(0.0);
  // Sample and trace every profile (independent, so in parallel); report
  // the first failure in profile order.
  tbb::parallel_for(0, np, [&](int p) {
    try {
      const Profile& pr = rig.profiles[p];
      const int a = in.profile_from[p], b = in.profile_to[p];
      SampledProfile s = sample_profile(curves[p], spacing, !cage);
      impl.samples[p] = s.points;
      impl.sample_t[p] = s.t;
      tin[p] = {pr.id,
                &curves[p],
                std::move(s.points),
                std::move(s.t),
                in.node_points[a],
                in.node_points[b],
                a,
                b,
                tol.fidelity(),
                {},
                {},
                !cage};
      in.traces[p] = trace_profile(tm, tin[p], h, tol);
    } catch (...) {
      errors[p] = std::current_exception();
    }
    const int d = ++done;
    if (options.progress && d % 16 == 0)
      report(static_cast<double>(d) / np);
  });
  for (auto& e : errors)
    if (e)
      std::rethrow_exception(e);
  for (int p = 0; p < np; ++p) {
    const auto& pts = in.traces[p].points;
    if (in.profile_from[p] == in.profile_to[p] && pts.size() <= 2)
      throw EmbedError("trace: profile '" + in.profile_ids[p] + "' is a loop at node '" +
                       in.node_ids[in.profile_from[p]] + "' that has no length on the surface");
    rep.samples += static_cast<int>(tin[p].samples.size());
    rep.refinements += in.traces[p].refinements;
  }
  report(1.0);
}

namespace {
Embedding embed_with(const SurfaceMesh& mesh, const TraceMesh* given, const Rig& rig, const EmbedOptions& options,
                     std::optional<CutMesh> uncut);
} // namespace

Embedding embed(const SurfaceMesh& mesh, const Rig& rig, const EmbedOptions& options) {
  return embed_with(mesh, nullptr, rig, options, std::nullopt);
}

Embedding detail::embed_on(const SurfaceMesh& mesh, const TraceMesh& tm, const Rig& rig, const EmbedOptions& options,
                           std::optional<CutMesh> uncut) {
  return embed_with(mesh, &tm, rig, options, std::move(uncut));
}

namespace {

/// The embedding, on `given` (the trace mesh of `mesh`) or on one built
/// here; `uncut`, when given, is CutMesh::from_surface(mesh).
Embedding embed_with(const SurfaceMesh& mesh, const TraceMesh* given, const Rig& rig, const EmbedOptions& options,
                     std::optional<CutMesh> uncut) {
  auto impl = std::make_shared<Embedding::Impl>();
  EmbedReport& rep = impl->report;
  auto progress = [&](std::string_view stage, double f) {
    if (options.progress)
      options.progress(stage, f);
  };
  Stopwatch clock(rep);
  // The cut decides sides with exact predicates on products of three
  // coordinates: they must stay within double range.
  {
    double largest = 0;
    Eigen::AlignedBox3d box;
    for (const Vec3& p : mesh.positions) {
      largest = std::max(largest, p.cwiseAbs().maxCoeff());
      box.extend(p);
    }
    const double diagonal = mesh.positions.empty() ? 0 : box.diagonal().stableNorm(); // no underflow at 1e-200
    if (largest > Tolerances::max_coordinate || (diagonal > 0 && diagonal < 1 / Tolerances::max_coordinate)) {
      std::ostringstream msg;
      msg << "embed: " << mesh.source << " spans " << std::setprecision(3) << diagonal << " and reaches " << largest
          << ": an embedding takes coordinates and sizes within 1e-40 to 1e40 (scale "
          << "the mesh, and the rig's frame with it)";
      throw EmbedError(msg.str());
    }
  }
  const Tolerances tol = Tolerances::for_model(mesh.bbox_diagonal());
  // A rig that transfer placed on a control cage says so.
  const bool cage = options.cage || rig.extensions.count("x_cage") > 0;
  rep.input_vertices = mesh.num_vertices();
  rep.input_faces = mesh.num_faces();
  rep.logical_nodes = static_cast<int>(rig.nodes.size());
  rep.profiles = static_cast<int>(rig.profiles.size());
  rep.components = net_components(rig);
  rep.notes = mesh.notes;

  // Build the surface structures.
  impl->cut = uncut ? std::move(*uncut) : CutMesh::from_surface(mesh);
  std::vector<int> face_component;
  const auto comps = input_components(impl->cut, face_component);
  clock.lap("halfedges");
  rep.mesh_components = static_cast<int>(comps.size());
  bool all_closed = true, higher_genus = false;
  for (const auto& c : comps) {
    rep.closed_components += c.closed;
    all_closed = all_closed && c.closed;
    higher_genus = higher_genus || (c.closed && c.genus() != 0);
  }
  Coverage cov = options.coverage.value_or(rig.coverage);
  if (cov == Coverage::Auto)
    cov = all_closed ? Coverage::Full : Coverage::Local;
  rep.coverage = cov;
  const int V = rep.logical_nodes, E = rep.profiles, C = rep.components, K = rep.closed_components;
  if (!higher_genus)
    rep.expected_regions = cov == Coverage::Full ? C + K - V + E : E - V + C;

  std::optional<TraceMesh> built;
  if (!given)
    built.emplace(mesh, impl->cut);
  const TraceMesh& tm = given ? *given : *built;
  clock.lap("bvh");

  Traced traced;
  place_and_trace(tm, rig, options, tol, cage, *impl, traced, rep, progress);
  CutInput& in = impl->input;
  std::vector<TraceInput>& tin = traced.tin;
  const int np = static_cast<int>(rig.profiles.size());
  clock.lap("trace");

  // Cut. Where two chains meet, their curves may only be closer together
  // than the tracer followed them: trace the two more closely near there
  // and cut again, down to the floor.
  std::map<std::tuple<int, int, std::string>, double> last_gap; // per pair of profiles and place they met
  for (int round = 0;; ++round) {
    if (round > 0)
      impl->cut = CutMesh::from_surface(mesh);
    try {
      impl->result = cut_mesh(impl->cut, tm, in);
      break;
    } catch (const ProfilesMeet& meet) {
      const int p = meet.first, q = meet.second;
      const TraceMesh::Nearest near = tm.nearest(meet.at);
      double radius = 4 * tm.edge_length(near.tri);
      // Keep the ball off the nodes the two share: there they meet by design.
      for (int x : {in.profile_from[p], in.profile_to[p]})
        if (x == in.profile_from[q] || x == in.profile_to[q])
          radius = std::min(radius, (in.node_points[x].pos - meet.at).norm() / 2);
      const double gap = curve_gap(in.traces[p], in.traces[q], p == q, meet.at, radius);
      const std::string who = p == q ? "profile '" + in.profile_ids[p] + "' and itself"
                                     : "profiles '" + in.profile_ids[p] + "' and '" + in.profile_ids[q] + "'";
      auto retrace = [&](int x) {
        rep.refinements -= in.traces[x].refinements;
        in.traces[x] = trace_profile(tm, tin[x], tm.mean_edge_length(), tol);
        rep.refinements += in.traces[x].refinements;
      };
      const std::vector<int> both = p == q ? std::vector<int>{p} : std::vector<int>{p, q};
      ++rep.cut_rounds;
      // Run straight across the face where the chains meet, as the walks
      // between samples do: where the curves placed on this surface fold
      // (a curve off the surface, projected onto a thin or far-off part),
      // following their samples inside the face makes the chains cross.
      auto unfold = [&] {
        bool any = false;
        if (meet.face >= 0 && round < Tolerances::cut_rounds)
          for (int x : both) {
            auto& faces = tin[x].unfold_faces;
            if (std::binary_search(faces.begin(), faces.end(), meet.face))
              continue;
            faces.insert(std::upper_bound(faces.begin(), faces.end(), meet.face), meet.face);
            retrace(x);
            ++rep.unfolded_faces;
            any = true;
          }
        return any;
      };
      // A profile that meets itself inside a face folds there, most likely.
      if (p == q && unfold())
        continue;
      if (gap <= tol.floor()) {
        std::ostringstream msg;
        msg << "cut: " << who << " meet or come closer than " << std::setprecision(3) << tol.floor() << " ("
            << Tolerances::floor_rel << " of the diagonal) in or near " << meet.place << ", away from any node";
        throw EmbedError(msg.str());
      }
      // Tracing more closely helps only while it brings the curves apart:
      // not for two that truly cross, whose gap where they meet does not
      // shrink from one round to the next.
      const auto key = std::make_tuple(std::min(p, q), std::max(p, q), meet.place);
      const auto before = last_gap.find(key);
      const bool shrinking = before == last_gap.end() || gap < 0.5 * before->second;
      last_gap[key] = gap;
      if (round < Tolerances::cut_rounds && shrinking && gap / 4 < tol.fidelity()) {
        // The curves come closer than the chains may stray: trace both more
        // closely near here, so their chains stay apart.
        for (int x : both) {
          tin[x].tighter.push_back({meet.at, radius, std::max(tol.floor(), gap / 4)});
          retrace(x);
        }
        continue;
      }
      // The curves stay well apart, yet their chains cross inside a face.
      const bool unfolded = unfold();
      if (!unfolded) {
        std::ostringstream msg;
        msg << "cut: the chains of " << who << " cross in or near " << meet.place
            << ", away from any node; their curves come within " << std::setprecision(3) << gap << " ("
            << gap / tol.diagonal << " of the diagonal) of each other there: they cross, or the curves placed on "
            << "this surface fold";
        throw EmbedError(msg.str());
      }
    }
  }
  rep.crossings = impl->result.crossings;
  clock.lap("cut");
  if (auto fault = impl->cut.validate())
    throw TopologyError("cut mesh invalid after cutting: " + *fault);
  if (auto fault = validate_chains(impl->cut, in, impl->result))
    throw TopologyError("cut chains invalid: " + *fault);
  // Fidelity: every chain within the tolerance of its curve.
  rep.fidelity_tolerance = tol.fidelity();
  rep.diagonal = tol.diagonal;
  rep.fidelity_enforced = !cage;
  for (int p = 0; p < np; ++p) {
    const ChainFidelity f = chain_fidelity(impl->cut, impl->result.chains[p], in.traces[p]);
    rep.fidelity.emplace_back(in.profile_ids[p], f.distance);
    rep.fidelity_max = std::max(rep.fidelity_max, f.distance);
    if (f.distance > tol.fidelity() && !cage) {
      std::ostringstream msg;
      msg << "cut: profile '" << in.profile_ids[p] << "' strays " << std::setprecision(3) << f.distance << " ("
          << f.distance / tol.diagonal << " of the diagonal) from its curve near sample " << f.sample << " at ("
          << f.at.x() << ", " << f.at.y() << ", " << f.at.z() << "), over the tolerance of " << Tolerances::fidelity_rel
          << " of the diagonal";
      // A rig drawn on another tessellation of the shape: its nodes lie off
      // this one, and its curves with them.
      double off = 0;
      for (size_t i = 0; i < rig.nodes.size(); ++i)
        off = std::max(off, (apply(rig.frame, rig.nodes[i].position) - in.node_points[i].pos).stableNorm());
      if (off > tol.fidelity())
        msg << "; the rig's nodes lie up to " << 100 * off / tol.diagonal
            << "% of the diagonal off this surface: a rig made on another tessellation goes onto this one with "
               "`curvenet transfer`";
      throw EmbedError(msg.str());
    }
  }
  clock.lap("validate");

  impl->regions = find_regions(impl->cut, in.profile_ids, cov, face_component);
  clock.lap("regions");

  rep.regions = static_cast<int>(impl->regions.regions.size());
  rep.region_list = impl->regions.regions;
  rep.cut_vertices = impl->cut.num_vertices();
  rep.cut_faces = impl->cut.num_faces();
  rep.outside_faces = impl->regions.outside_faces;
  for (int r : impl->regions.face_region)
    rep.mapped_faces += r >= 0;
  rep.unmapped_faces = rep.cut_faces - rep.mapped_faces - rep.outside_faces;
  std::vector<int> nv;
  for (Vertex v : impl->result.node_vertex)
    if (v.is_valid())
      nv.push_back(v.idx);
  std::sort(nv.begin(), nv.end());
  rep.physical_nodes = static_cast<int>(std::unique(nv.begin(), nv.end()) - nv.begin());
  for (int i = 0; i < V; ++i)
    if (!impl->result.node_vertex[i].is_valid())
      rep.notes.push_back("node '" + rig.nodes[i].id + "' has no profile and is not cut into the mesh");
  if (cov == Coverage::Full && !all_closed) {
    std::set<int> boundary; // input edges on the boundary
    for (int hh = 0; hh < impl->cut.num_halfedges(); ++hh)
      if (impl->cut.is_boundary(Halfedge(hh)))
        boundary.insert(impl->cut.edge_origin(Halfedge(hh)));
    rep.problems.push_back("the mesh is open (" + std::to_string(boundary.size()) +
                           " boundary edges): a full-coverage net needs a closed surface; use coverage local or auto");
  }
  if (rep.expected_regions && rep.regions != *rep.expected_regions)
    rep.problems.push_back("found " + std::to_string(rep.regions) + " regions, expected " +
                           std::to_string(*rep.expected_regions));
  if (rep.unmapped_faces != 0)
    rep.problems.push_back(std::to_string(rep.unmapped_faces) + " faces belong to no region");
  if (higher_genus)
    rep.notes.push_back("a closed component has genus > 0: the expected region count is not determined");
  rep.ok = rep.problems.empty();
  return Embedding(impl);
}

} // namespace

std::string report_to_json(const EmbedReport& r) {
  nlohmann::ordered_json j;
  j["ok"] = r.ok;
  j["coverage"] = to_string(r.coverage);
  j["logical_nodes"] = r.logical_nodes;
  j["profiles"] = r.profiles;
  j["components"] = r.components;
  j["mesh_components"] = r.mesh_components;
  j["closed_components"] = r.closed_components;
  j["regions"] = r.regions;
  j["expected_regions"] =
      r.expected_regions ? nlohmann::ordered_json(*r.expected_regions) : nlohmann::ordered_json(nullptr);
  j["mapped_faces"] = r.mapped_faces;
  j["unmapped_faces"] = r.unmapped_faces;
  j["outside_faces"] = r.outside_faces;
  j["physical_nodes"] = r.physical_nodes;
  j["input"] = {{"vertices", r.input_vertices}, {"faces", r.input_faces}};
  j["cut_mesh"] = {{"vertices", r.cut_vertices}, {"faces", r.cut_faces}};
  j["samples"] = r.samples;
  j["crossings"] = r.crossings;
  j["refinements"] = r.refinements;
  j["cut_rounds"] = r.cut_rounds;
  j["unfolded_faces"] = r.unfolded_faces;
  {
    nlohmann::ordered_json per = nlohmann::ordered_json::object();
    for (const auto& [id, d] : r.fidelity)
      per[id] = d;
    j["fidelity"] = {{"tolerance", r.fidelity_tolerance},
                     {"diagonal", r.diagonal},
                     {"max", r.fidelity_max},
                     {"max_relative", r.fidelity_tolerance > 0 ? r.fidelity_max / r.fidelity_tolerance : 0.0},
                     {"enforced", r.fidelity_enforced},
                     {"profiles", per}};
  }
  nlohmann::ordered_json t = nlohmann::ordered_json::object();
  for (const auto& [stage, ms] : r.timings_ms)
    t[stage] = ms;
  j["timings_ms"] = t;
  j["problems"] = r.problems;
  j["notes"] = r.notes;
  nlohmann::ordered_json regions = nlohmann::ordered_json::array();
  for (const auto& reg : r.region_list) {
    nlohmann::ordered_json b = nlohmann::ordered_json::array();
    for (const auto& [id, side] : reg.boundary)
      b.push_back({id, std::string(1, side)});
    regions.push_back(
        {{"key", reg.key()}, {"boundary", b}, {"faces", reg.faces}, {"area", reg.area}, {"colour", reg.colour}});
  }
  j["region_list"] = regions;
  return j.dump(2) + "\n";
}

std::string Embedding::cut_mesh_obj() const {
  const CutMesh& m = impl_->cut;
  std::vector<Vec3> rest(static_cast<size_t>(m.num_vertices()));
  for (int v = 0; v < m.num_vertices(); ++v)
    rest[v] = m.position(Vertex(v));
  return cut_mesh_obj(rest);
}

std::string Embedding::cut_mesh_obj(std::span<const Vec3> positions) const {
  const CutMesh& m = impl_->cut;
  if (positions.size() != static_cast<size_t>(m.num_vertices()))
    throw Error("cut mesh: " + std::to_string(positions.size()) + " positions for " + std::to_string(m.num_vertices()) +
                " vertices");
  for (size_t v = 0; v < positions.size(); ++v)
    if (!positions[v].allFinite())
      throw Error("cut mesh: vertex " + std::to_string(v) + " is not finite; nothing was written");
  std::ostringstream out;
  out << std::setprecision(17);
  out << "# curvenet cut mesh: " << m.num_vertices() << " vertices, " << m.num_faces() << " faces\n";
  for (const Vec3& p : positions)
    out << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  out << "g faces\n";
  for (int f = 0; f < m.num_faces(); ++f) {
    out << 'f';
    for (Halfedge h : m.face_loop(Face(f)))
      out << ' ' << m.from(h).idx + 1;
    out << '\n';
  }
  const auto& chains = impl_->result.chains;
  for (size_t p = 0; p < chains.size(); ++p) {
    out << "g chain_" << impl_->input.profile_ids[p] << "\nl";
    for (Vertex v : chains[p].vertices)
      out << ' ' << v.idx + 1;
    out << '\n';
  }
  return out.str();
}

std::vector<std::vector<Vec3>> trace_profiles(const SurfaceMesh& mesh, const Rig& rig, const EmbedOptions& options) {
  Embedding::Impl impl;
  const Tolerances tol = Tolerances::for_model(mesh.bbox_diagonal());
  const bool cage = options.cage || rig.extensions.count("x_cage") > 0;
  impl.cut = CutMesh::from_surface(mesh);
  const TraceMesh tm(mesh, impl.cut);
  Traced traced;
  place_and_trace(tm, rig, options, tol, cage, impl, traced, impl.report, [&](std::string_view s, double f) {
    if (options.progress)
      options.progress(s, f);
  });
  std::vector<std::vector<Vec3>> paths;
  paths.reserve(impl.input.traces.size());
  for (const auto& t : impl.input.traces) {
    std::vector<Vec3>& path = paths.emplace_back();
    path.reserve(t.points.size());
    for (const PathPoint& q : t.points)
      path.push_back(q.at.pos);
  }
  return paths;
}

RawMesh Embedding::cut_mesh() const {
  const CutMesh& m = impl_->cut;
  RawMesh out;
  out.positions.reserve(m.num_vertices());
  for (int v = 0; v < m.num_vertices(); ++v)
    out.positions.push_back(m.position(Vertex(v)));
  std::vector<int> corners;
  for (int f = 0; f < m.num_faces(); ++f) {
    corners.clear();
    for (Halfedge h : m.face_loop(Face(f)))
      corners.push_back(m.from(h).idx);
    out.add_face(corners);
  }
  return out;
}

SurfaceMesh Embedding::cut_surface() const {
  return make_surface_mesh(cut_mesh(), "the cut mesh");
}

std::vector<std::pair<std::string, std::vector<Vec3>>> Embedding::chains() const {
  const CutMesh& m = impl_->cut;
  const auto& chains = impl_->result.chains;
  std::vector<std::pair<std::string, std::vector<Vec3>>> out(chains.size());
  for (size_t p = 0; p < chains.size(); ++p) {
    out[p].first = impl_->input.profile_ids[p];
    for (Vertex v : chains[p].vertices)
      out[p].second.push_back(m.position(v));
  }
  return out;
}

std::array<int, 3> Embedding::face_colour(int f) const {
  const int r = impl_->regions.face_region.at(static_cast<size_t>(f));
  return r >= 0 ? palette_colour(impl_->regions.regions[r].colour) : std::array<int, 3>{128, 128, 128};
}

std::string Embedding::regions_ply() const {
  const CutMesh& m = impl_->cut;
  const auto& fr = impl_->regions.face_region;
  std::ostringstream out;
  out << std::setprecision(9);
  out << "ply\nformat ascii 1.0\ncomment curvenet region preview: one colour per region, adjacent regions differ\n";
  out << "element vertex " << m.num_vertices() << "\nproperty float x\nproperty float y\nproperty float z\n";
  out << "element face " << m.num_faces() << "\nproperty list int int vertex_indices\n";
  out << "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty int region\nend_header\n";
  for (int v = 0; v < m.num_vertices(); ++v) {
    const Vec3& p = m.position(Vertex(v));
    out << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  }
  for (int f = 0; f < m.num_faces(); ++f) {
    const auto loop = m.face_loop(Face(f));
    out << loop.size();
    for (Halfedge h : loop)
      out << ' ' << m.from(h).idx;
    const std::array<int, 3> c = face_colour(f);
    out << ' ' << c[0] << ' ' << c[1] << ' ' << c[2] << ' ' << fr[f] << '\n';
  }
  return out.str();
}

} // namespace curvenet
