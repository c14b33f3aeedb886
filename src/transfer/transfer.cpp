// Transfer (docs/transfer.md): map the rig through the frames, project it
// onto the target, embed it there, and check that regions of the same
// identity cover the same surface.

#include "curvenet/transfer.hpp"

#include "core/matrix_checks.hpp"
#include "core/polyline_distance.hpp"
#include "core/tolerances.hpp"

#include "compare/surface_distance.hpp"
#include "core/plane_section.hpp"
#include "core/polygon.hpp"
#include "core/quoted.hpp"
#include "curvenet/errors.hpp"
#include "embed/embedding_impl.hpp"
#include "skeleton/skeleton_fit.hpp"
#include "trace/trace_mesh.hpp"
#include "transfer/cage_map.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <utility>

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

/// Rays that look for the surface along a normal reach no farther than
/// kRayReach times the distance to the closest point, plus kRaySlack mean
/// edge lengths of the mesh they look for: farther, they graze it.
constexpr double kRayReach = 3;
constexpr double kRaySlack = 0.5;

/// The nearest point of `tm` on the line through p along the unit vector n,
/// either way and within `reach`, on a triangle facing along n.
std::optional<TraceMesh::Nearest> hit_along(const TraceMesh& tm, const Vec3& p, const Vec3& n, double reach) {
  std::optional<TraceMesh::Nearest> best;
  for (const double sign : {1.0, -1.0})
    if (const auto hit = tm.ray_hit(p, sign * n, reach, n))
      if (!best || hit->distance(p) < best->distance(p))
        best = hit;
  return best;
}

/// Which region of an embedding holds a point of its input mesh.
class RegionLocator {
public:
  /// `tm` is the trace mesh of the mesh `e` embeds in.
  RegionLocator(const TraceMesh& tm, const Embedding& e) : mesh_(tm.mesh()), emb_(e), tm_(tm) {
    // The cut faces of each input face, as one run per input face.
    const CutMesh& cm = e.impl().cut;
    first_.assign(mesh_.num_faces() + 1, 0);
    for (int f = 0; f < cm.num_faces(); ++f)
      ++first_[cm.face_origin(Face(f)) + 1];
    for (int f = 0; f < mesh_.num_faces(); ++f)
      first_[f + 1] += first_[f];
    pieces_.resize(cm.num_faces());
    std::vector<int> fill(first_.begin(), first_.end() - 1);
    for (int f = 0; f < cm.num_faces(); ++f)
      pieces_[fill[cm.face_origin(Face(f))]++] = f;
  }

  /// The region (an index into the embedding's region list) at the surface
  /// point nearest to p; -1 outside a local net. With `facing` (the normal
  /// of the surface p lies on), a nearest point on a triangle that faces the
  /// other way is on the far side of a thin part (a flat ear or foot, nearer
  /// to p's other side than its own where the two surfaces differ): the
  /// nearest point along the normal, either way, on a triangle facing the
  /// same way is taken instead, where there is one. `facing` is a unit
  /// vector.
  int region_at(const Vec3& p, const Vec3* facing = nullptr) const {
    auto n = tm_.nearest(p);
    if (facing) {
      const auto& c = tm_.tri(n.tri);
      const Vec3 normal = (tm_.position(c[1]) - tm_.position(c[0])).cross(tm_.position(c[2]) - tm_.position(c[0]));
      if (normal.dot(*facing) < 0) {
        if (const auto hit = hit_along(tm_, p, *facing, kRayReach * n.distance(p) + kRaySlack * tm_.mean_edge_length()))
          n = *hit;
      }
    }
    const int f = tm_.tri_face(n.tri);
    const CutMesh& cm = emb_.impl().cut;
    const int* begin = pieces_.data() + first_[f];
    const int* end = pieces_.data() + first_[f + 1];
    int face = *begin;
    if (end - begin > 1) {
      // Point in polygon, in the input face's plane.
      const auto c = mesh_.face(f);
      Vec3 normal = Vec3::Zero();
      for (size_t i = 0; i < c.size(); ++i)
        normal += mesh_.positions[c[i]].cross(mesh_.positions[c[(i + 1) % c.size()]]);
      const Vec3 u = normal.unitOrthogonal(), w = normal.normalized().cross(u);
      auto to2 = [&](const Vec3& q) { return Eigen::Vector2d(q.dot(u), q.dot(w)); };
      const Eigen::Vector2d q = to2(n.point);
      double best = -1;
      for (const int* piece = begin; piece != end; ++piece) {
        // Winding via the signed angle sum is robust enough for a sample at a centroid.
        double angle = 0;
        const Halfedge h0 = cm.halfedge(Face(*piece));
        for (Halfedge h = h0;;) {
          const Eigen::Vector2d a = to2(cm.position(cm.from(h))) - q, b = to2(cm.position(cm.to(h))) - q;
          angle += std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));
          if ((h = cm.next(h)) == h0)
            break;
        }
        if (std::abs(angle) > best) {
          best = std::abs(angle);
          face = *piece;
        }
      }
    }
    return emb_.face_regions()[face];
  }

private:
  const SurfaceMesh& mesh_;
  const Embedding& emb_;
  const TraceMesh& tm_;
  std::vector<int> first_;  ///< pieces_[first_[f], first_[f + 1]) are input face f's cut faces
  std::vector<int> pieces_; ///< cut faces, grouped by input face
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
        normal_map_(source_to_target.topLeftCorner<3, 3>().inverse().transpose()), h_(target.mean_edge_length()),
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
    const auto hit = hit_along(ttm_, q, n, reach);
    return hit ? std::pair{hit->point, hit->distance(q)} : std::pair{near.point, d0};
  }

private:
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
constexpr int kReplacements = 32;   ///< re-placements of the profiles a target's embedding names
constexpr int kRegionSamples = 500; ///< faces inside a region the agreement is measured on, at most
constexpr double kMinAngle =
    10 * 3.14159265358979323846 / 180; ///< pairs of curves closer than this on the source are not compared
