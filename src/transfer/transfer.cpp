// Transfer (docs/transfer.md): map the rig through the frames, project it
// onto the target, embed it there, and check that regions of the same
// identity cover the same surface.

#include "curvenet/transfer.hpp"

#include "core/matrix_checks.hpp"
#include "core/polyline_distance.hpp"
#include "core/tolerances.hpp"

#include "core/polygon.hpp"
#include "curvenet/errors.hpp"
#include "embed/embedding_impl.hpp"
#include "trace/trace_mesh.hpp"
#include "transfer/cage_map.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <sstream>

namespace curvenet {

using namespace detail;

namespace {

Vec3 apply(const Mat4& m, const Vec3& p) {
  return (m * p.homogeneous()).head<3>();
}

std::string percent(double x) {
  std::ostringstream s;
  s.precision(3);
  s << 100 * x << "%";
  return s.str();
}

/// Which cut face of an embedding holds a point of its input mesh.
class RegionLocator {
public:
  /// `tm` is the trace mesh of the mesh `e` embeds in.
  RegionLocator(const TraceMesh& tm, const Embedding& e) : mesh_(tm.mesh()), emb_(e), tm_(tm) {
    const CutMesh& cm = e.impl().cut;
    pieces_.resize(mesh_.num_faces());
    for (int f = 0; f < cm.num_faces(); ++f)
      pieces_[cm.face_origin(Face(f))].push_back(f);
  }

  /// The region key at the surface point nearest to p ("" outside a local net).
  std::string key_at(const Vec3& p) const {
    const auto n = tm_.nearest(p);
    const int f = tm_.tri_face(n.tri);
    const CutMesh& cm = emb_.impl().cut;
    int face = pieces_[f].front();
    if (pieces_[f].size() > 1) {
      // Point in polygon, in the input face's plane.
      const auto c = mesh_.face(f);
      Vec3 normal = Vec3::Zero();
      for (size_t i = 0; i < c.size(); ++i)
        normal += mesh_.positions[c[i]].cross(mesh_.positions[c[(i + 1) % c.size()]]);
      const Vec3 u = normal.unitOrthogonal(), w = normal.normalized().cross(u);
      auto to2 = [&](const Vec3& q) { return Eigen::Vector2d(q.dot(u), q.dot(w)); };
      const Eigen::Vector2d q = to2(n.point);
      double best = -1;
      for (int piece : pieces_[f]) {
        // Winding via the signed angle sum is robust enough for a sample at a centroid.
        const auto loop = cm.face_loop(Face(piece));
        double angle = 0;
        for (Halfedge h : loop) {
          const Eigen::Vector2d a = to2(cm.position(cm.from(h))) - q, b = to2(cm.position(cm.to(h))) - q;
          angle += std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));
        }
        if (std::abs(angle) > best) {
          best = std::abs(angle);
          face = piece;
        }
      }
    }
    const int r = emb_.face_regions()[face];
    return r < 0 ? std::string() : emb_.report().region_list[r].key();
  }

private:
  const SurfaceMesh& mesh_;
  const Embedding& emb_;
  const TraceMesh& tm_;
  std::vector<std::vector<int>> pieces_;
};

/// Places points of the source surface on the target along the source's
/// surface normal. Closest points alone fold: where the target is a coarser
/// tessellation lying inside the source's curved parts, every point over a
/// convex edge or corner of the target lands on that edge or corner, and
/// profiles that met at right angles on the source meet at shallow angles,
/// or cross, on the target. The normal is smooth across the source, so the
/// projection keeps the curves' order and angles.
class Projector {
public:
  /// Rays reach no farther than `max_reach` (the distance beyond which a
  /// point counts as off the target).
  Projector(const TraceMesh& source, const TraceMesh& target, const Mat4& source_to_target, double max_reach)
      : stm_(source), normals_(source), ttm_(target), map_(source_to_target),
        normal_map_(source_to_target.topLeftCorner<3, 3>().inverse().transpose()), h_(target.mesh().mean_edge_length()),
        max_reach_(max_reach) {}