constexpr double kKeptAngle = 0.5;     ///< a node whose curves keep less of their angle than this is placed again

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

/// The placed polyline without the loops where it comes back within `eps`
/// of itself (a source curve that doubles back, folded flat on a coarse
/// target): the points between the two segments that meet are left out.
std::vector<Vec3> without_loops(std::vector<Vec3> pts, double eps) {
  for (size_t i = 0; i + 3 < pts.size(); ++i) {
    size_t last = 0;
    for (size_t j = i + 2; j + 1 < pts.size(); ++j)
      if (segment_distance(pts[i], pts[i + 1], pts[j], pts[j + 1]) < eps)
        last = j;
    if (last > 0)
      pts.erase(pts.begin() + static_cast<std::ptrdiff_t>(i + 1), pts.begin() + static_cast<std::ptrdiff_t>(last + 1));
  }
  return pts;
}

/// How a placed profile leaves its end node: towards its first point at
/// least `reach` from the node (or its far end).
Vec3 leaving(const std::vector<Vec3>& pts, bool from_start, double reach) {
  const Vec3& o = from_start ? pts.front() : pts.back();
  for (size_t i = 1; i < pts.size(); ++i) {
    const Vec3& q = from_start ? pts[i] : pts[pts.size() - 1 - i];
    if ((q - o).norm() >= reach || i + 1 == pts.size())
      return (q - o).norm() > 0 ? Vec3((q - o).normalized()) : Vec3(Vec3::Zero());
  }
  return Vec3::Zero();
}

/// Places a rig's nodes and polyline profiles on the target (see
/// Projector), the profiles sampled as finely as the target's edges.
class RigPlacer {
public:
  RigPlacer(const Rig& rig, const TraceMesh& source, const TraceMesh& target, const TransferOptions& opt,
            const CageMap* source_cage)
      : rig_(rig), target_(target), source_cage_(source_cage),
        source_to_target_(opt.target_frame.inverse() * opt.source_frame), to_target_(source_to_target_ * rig.frame),
        scale_(std::cbrt(std::abs(to_target_.topLeftCorner<3, 3>().determinant()))),
        diag_(target.mesh().bbox_diagonal()), h_(target.mean_edge_length()), max_off_(opt.max_offset * diag_),
        project_(source, target, opt.target_frame.inverse() * opt.source_frame, max_off_) {}

  /// A rig point in the source surface's space.
  [[nodiscard]] Vec3 from_source(const Vec3& p) const { return on_source(apply(rig_.frame, p)); }
  /// A point of the source mesh (a cage's: then carried to its limit) on the surface placed from.
  [[nodiscard]] Vec3 on_source(const Vec3& q) const { return source_cage_ ? source_cage_->to_limit(q) : q; }
  [[nodiscard]] Vec3 mapped(const Vec3& p) const { return apply(to_target_, p); }
  /// A point of the source mesh, mapped into the target's space.
  [[nodiscard]] Vec3 mapped_from_mesh(const Vec3& q) const { return apply(source_to_target_, q); }
  /// The length of the target's edges near a mapped point.
  [[nodiscard]] double edge_near(const Vec3& q) const {
    const double e = target_.edge_length(target_.nearest(q).tri);
    return e > 0 ? e : h_;
  }

  /// A node along the source normal, or (`closest`) at the target's closest point.
  [[nodiscard]] Vec3 place_node(const Node& n, bool closest, double& offset) const {
    if (closest) {
      const Vec3 q = mapped(n.position);
      const auto near = target_.nearest(q);
      offset = near.distance(q);
      return near.point;
    }
    const auto [point, off] = project_.place(from_source(n.position));
    offset = off;
    return point;
  }

  /// A profile as the source's embedding traced it (`pts`, on the source
  /// mesh), sampled at half the target's local edge length, each sample
  /// placed; its ends on the given node positions. `mapped_out` gets the
  /// same samples mapped, not placed.
  /// Where the placed samples jump to another part of the surface, that is
  /// refused, or, given `jump`, said there (a plane section replaces the
  /// curve then).
  [[nodiscard]] std::vector<Vec3> place_profile(const Profile& p, const std::vector<Vec3>& pts, const Vec3& from,
                                                const Vec3& to, bool closest, std::vector<Vec3>& mapped_out,
                                                std::string* jump = nullptr) const {
    std::vector<Vec3> samples;
    for (size_t i = 0; i + 1 < pts.size(); ++i) {
      const Vec3 a = mapped_from_mesh(pts[i]), b = mapped_from_mesh(pts[i + 1]);
      const double step = 0.5 * edge_near((a + b) / 2);
      const int n = std::clamp(static_cast<int>(std::ceil((b - a).norm() / step)), 1, kMaxSamplesPerSegment);
      for (int k = 0; k < n; ++k)
        samples.push_back(pts[i] + (pts[i + 1] - pts[i]) * (static_cast<double>(k) / n));
    }
    samples.push_back(pts.back());
    const double tol = detail::Tolerances::fidelity_rel * diag_ / 2;
    const auto off_target = [&](const Vec3& q) { return target_.nearest(q).distance(q); };
    auto place_one = [&](const Vec3& sample, bool refinement = false) {
      const auto [point, offset] = closest ? nearest_on_target(sample) : project_.place(on_source(sample));
      if (offset > max_off_ && refinement) // a chord's middle deep inside: the chord as it was
        return std::optional<Vec3>();
      if (offset > max_off_)
        throw EmbedError("transfer: profile '" + p.id + "' leaves the surface: a point of it lies " +
                         percent(offset / diag_) + " of the diagonal off the target");
      return std::optional<Vec3>(point);
    };
    // Each sample placed; where the chord between two placed samples cuts
    // across the target (over a ridge), the sample half-way between them
    // is placed too, until every chord lies within the tolerance.
    std::vector<Vec3> placed, rig_at;
    mapped_out.clear();
    for (size_t i = 0; i < samples.size(); ++i) {
      Vec3 point = *place_one(samples[i]);
      if (i == 0)
        point = from;
      else if (i + 1 == samples.size())
        point = to;
      if (i > 0) {
        const double before = (mapped_out.back() - mapped_from_mesh(samples[i])).norm(),
                     after = (placed.back() - point).norm();
        if (after > 3 * before + 2 * h_) {
          std::string what = "transfer: profile '" + p.id +
                             "': " + (closest ? "the target's closest points jump " : "the projection jumped ") +
                             percent(after / diag_) +
                             " of the diagonal to another part of the surface (the target is thinner, thicker or "
                             "shaped otherwise here)";
          if (!jump)
            throw EmbedError(what);
          if (jump->empty())
            *jump = std::move(what);
        }
        // (rig point, placed point) pairs between the last one kept and this one.
        std::vector<std::pair<Vec3, Vec3>> stack{{samples[i], point}};
        std::pair<Vec3, Vec3> last{rig_at.back(), placed.back()};
        for (int guard = 0; !stack.empty() && guard < kMaxRefinements; ++guard) {
          const auto next = stack.back();
          if (off_target((last.second + next.second) / 2) > tol) {
            const Vec3 mid = (last.first + next.first) / 2;
            if (const auto q = place_one(mid, true)) {
              stack.emplace_back(mid, *q);
              continue;
            }
          }
          stack.pop_back();
          if (!stack.empty() || next.first != samples[i]) {
            rig_at.push_back(next.first);
            placed.push_back(next.second);
            mapped_out.push_back(mapped_from_mesh(next.first));
          }
          last = next;
        }
        for (auto it = stack.rbegin(); it != stack.rend(); ++it) { // refinements run out: keep what is left
          if (it->first == samples[i])
            continue;
          rig_at.push_back(it->first);
          placed.push_back(it->second);
          mapped_out.push_back(mapped_from_mesh(it->first));
        }
      }
      rig_at.push_back(samples[i]);
      placed.push_back(point);
      mapped_out.push_back(mapped_from_mesh(samples[i]));
    }
    // Only the points the shape needs on the target, within half the
    // embedding's fidelity tolerance of the placed samples and of the
    // target's surface: a chord does not cut across a coarse target's ridge.
    const std::vector<Vec3> unfolded = without_loops(without_folds(placed, mapped_out), tol);
    std::vector<Vec3> out;
    for (size_t k : simplify_polyline(unfolded, tol, off_target))
      out.push_back(unfolded[k]);
    return out;
  }