  /// The target point for a point in the source mesh's space, and its
  /// distance from where the frames put it.
  std::pair<Vec3, double> place(const Vec3& p) const {
    const auto on_source = stm_.nearest(p);
    const Vec3 q = apply(map_, p);
    const auto near = ttm_.nearest(q);
    const double d0 = near.distance(q);
    const Vec3 n = (normal_map_ * normals_.at(on_source.tri, on_source.bary)).normalized();
    // Both ways along the normal, since the target may lie inside or
    // outside; only through triangles that face the same way, so that a ray
    // never lands on the far side of a thin fin or finger. A ray much longer
    // than the closest distance grazes the surface: keep the closest point.
    const double reach = std::min(kRayReach * d0 + kRaySlack * h_, max_reach_);
    std::optional<Vec3> best;
    for (const double sign : {1.0, -1.0})
      if (const auto hit = ttm_.ray_hit(q, sign * n, reach, n))
        if (!best || hit->distance(q) < (*best - q).norm())
          best = hit->point;
    return best ? std::pair{*best, (*best - q).norm()} : std::pair{near.point, d0};
  }

private:
  static constexpr double kRayReach = 3;   ///< rays up to this many times the closest distance...
  static constexpr double kRaySlack = 0.5; ///< ...plus this many target mean edge lengths
  const TraceMesh& stm_;
  SmoothNormals normals_;
  const TraceMesh& ttm_;
  Mat4 map_;
  Eigen::Matrix3d normal_map_;
  double h_, max_reach_;
};

/// The placed polyline without the points where it doubles back. Where the
/// two surfaces are far apart (a control cage and its limit surface), the
/// projection can swing a few points back against the curve's direction;
/// the profile would then cross itself. A point is kept when the step to it
/// runs the same way as the step between the same points before placing
/// (`mapped`); the last point (the end node) is always kept, and takes back
/// the kept points it would double back over.
std::vector<Vec3> without_folds(const std::vector<Vec3>& placed, const std::vector<Vec3>& mapped) {
  std::vector<size_t> kept{0};
  auto forward = [&](size_t a, size_t b) { return (placed[b] - placed[a]).dot(mapped[b] - mapped[a]) > 0; };
  for (size_t i = 1; i < placed.size(); ++i) {
    if (i + 1 == placed.size()) {
      while (kept.size() > 1 && !forward(kept.back(), i))
        kept.pop_back();
      kept.push_back(i);
    } else if (forward(kept.back(), i)) {
      kept.push_back(i);
    }
  }
  std::vector<Vec3> out;
  for (size_t i : kept)
    out.push_back(placed[i]);
  return out;
}

/// The rig in the target's space, every node and profile placed on the
/// target surface (see Projector).
/// `source` and `target` are the surfaces placed from and onto: a cage's
/// limit surface where the mesh is a cage, and then the rig is carried up
/// from the source cage (`source_cage`) and down to the target cage.
Rig place_on_target(const Rig& rig, const TraceMesh& source, const TraceMesh& target, const TransferOptions& opt,
                    const CageMap* source_cage, const CageMap* target_cage, double& max_node_offset) {
  auto from_source = [&](const Vec3& p) {
    const Vec3 q = apply(rig.frame, p);
    return source_cage ? source_cage->to_limit(q) : q;
  };
  const Mat4 source_to_target = opt.target_frame.inverse() * opt.source_frame;
  const Mat4 to_target = source_to_target * rig.frame;
  const double diag = target.mesh().bbox_diagonal(), h = target.mesh().mean_edge_length();
  const Projector project(source, target, source_to_target, opt.max_offset * diag);
  Rig out = rig;
  out.frame = Mat4::Identity();
  out.extensions.erase("x_cage"); // set again below when the target is a cage
  for (auto& j : out.joints)
    j.bind = to_target * j.bind;
  std::map<std::string, Vec3> node_at;
  for (auto& n : out.nodes) {
    const auto [point, offset] = project.place(from_source(n.position));
    if (offset > opt.max_offset * diag)
      throw EmbedError("transfer: node '" + n.id + "' lies " + percent(offset / diag) +
                       " of the diagonal off the target " + target.mesh().source +
                       " (the frames do not line the meshes up, or the target is another shape)");
    max_node_offset = std::max(max_node_offset, 100 * offset / diag);
    n.position = point;
    node_at[n.id] = point;
  }
  for (auto& p : out.profiles) {
    const auto& pts = p.curve.points;
    // A Bezier or NURBS curve keeps its shape, mapped; the embedding places it.
    if (p.curve.kind != Curve::Kind::Polyline) {
      for (auto& q : p.curve.points)
        q = apply(to_target, q);
      continue;
    }
    std::vector<Vec3> placed, mapped;
    for (size_t i = 0; i < pts.size(); ++i) {
      mapped.push_back(apply(to_target, pts[i]));
      const auto [point, offset] = project.place(from_source(pts[i]));
      if (offset > opt.max_offset * diag)
        throw EmbedError("transfer: profile '" + p.id + "', point " + std::to_string(i) + " lies " +
                         percent(offset / diag) + " of the diagonal off the target: the profile leaves the surface");
      if (i > 0) {
        const double before = (mapped[i - 1] - mapped[i]).norm(), after = (placed.back() - point).norm();
        if (after > 3 * before + 2 * h)
          throw EmbedError("transfer: profile '" + p.id + "', point " + std::to_string(i) + ": the projection jumped " +
                           percent(after / diag) + " of the diagonal to another part of the surface (another finger?)");
      }
      placed.push_back(point);
    }
    placed.front() = node_at[p.from];
    placed.back() = node_at[p.to];
    // The source's own tessellation shows in its points (a starter ring has
    // one per source edge it crosses): keep only those the shape needs on
    // the target, within half the embedding's fidelity tolerance.
    const std::vector<Vec3> unfolded = without_folds(placed, mapped);
    p.curve.points.clear();
    for (size_t k : simplify_polyline(unfolded, detail::Tolerances::fidelity_rel * diag / 2))
      p.curve.points.push_back(unfolded[k]);
  }
  if (target_cage) {
    // The rig now lives on a cage: embedding it there (here, and when it is
    // bound later) treats the mesh as a cage (EmbedOptions::cage).
    out.extensions["x_cage"] = R"({"levels":)" + std::to_string(opt.target_cage_levels) + "}";
    for (auto& n : out.nodes)
      n.position = target_cage->to_cage(n.position);
    for (auto& p : out.profiles)
      if (p.curve.kind == Curve::Kind::Polyline)
        for (auto& q : p.curve.points)
          q = target_cage->to_cage(q);
  }
  return out;
}

} // namespace