  [[nodiscard]] double scale() const { return scale_; }

  /// A point already in the target's space at the target's closest point.
  [[nodiscard]] Vec3 closest_on_target(const Vec3& m) const { return target_.nearest(m).point; }
  /// A point of the source mesh at the target's closest point.
  [[nodiscard]] std::pair<Vec3, double> nearest_on_target(const Vec3& q) const {
    const Vec3 m = mapped_from_mesh(on_source(q));
    const auto near = target_.nearest(m);
    return {near.point, near.distance(m)};
  }

private:
  static constexpr int kMaxSamplesPerSegment = 4096;
  static constexpr int kMaxRefinements = 64; ///< halvings between two samples
  const Rig& rig_;
  const TraceMesh& target_;
  const CageMap* source_cage_;
  Mat4 source_to_target_, to_target_;
  double scale_, diag_, h_, max_off_;
  Projector project_;
};

/// The rig in the target's space, every node and profile placed on the
/// target surface (see Projector). Curves that leave a node keep their
/// angles there: where the projection puts a node on a ridge of a coarse
/// target and folds two of its curves together, the node goes to the
/// target's closest point instead, if that keeps them apart better. The
/// other way round too: a node sent to its closest point as the end of a
/// profile placed by closest points goes back along the normal if its
/// curves keep their angles better there (on a coarse ear tip, a ring's
/// node whose closest point lay past the next node of its ring, turning
/// the ring's order, so that a line into the ring crossed it). Nodes in
/// `at_corner` go to the nearest free corner of the target triangle they
/// lie on (see transfer()).
/// `source` and `target` are the surfaces placed from and onto: a cage's
/// limit surface where the mesh is a cage, and then the rig is carried up
/// from the source cage (`source_cage`) and down to the target cage.
Rig place_on_target(const Rig& rig, const Embedding& traced, const TraceMesh& source, const TraceMesh& target,
                    const TransferOptions& opt, const CageMap* source_cage, const CageMap* target_cage,
                    const std::set<std::string>& by_closest, const std::set<std::string>& by_section,
                    const std::set<std::string>& by_ends, const std::set<std::string>& at_corner,
                    const SectionMesh* target_sections, double& max_node_offset) {
  // The profiles as the source's embedding traced them, on its surface,
  // without the steps smaller than half the fidelity tolerance (a chain
  // zigzags across the edges near its nodes).
  auto chains = traced.chains();
  const double source_tol = detail::Tolerances::fidelity_rel * source.mesh().bbox_diagonal() / 2;
  for (auto& [id, pts] : chains) {
    std::vector<Vec3> kept;
    for (size_t k : simplify_polyline(pts, source_tol))
      kept.push_back(pts[k]);
    pts = std::move(kept);
  }
  const Mat4 to_target = opt.target_frame.inverse() * opt.source_frame * rig.frame;
  const double diag = target.mesh().bbox_diagonal();
  const RigPlacer placer(rig, source, target, opt, source_cage);
  Rig out = rig;
  out.frame = Mat4::Identity();
  out.extensions.erase("x_cage"); // set again below when the target is a cage
  for (auto& j : out.joints)
    j.bind = to_target * j.bind;
  std::map<std::string, int> node_index;
  std::vector<double> offsets(out.nodes.size());
  for (size_t k = 0; k < out.nodes.size(); ++k) {
    Node& n = out.nodes[k];
    n.position = placer.place_node(rig.nodes[k], false, offsets[k]);
    node_index[n.id] = static_cast<int>(k);
    if (offsets[k] > opt.max_offset * diag)
      throw EmbedError("transfer: node '" + n.id + "' lies " + percent(offsets[k] / diag) +
                       " of the diagonal off the target " + target.mesh().source +
                       " (the frames do not line the meshes up, or the target is another shape)");
  }
  // The ends of the profiles placed by closest points (see transfer()) go to the target's closest points too.
  std::vector<char> at_closest(out.nodes.size(), 0);
  for (const Profile& p : rig.profiles)
    if (by_closest.count(p.id))
      for (const std::string& id : {p.from, p.to}) {
        const int k = node_index.at(id);
        out.nodes[k].position = placer.place_node(rig.nodes[k], true, offsets[k]);
        at_closest[k] = 1;
      }
  // Nodes that two of their curves met near (see transfer()) go to the
  // nearest corner of the target's triangle they lie on, and stay there;
  // a corner that another node is at, or goes to, is passed over (two
  // nodes on one vertex are refused), and a node whose three corners are
  // all taken stays where it is.
  std::vector<char> cornered(out.nodes.size(), 0);
  if (!at_corner.empty()) {
    const double snap = detail::Tolerances::node_snap_rel * diag;
    for (size_t k = 0; k < out.nodes.size(); ++k) {
      if (!at_corner.count(out.nodes[k].id))
        continue;
      const Vec3 at = out.nodes[k].position;
      const auto& tri = target.tri(target.nearest(at).tri);
      std::array<int, 3> corners = tri;
      std::sort(corners.begin(), corners.end(), [&](int a, int b) {
        return std::pair((target.position(a) - at).norm(), a) < std::pair((target.position(b) - at).norm(), b);
      });
      for (const int c : corners) {
        const Vec3& corner = target.position(c);
        bool taken = false;
        for (size_t m = 0; m < out.nodes.size() && !taken; ++m)
          taken = m != k && (out.nodes[m].position - corner).norm() <= snap;
        if (taken)
          continue;
        out.nodes[k].position = corner;
        offsets[k] = (corner - placer.mapped(rig.nodes[k].position)).norm();
        cornered[k] = 1;
        break;
      }
    }
  }
  std::vector<std::vector<Vec3>> mapped(out.profiles.size());
  std::vector<std::pair<std::string, std::string>> jumps; // (profile, refusal)
  auto place = [&](size_t i) {
    Profile& p = out.profiles[i];
    if (p.curve.kind !=
        Curve::Kind::Polyline) // a Bezier or NURBS curve keeps its shape, mapped; the embedding places it
      return;
    const Vec3 &a = out.nodes[node_index.at(p.from)].position, &b = out.nodes[node_index.at(p.to)].position;
    const bool sectioned = by_section.count(p.id) && target_sections != nullptr;
    std::string jump;
    p.curve.points =
        placer.place_profile(rig.profiles[i], chains[i].second, a, b, by_closest.count(p.id) > 0, mapped[i], &jump);
    // Where neither closest points nor a section keep it clear (a claw or
    // a toe the coarse target has lost, that its placed samples zigzag
    // over), its ends alone: the embedding traces it across the target
    // between them. (Not a loop from a node back to itself: its ends are
    // one point.)
    if (by_ends.count(p.id) && p.from != p.to) {
      p.curve.points = {a, b};
      return;
    }
    if (!jump.empty() && !sectioned) { // placed again, with every other profile that jumps (below)
      jumps.emplace_back(p.id, std::move(jump));
      return;
    }
    // Where even closest points fold it (a limb a few faces across), the
    // plane section through its ends and its placed middle: a section
    // cannot fold, and it keeps to the side of the limb the curve was on.
    if (sectioned) {
      auto middle_of = [](const std::vector<Vec3>& q) {
        double length = 0, walked = 0;
        for (size_t k = 1; k < q.size(); ++k)
          length += (q[k] - q[k - 1]).norm();
        for (size_t k = 1; k < q.size(); ++k) {
          const double step = (q[k] - q[k - 1]).norm();
          if (walked + step >= length / 2)
            return Vec3(q[k - 1] + (step > 0 ? (length / 2 - walked) / step : 0.0) * (q[k] - q[k - 1]));
          walked += step;
        }
        return q.front();
      };
      const double tol = detail::Tolerances::fidelity_rel * diag;
      auto section = section_path_through(*target_sections, a, middle_of(p.curve.points), b, tol);
      // Where the placed curve jumped, its middle may lie on another part:
      // the target's closest point to the source curve's middle instead.
      if (!section && !jump.empty() && !mapped[i].empty())
        section = section_path_through(*target_sections, a, placer.closest_on_target(middle_of(mapped[i])), b, tol);
      if (section)
        p.curve.points = std::move(*section);
      else if (!jump.empty())
        throw EmbedError(jump);
    }
  };
  for (size_t i = 0; i < out.profiles.size(); ++i) {
    if (out.profiles[i].curve.kind != Curve::Kind::Polyline)
      for (auto& q : out.profiles[i].curve.points)
        q = apply(to_target, q);
    place(i);
  }
  // Every profile whose placed samples jumped, named in one refusal, so
  // that transfer() places them all again at once (a voxel remesh's tail
  // has a dozen); the first one's words.
  if (!jumps.empty()) {
    std::string more;
    for (size_t k = 1; k < jumps.size(); ++k)
      more += (k == 1 ? "" : ", ") + ("'" + jumps[k].first + "'");
    std::string what = jumps.front().second;
    if (!more.empty())
      what += "; so do profiles " + more;
    throw EmbedError(what);
  }
  // The angles at each node, on the source (mapped) and placed: the worst
  // ratio of a pair's placed angle to its source angle.
  std::vector<std::vector<std::pair<size_t, bool>>> at_node(out.nodes.size()); // (profile, leaves from its start)
  for (size_t i = 0; i < out.profiles.size(); ++i)
    if (out.profiles[i].curve.kind == Curve::Kind::Polyline && out.profiles[i].curve.points.size() >= 2) {
      at_node[node_index.at(out.profiles[i].from)].emplace_back(i, true);
      at_node[node_index.at(out.profiles[i].to)].emplace_back(i, false);
    }
  auto worst_ratio = [&](size_t k) {
    const double reach = placer.edge_near(out.nodes[k].position);
    double worst = 1;
    const auto& list = at_node[k];
    for (size_t a = 0; a < list.size(); ++a)
      for (size_t b = a + 1; b < list.size(); ++b) {
        const auto [pa, sa] = list[a];
        const auto [pb, sb] = list[b];
        const double before =
            std::acos(std::clamp(leaving(mapped[pa], sa, reach).dot(leaving(mapped[pb], sb, reach)), -1.0, 1.0));
        const double after = std::acos(std::clamp(
            leaving(out.profiles[pa].curve.points, sa, reach).dot(leaving(out.profiles[pb].curve.points, sb, reach)),
            -1.0, 1.0));
        if (before > kMinAngle)
          worst = std::min(worst, after / before);
      }
    return worst;
  };
  for (size_t k = 0; k < out.nodes.size(); ++k) {
    const double ratio = worst_ratio(k);
    if (ratio >= kKeptAngle || cornered[k])
      continue;
    const Vec3 placed = out.nodes[k].position; // along the normal, or at the closest point
    std::vector<std::vector<Vec3>> before;
    for (const auto& [i, start] : at_node[k])
      before.push_back(out.profiles[i].curve.points);
    double offset = 0;
    out.nodes[k].position = placer.place_node(rig.nodes[k], !at_closest[k], offset);
    const size_t jumped = jumps.size();
    for (const auto& [i, start] : at_node[k])
      place(i);
    // No better, or one of its curves now jumps (which the refusal above
    // would not see): as it was.
    if (jumps.size() > jumped || worst_ratio(k) <= ratio) {
      jumps.resize(jumped);
      out.nodes[k].position = placed;
      for (size_t m = 0; m < at_node[k].size(); ++m)
        out.profiles[at_node[k][m].first].curve.points = before[m];
    } else {
      offsets[k] = offset;
    }
  }
  for (double o : offsets)
    max_node_offset = std::max(max_node_offset, 100 * o / diag);
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

const char* to_string(Alignment a) {
  switch (a) {
  case Alignment::Frames:
    return "frames";
  case Alignment::Skeletons:
    return "skeletons";
  case Alignment::Auto:
    return "auto";
  }
  return "?";
}

Alignment parse_alignment(const std::string& text, const std::string& option) {
  for (const Alignment a : {Alignment::Frames, Alignment::Skeletons, Alignment::Auto})
    if (text == to_string(a))
      return a;
  throw InputError(option, text, "expected frames, skeletons or auto");
}

std::optional<SkeletonFit> fit_skeletons(const std::vector<Joint>& source, const std::vector<Joint>& target,
                                         double diagonal, std::string* why) {
  auto refuse = [&](const std::string& reason) {
    if (why)
      *why = reason;
    return std::optional<SkeletonFit>();
  };
  const auto [P, Q] = detail::matched_bind_positions(source, target);
  const int n = static_cast<int>(P.cols());
  if (n < 3)
    return refuse(std::to_string(n) + " joints match by name (3 are needed)");
  if (!P.allFinite() || !Q.allFinite())
    return refuse("a joint's position is not finite");
  // On one line (or one point), no rotation about it is determined.
  const Eigen::Matrix3Xd centred = P.colwise() - P.rowwise().mean();
  const Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(centred);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv[1] > 1e-6 * sv[0]))
    return refuse("the " + std::to_string(n) + " matched joints lie on one line");
  SkeletonFit fit;
  fit.source_to_target = Eigen::umeyama(P, Q, true);
  fit.joints = n;
  fit.scale = std::cbrt(std::abs(fit.source_to_target.topLeftCorner<3, 3>().determinant()));
  for (int k = 0; k < n; ++k) {
    const double d = (apply(fit.source_to_target, P.col(k)) - Q.col(k)).norm() / diagonal;
    if (!(d <= fit.worst)) // the larger, or not a number
      fit.worst = d;
  }
  if (!fit.source_to_target.allFinite() || !detail::invertible(fit.source_to_target))
    return refuse("the fit is singular");
  if (!(fit.worst <= detail::Tolerances::skeleton_fit_rel)) {
    std::ostringstream s;
    s << "after the best fit a joint lies " << percent(fit.worst) << " of the diagonal from its match (more than "
      << percent(detail::Tolerances::skeleton_fit_rel) << ": another rig, or another bind pose)";
    return refuse(s.str());
  }
  return fit;
}

namespace {

/// The options with their frames set as `options.alignment` asks, and the
/// report saying how.
TransferOptions aligned(const TransferOptions& options, const SurfaceMesh& source, const SurfaceMesh& target,
                        TransferReport& rep) {
  TransferOptions o = options;
  rep.alignment = "frames";
  if (o.alignment == Alignment::Frames)
    return o;
  const bool frames_given = !o.source_frame.isIdentity(0) || !o.target_frame.isIdentity(0);
  if (o.alignment == Alignment::Auto && o.source_skeleton.empty() && o.target_skeleton.empty())
    return o; // nothing to line up by: the frames, with nothing to say
  std::string why;
  if (o.source_skeleton.empty() || o.target_skeleton.empty())
    why = std::string("the ") + (o.source_skeleton.empty() ? "source " + source.source : "target " + target.source) +
          " has no skeleton";
  else if (frames_given && o.alignment == Alignment::Auto)
    why = "frames were given";
  std::optional<SkeletonFit> fit;
  if (why.empty())
    fit = fit_skeletons(o.source_skeleton, o.target_skeleton, target.bbox_diagonal(), &why);
  if (!fit) {
    if (o.alignment == Alignment::Skeletons)
      throw InputError(source.source + " and " + target.source, "skeletons", "cannot line the meshes up: " + why);
    rep.alignment = "frames (not the skeletons: " + why + ")";
    return o;
  }
  o.source_frame = fit->source_to_target;
  o.target_frame = Mat4::Identity();
  std::ostringstream s;
  s << "skeletons: " << fit->joints << " joints matched, scale " << fit->scale << ", worst joint "
    << percent(fit->worst) << " of the diagonal off";
  rep.alignment = s.str();
  rep.skeleton_fit = fit;
  return o;
}

} // namespace