TransferResult transfer(const Rig& rig, const SurfaceMesh& source, const SurfaceMesh& target,
                        const TransferOptions& opt) {
  TransferResult result;
  TransferReport& rep = result.report;
  if (!detail::invertible(opt.source_frame))
    throw InputError("source frame", "", "the matrix is singular or not finite");
  if (!detail::invertible(opt.target_frame))
    throw InputError("target frame", "", "the matrix is singular or not finite");
  const Mat4 source_to_target = opt.target_frame.inverse() * opt.source_frame;
  const Mat4 to_source = source_to_target.inverse();

  EmbedOptions source_embed = opt.embed, target_embed = opt.embed;
  source_embed.cage = opt.source_cage_levels > 0;
  target_embed.cage = opt.target_cage_levels > 0;
  const Embedding src = embed(source, rig, source_embed);
  rep.source = src.report();
  if (!rep.source.ok)
    throw EmbedError("transfer: the rig does not embed on the source " + source.source + ": " +
                     (rep.source.problems.empty() ? std::string("not ok") : rep.source.problems[0]));
  // Cages are placed from and onto through their limit surfaces.
  std::optional<CageMap> source_cage, target_cage;
  if (opt.source_cage_levels > 0)
    source_cage.emplace(source, opt.source_cage_levels, opt.max_faces);
  if (opt.target_cage_levels > 0)
    target_cage.emplace(target, opt.target_cage_levels, opt.max_faces);
  const SurfaceMesh& source_surface = source_cage ? source_cage->limit() : source;
  const SurfaceMesh& target_surface = target_cage ? target_cage->limit() : target;
  // The trace meshes: a cage map holds its own; a plain mesh gets one here.
  auto trace_of = [](const SurfaceMesh& m) { return std::make_unique<TraceMesh>(m, CutMesh::from_surface(m)); };
  const std::unique_ptr<TraceMesh> source_trace = source_cage ? nullptr : trace_of(source);
  const std::unique_ptr<TraceMesh> target_trace = target_cage ? nullptr : trace_of(target);
  const TraceMesh& source_placed = source_cage ? source_cage->limit_trace() : *source_trace;
  const TraceMesh& target_placed = target_cage ? target_cage->limit_trace() : *target_trace;
  const TraceMesh& source_located = source_cage ? source_cage->cage_trace() : *source_trace;
  SurfaceMesh mapped = source_surface;
  for (auto& p : mapped.positions)
    p = apply(source_to_target, p);
  rep.shape = surface_distance(mapped, target_surface, 1);
  const std::string apart = " (the surfaces lie up to " + percent(rep.shape.max / rep.shape.diagonal) +
                            " of the diagonal apart, " + percent(rep.shape.mean / rep.shape.diagonal) + " on average)";

  std::optional<Embedding> placed;
  try {
    result.rig = place_on_target(rig, source_placed, target_placed, opt, source_cage ? &*source_cage : nullptr,
                                 target_cage ? &*target_cage : nullptr, rep.max_node_offset);
    placed.emplace(embed(target, result.rig, target_embed));
  } catch (const EmbedError& e) {
    throw EmbedError(e.what() + apart);
  }
  const Embedding& tgt = *placed;
  rep.target = tgt.report();
  const EmbedReport &a = rep.source, &b = rep.target;
  if (!b.ok)
    for (const auto& pr : b.problems)
      rep.problems.push_back("target: " + pr + apart);
  if (a.logical_nodes != b.logical_nodes || a.profiles != b.profiles || a.components != b.components)
    rep.problems.push_back("the logical counts differ between source and target");
  if (a.regions != b.regions)
    rep.problems.push_back("the region counts differ: " + std::to_string(a.regions) + " on the source, " +
                           std::to_string(b.regions) + " on the target");

  // Region correspondence: the target's area, sampled at the centroid of
  // every triangle of its cut faces, against the source region found there.
  const RegionLocator locate(source_located, src);
  std::map<std::string, std::pair<double, double>> by_key; // key -> (area, agreeing area)
  const CutMesh& cm = tgt.impl().cut;
  double total = 0, agreeing = 0;
  for (int f = 0; f < cm.num_faces(); ++f) {
    const int r = tgt.face_regions()[f];
    if (r < 0)
      continue;
    const std::string key = b.region_list[r].key();
    std::vector<Vec3> corners;
    for (Halfedge hh : cm.face_loop(Face(f)))
      corners.push_back(cm.position(cm.from(hh)));
    for (const auto& t : triangulate_polygon(corners)) {
      const double area = 0.5 * (corners[t[1]] - corners[t[0]]).cross(corners[t[2]] - corners[t[0]]).norm();
      if (!(area > 0))
        continue;
      const Vec3 centroid = (corners[t[0]] + corners[t[1]] + corners[t[2]]) / 3;
      // Through the limit surfaces where either mesh is a cage.
      Vec3 at = apply(to_source, target_cage ? target_cage->to_limit(centroid) : centroid);
      if (source_cage)
        at = source_cage->to_cage(at);
      const bool same = locate.key_at(at) == key;
      by_key[key].first += area;
      by_key[key].second += same ? area : 0;
      total += area;
      agreeing += same ? area : 0;
    }
  }
  for (const auto& [key, v] : by_key)
    rep.regions.push_back({key, v.first, v.first > 0 ? v.second / v.first : 0});
  rep.agreement = total > 0 ? agreeing / total : 0;
  rep.ok = rep.problems.empty();
  return result;
}