TransferResult transfer(const Rig& rig, const SurfaceMesh& source, const SurfaceMesh& target,
                        const TransferOptions& options) {
  TransferResult result;
  TransferReport& rep = result.report;
  const TransferOptions opt = aligned(options, source, target, rep);
  if (!detail::invertible(opt.source_frame))
    throw InputError("source frame", "", "the matrix is singular or not finite");
  if (!detail::invertible(opt.target_frame))
    throw InputError("target frame", "", "the matrix is singular or not finite");
  const Mat4 source_to_target = opt.target_frame.inverse() * opt.source_frame;
  const Mat4 to_source = source_to_target.inverse();
  {
    // Frames that carry the source far from the target, or to another size
    // by a thousand times or more, line nothing up: said of the frames (at
    // 1e300 the closest-point queries overflowed, and said so).
    Eigen::AlignedBox3d from, to;
    for (const Vec3& p : source.positions)
      from.extend(p);
    for (const Vec3& p : target.positions)
      to.extend(p);
    Eigen::AlignedBox3d mapped;
    for (int k = 0; k < 8; ++k)
      mapped.extend(apply(source_to_target, from.corner(static_cast<Eigen::AlignedBox3d::CornerType>(k))));
    const double size = to.diagonal().stableNorm(), got = mapped.diagonal().stableNorm();
    const double apart = (mapped.center() - to.center()).stableNorm();
    if (!(got <= 1e3 * size && got >= 1e-3 * size && apart <= 1e3 * size)) {
      std::ostringstream why;
      why << std::setprecision(3) << "they carry the source to " << got / size << " times the target's size, "
          << apart / size << " of its diagonals from it: they do not line the meshes up";
      throw InputError("source and target frames", "", why.str());
    }
  }
  // A full net (or an automatic one on a closed source) cannot cover an
  // open target: said before the work, with what to do about it.
  if (rig.coverage != Coverage::Local)
    if (const std::string open = open_parts_words(target); !open.empty() && open_parts_words(source).empty())
      throw EmbedError("transfer: the target " + target.source + " is open (" + open + ") where the source " +
                       source.source +
                       " is closed, and the rig's net covers the whole surface: close the target's holes (a LOD "
                       "simplified part by part, as gltfpack -si does a file of several primitives, has cracks "
                       "between the parts: simplify it as one mesh), or make the target's own net with curvenet "
                       "starter, which gives an open mesh a local net");

  EmbedOptions source_embed = opt.embed, target_embed = opt.embed;
  source_embed.cage = opt.source_cage_levels > 0;
  target_embed.cage = opt.target_cage_levels > 0;
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
  // Two lines of work side by side, twice, as most of an embedding is
  // serial. First the source's trace mesh and its embedding beside the
  // target's trace mesh; then the placing and the target's embedding beside
  // the shape distance, measured at every vertex of each mesh (the corners
  // of its triangles) on the trace meshes built for placing, where the
  // frames leave the source where it is. The half-edge mesh each trace mesh
  // is built from goes on to be its embedding's first cut mesh.
  std::unique_ptr<TraceMesh> source_trace, target_trace;
  std::optional<CutMesh> source_uncut, target_uncut;
  std::optional<Embedding> source_embedding, placed;
  tbb::parallel_invoke(
      [&] {
        if (!source_cage)
          source_trace = std::make_unique<TraceMesh>(source, source_uncut.emplace(CutMesh::from_surface(source)));
        try {
          source_embedding.emplace(source_cage ? embed(source, rig, source_embed)
                                               : embed_on(source, *source_trace, rig, source_embed,
                                                          std::exchange(source_uncut, std::nullopt)));
        } catch (const EmbedError& e) { // said of the source, as its report's refusal is
          throw EmbedError("transfer: the rig does not embed on the source " + source.source + ": " + e.what());
        }
      },
      [&] {
        if (!target_cage)
          target_trace = std::make_unique<TraceMesh>(target, target_uncut.emplace(CutMesh::from_surface(target)));
      });
  const TraceMesh& source_placed = source_cage ? source_cage->limit_trace() : *source_trace;
  const TraceMesh& target_placed = target_cage ? target_cage->limit_trace() : *target_trace;
  const TraceMesh& source_located = source_cage ? source_cage->cage_trace() : *source_trace;
  rep.source = source_embedding->report();
  if (!rep.source.ok)
    throw EmbedError("transfer: the rig does not embed on the source " + source.source + ": " +
                     (rep.source.problems.empty() ? std::string("not ok") : rep.source.problems[0]));
  std::string unplaced; // the target's embedding's last refusal, when the placing gives up
  int placings = 0;     // how many times the rig was placed
  tbb::parallel_invoke(
      [&] {
        const Embedding& src = *source_embedding;
        // Placed along the source's normals; where the target's embedding
        // then finds two profiles crossing or a profile straying (a thin
        // limb of a coarse target, whose few faces the normals cross at
        // steep angles), the profiles it names go to the target's closest
        // points instead, a few times over.
        // Then, for those named again, the plane section through their
        // placed ends and middle; then their ends alone.
        std::set<std::string> by_closest, by_section, by_ends, at_corner;
        std::map<std::string, std::pair<std::string, std::string>> ends; // of each profile, by id
        for (const Profile& p : rig.profiles)
          ends[p.id] = {p.from, p.to};
        std::optional<SectionMesh> sections;
        for (int attempt = 0;; ++attempt) {
          try {
            double offset = 0;
            result.rig =
                place_on_target(rig, src, source_placed, target_placed, opt, source_cage ? &*source_cage : nullptr,
                                target_cage ? &*target_cage : nullptr, by_closest, by_section, by_ends, at_corner,
                                sections ? &*sections : nullptr, offset);
            rep.max_node_offset = offset;
            placed.emplace(target_cage ? embed(target, result.rig, target_embed)
                                       : embed_on(target, *target_trace, result.rig, target_embed,
                                                  std::exchange(target_uncut, std::nullopt)));
            return;
          } catch (const EmbedError& e) {
            const std::string what = e.what();
            bool more = false;
            // A profile whose projection jumped is placed again too; the
            // other refusals of the placing itself are final.
            const bool jumped = what.rfind("transfer: profile '", 0) == 0 && what.find(" jump") != std::string::npos;
            if (attempt < kReplacements && (what.rfind("transfer:", 0) != 0 || jumped))
              for (const std::string& id : quoted(what)) {
                if (!ends.count(id))
                  continue;
                if (by_closest.insert(id).second) {
                  more = true;
                } else if (by_section.insert(id).second) {
                  more = true;
                  if (!sections)
                    sections.emplace(target_surface);
                } else if (by_ends.insert(id).second) {
                  more = true;
                }
              }
            // Last, where the target's embedding still names two profiles
            // that share a node, each placed every way (on a coarse target
            // they meet near it): a node a tenth of an edge off a corner
            // (where a flat tail's edge runs) leaves its curves only the
            // sliver between it and the corner to pass through. The node
            // goes to the corner. (Not on a cage, whose limit surface the
            // rig is placed on: a corner there is not the cage's.)
            if (!more && attempt < kReplacements && what.rfind("transfer:", 0) != 0 && !target_cage) {
              const std::vector<std::string> named = quoted(what);
              for (size_t a = 0; a < named.size(); ++a)
                for (size_t b = a + 1; b < named.size(); ++b) {
                  const auto pa = ends.find(named[a]), pb = ends.find(named[b]);
                  if (pa == ends.end() || pb == ends.end())
                    continue;
                  for (const std::string& node : {pa->second.first, pa->second.second})
                    if ((node == pb->second.first || node == pb->second.second) && at_corner.insert(node).second)
                      more = true;
                }
            }
            if (!more) {
              unplaced = what;
              placings = attempt + 1;
              return;
            }
          }
        }
      },
      [&] {
        SurfaceMesh mapped = source_surface;
        for (auto& p : mapped.positions)
          p = apply(source_to_target, p);
        const bool same_space = source_to_target.isIdentity(0);
        const std::unique_ptr<TraceMesh> mapped_trace = same_space ? nullptr : trace_of(mapped);
        rep.shape = detail::surface_distance(mapped, same_space ? source_placed : *mapped_trace, target_surface,
                                             target_placed, 1);
      });
  // A refusal says how far apart the surfaces lie, and, where the
  // skeletons were asked for and not used, why not.
  const std::string apart =
      " (the surfaces lie up to " + percent(rep.shape.max / rep.shape.diagonal) + " of the diagonal apart, " +
      percent(rep.shape.mean / rep.shape.diagonal) + " on average" +
      (rep.alignment.rfind("frames (", 0) == 0 ? "; lined up by " + rep.alignment : std::string()) + ")";
  // Named by the target: it is where the placed rig did not embed. Where
  // placing again could not keep the curves apart, what to do.
  if (!placed && unplaced.rfind("transfer:", 0) == 0)
    throw EmbedError(unplaced + apart);
  // What to do: a coarser target may have too few faces for the rig's
  // curves; a finer one (a remesh, a subdivision) is not that, and a net
  // made on it fits either way.
  const bool coarser = target_surface.num_faces() < source_surface.num_faces();
  const std::string own_net = "a net made on the target (curvenet starter) fits it, with ids of its own";
  if (!placed && placings <= 1)
    throw EmbedError(target.source + ": " + unplaced + apart + "; " +
                     (coarser ? "the target has " + std::to_string(target_surface.num_faces()) +
                                    " faces against the source's " + std::to_string(source_surface.num_faces()) + ": "
                              : std::string()) +
                     own_net);
  if (!placed)
    throw EmbedError(target.source + ": " + unplaced + apart + "; placed " + std::to_string(placings) +
                     " times, the curves it names still do not fit: " +
                     (coarser ? "the target may have too few faces there for the rig's curves (a thin part a few "
                                "faces round); "
                              : "the target's shape there may differ from the source's (the surfaces' distance "
                                "above); ") +
                     own_net);
  const Embedding& src = *source_embedding;
  const Embedding& tgt = *placed;
  rep.target = tgt.report();
  const EmbedReport &a = rep.source, &b = rep.target;
  if (!b.ok)
    for (const auto& pr : b.problems)
      rep.problems.push_back("target: " + pr + apart);
  if (a.logical_nodes != b.logical_nodes || a.profiles != b.profiles || a.components != b.components)
    rep.problems.push_back("the logical counts differ between source and target");
  // A part no curve touches (an eye or a tooth modelled apart, on one mesh
  // and not the other) is a region without a boundary: said in a note, and
  // left out of the comparison, as no curve of the transfer bounds it (bound,
  // it follows its nearest joint rigidly).
  auto parts = [](const EmbedReport& r) {
    int n = 0, faces = 0;
    for (const auto& g : r.region_list)
      if (g.boundary.empty()) {
        ++n;
        faces += g.faces;
      }
    return std::pair{n, faces};
  };
  const auto [source_parts, source_part_faces] = parts(a);
  const auto [target_parts, target_part_faces] = parts(b);
  if (source_parts != target_parts)
    rep.notes.push_back("the target has " + std::to_string(target_parts) + (target_parts == 1 ? " part" : " parts") +
                        " that no curve touches (" + std::to_string(target_part_faces) + " cut faces), the source " +
                        std::to_string(source_parts) +
                        ": left out of the region comparison; bound, each follows its nearest joint rigidly");
  if (a.regions - source_parts != b.regions - target_parts)
    rep.problems.push_back("the region counts differ: " + std::to_string(a.regions) + " on the source, " +
                           std::to_string(b.regions) + " on the target");

  // Region correspondence: the target's area, sampled at the centroid of
  // every triangle of its cut faces, against the source region found there.
  const RegionLocator locate(source_located, src);
  std::map<std::string, std::pair<double, double>> by_key; // key -> (area, agreeing area)
  const CutMesh& cm = tgt.impl().cut;
  std::vector<std::string> keys(b.region_list.size());
  for (size_t r = 0; r < keys.size(); ++r)
    keys[r] = b.region_list[r].key();
  // Each region's identity as a number, on both sides; a point outside a
  // local net has the empty identity.
  std::map<std::string, int> identity{{"", 0}};
  auto identity_of = [&](const std::string& key) {
    return identity.emplace(key, static_cast<int>(identity.size())).first->second;
  };
  std::vector<int> target_identity(keys.size()), source_identity(a.region_list.size());
  for (size_t r = 0; r < keys.size(); ++r)
    target_identity[r] = identity_of(keys[r]);
  for (size_t r = 0; r < source_identity.size(); ++r)
    source_identity[r] = identity_of(a.region_list[r].key());
  auto source_identity_at = [&](const Vec3& p, const Vec3* facing) {
    const int r = locate.region_at(p, facing);
    return r < 0 ? 0 : source_identity[r];
  };
  // Per cut face, in parallel: its area, and the part of it whose source
  // region has its key. Two regions can only disagree where their borders
  // do, so the faces along the curves (a side on a chain) are all
  // measured, and the faces inside a region on an even share of them
  // (every k-th, up to kRegionSamples), each standing for k: the same
  // fraction to well under a percent, at a fraction of the cost on a large
  // mesh.
  std::vector<char> border(cm.num_faces(), 0);
  tbb::parallel_for(0, cm.num_faces(), [&](int f) {
    const Halfedge h0 = cm.halfedge(Face(f));
    Halfedge hh = h0;
    for (int sides = 0; sides < 1 << 20 && !border[f]; ++sides) {
      border[f] = cm.tag(hh).is_curve() || cm.tag(CutMesh::twin(hh)).is_curve();
      hh = cm.next(hh);
      if (hh == h0)
        break;
    }
  });
  std::vector<int> region_faces(keys.size(), 0), nth(cm.num_faces(), 0);
  for (int f = 0; f < cm.num_faces(); ++f)
    if (const int r = tgt.face_regions()[f]; r >= 0 && !border[f])
      nth[f] = region_faces[r]++;
  std::vector<int> stride(keys.size(), 1);
  for (size_t r = 0; r < keys.size(); ++r)
    stride[r] = std::max(1, region_faces[r] / kRegionSamples);
  std::vector<std::pair<double, double>> face_area(cm.num_faces(), {0.0, 0.0});
  // A target triangle's outward normal (its sides' cross product) as a
  // direction in the source's space: by the inverse transpose, as the
  // projector maps the source's normals the other way.
  const Eigen::Matrix3d facing_map = to_source.topLeftCorner<3, 3>().inverse().transpose();
  tbb::parallel_for(0, cm.num_faces(), [&](int f) {
    const int r = tgt.face_regions()[f];
    if (r < 0 || (!border[f] && nth[f] % stride[r] != 0))
      return;
    const int weight = border[f] ? 1 : stride[r];
    thread_local std::vector<Vec3> corners;
    corners.clear();
    const Halfedge h0 = cm.halfedge(Face(f));
    for (Halfedge hh = h0;;) {
      corners.push_back(cm.position(cm.from(hh)));
      hh = cm.next(hh);
      if (hh == h0 || corners.size() > 1u << 20)
        break;
    }
    static const std::vector<std::array<int, 3>> one{{0, 1, 2}};
    for (const auto& t : corners.size() == 3 ? one : triangulate_polygon(corners)) {
      const double area = 0.5 * (corners[t[1]] - corners[t[0]]).cross(corners[t[2]] - corners[t[0]]).norm();
      if (!(area > 0))
        continue;
      const Vec3 centroid = (corners[t[0]] + corners[t[1]] + corners[t[2]]) / 3;
      // Through the limit surfaces where either mesh is a cage.
      Vec3 at = apply(to_source, target_cage ? target_cage->to_limit(centroid) : centroid);
      if (source_cage)
        at = source_cage->to_cage(at);
      face_area[f].first += weight * area;
      // Looked up on the side of the source the triangle faces (not through
      // a cage's limit surface, whose triangles are not the located mesh's).
      const Vec3 facing =
          (facing_map * (corners[t[1]] - corners[t[0]]).cross(corners[t[2]] - corners[t[0]])).normalized();
      const bool sided = !target_cage && !source_cage;
      face_area[f].second +=
          source_identity_at(at, sided ? &facing : nullptr) == target_identity[r] ? weight * area : 0;
    }
  });
  double total = 0, agreeing = 0; // summed in face order: the same on any thread count
  std::vector<std::pair<double, double>> by_region(keys.size(), {0.0, 0.0});
  for (int f = 0; f < cm.num_faces(); ++f) {
    const int r = tgt.face_regions()[f];
    if (r < 0)
      continue;
    by_region[r].first += face_area[f].first;
    by_region[r].second += face_area[f].second;
    if (keys[r].empty()) // a part no curve touches: no curve of the transfer placed it
      continue;
    total += face_area[f].first;
    agreeing += face_area[f].second;
  }
  for (size_t r = 0; r < keys.size(); ++r) { // regions of one key (none on a valid net) summed in region order
    if (keys[r].empty())
      continue;
    by_key[keys[r]].first += by_region[r].first;
    by_key[keys[r]].second += by_region[r].second;
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
  j["alignment"] = r.alignment;
  if (r.skeleton_fit) {
    nlohmann::ordered_json m = nlohmann::ordered_json::array();
    for (int row = 0; row < 4; ++row)
      for (int col = 0; col < 4; ++col)
        m.push_back(r.skeleton_fit->source_to_target(row, col));
    j["skeleton_fit"] = {{"joints", r.skeleton_fit->joints},
                         {"scale", r.skeleton_fit->scale},
                         {"worst", r.skeleton_fit->worst},
                         {"source_to_target", m}};
  }
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
  j["notes"] = r.notes;
  return j.dump(2) + "\n";
}

} // namespace curvenet