std::string transfer_report_json(const TransferReport& r) {
  nlohmann::ordered_json j;
  j["ok"] = r.ok;
  j["agreement"] = r.agreement;
  j["max_node_offset_percent"] = r.max_node_offset;
  j["shape_distance"] = {{"mean_percent", r.shape.percent(r.shape.mean)},
                         {"max_percent", r.shape.percent(r.shape.max)}};
  auto counts = [](const EmbedReport& e) {
    return nlohmann::ordered_json{{"ok", e.ok},
                                  {"logical_nodes", e.logical_nodes},
                                  {"profiles", e.profiles},
                                  {"components", e.components},
                                  {"regions", e.regions},
                                  {"expected_regions", e.expected_regions ? nlohmann::ordered_json(*e.expected_regions)
                                                                          : nlohmann::ordered_json(nullptr)},
                                  {"unmapped_faces", e.unmapped_faces}};
  };
  j["source"] = counts(r.source);
  j["target"] = counts(r.target);
  nlohmann::ordered_json regions = nlohmann::ordered_json::array();
  for (const auto& g : r.regions)
    regions.push_back({{"key", g.key}, {"area", g.area}, {"agree", g.agree}});
  j["regions"] = regions;
  j["problems"] = r.problems;
  return j.dump(2) + "\n";
}

} // namespace curvenet
