// The starter Curvenet (docs/starter.md): rings from plane sections through
// the joints, profiles along each chain, joins where chains branch, and a
// check that the result embeds.

#include "curvenet/starter.hpp"

#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "core/predicates.hpp"
#include "starter/plane_section.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <numbers>
#include <regex>
#include <set>

#include <Eigen/Eigenvalues>

namespace curvenet {

using namespace detail;

namespace {

struct Skeleton {
  std::vector<Vec3> origin;
  std::vector<int> parent;
  std::vector<std::vector<int>> kids;
  std::vector<Eigen::Matrix3d> rotation;
  std::vector<int> subtree; ///< joints in the subtree, the joint included

  explicit Skeleton(const std::vector<Joint>& joints) {
    const int n = static_cast<int>(joints.size());
    std::map<std::string, int> index;
    for (int j = 0; j < n; ++j)
      index[joints[j].name] = j;
    parent.assign(n, -1);
    kids.resize(n);
    for (int j = 0; j < n; ++j) {
      origin.push_back(joints[j].bind.block<3, 1>(0, 3));
      rotation.push_back(joints[j].bind.block<3, 3>(0, 0));
      if (joints[j].parent) {
        parent[j] = index.at(*joints[j].parent);
        kids[parent[j]].push_back(j);
      }
    }
    subtree.assign(n, 1);
    for (int j = 0; j < n; ++j) // a joint's ancestors (the hierarchy is acyclic: the rig reader checks it)
      for (int a = parent[j], guard = 0; a >= 0 && guard < n; a = parent[a], ++guard)
        ++subtree[a];
  }
};

/// Where a ring may sit: the plane through base + t * step, with normal
/// `along` (or `start_axis` at t = 0), for t in [t_min, t_max]. Moving a ring
/// along its bone raises t.
struct Placement {
  Vec3 base = Vec3::Zero(), step = Vec3::Zero();
  Vec3 along = Vec3::UnitZ(), start_axis = Vec3::UnitZ();
  double t_min = 0, t_max = 0;
  [[nodiscard]] Vec3 point(double t) const { return base + t * step; }
  [[nodiscard]] Vec3 axis(double t) const { return t == 0 ? start_axis : along; }
};

/// A ring: a closed section around a limb (or around several, a trunk).
struct Ring {
  std::string id;
  int joint = -1;  ///< the joint it belongs to
  double frac = 1; ///< its order among the rings of `joint` (1: the joint's own ring; 0: a shared trunk's)
  std::vector<int> own; ///< the joints whose bones it may enclose: `joint`, or a trunk's joints
  Placement place;
  double t = 0; ///< where in `place` it sits
  Vec3 centre = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ(); ///< the plane's normal, along the bone
  std::vector<Vec3> loop;    ///< counter-clockwise about `axis`
  std::vector<double> at;    ///< arc length of each loop point
  double perimeter = 0;
  int replaced_by = -1; ///< dropped: the ring that stands for it
  bool active = false;
  Vec3 ref = Vec3::Zero();        ///< direction of node 0 from the centre
  std::vector<double> base_nodes; ///< arc-length positions of nodes 0..N-1
  [[nodiscard]] double radius() const { return perimeter / (2 * std::numbers::pi); }
};

Vec3 loop_point(const Ring& r, double s) {
  s = std::fmod(std::fmod(s, r.perimeter) + r.perimeter, r.perimeter);
  const size_t n = r.loop.size();
  size_t i = std::upper_bound(r.at.begin(), r.at.end(), s) - r.at.begin();
  i = i == 0 ? 0 : i - 1;
  const Vec3& a = r.loop[i];
  const Vec3& b = r.loop[(i + 1) % n];
  const double len = (i + 1 < n ? r.at[i + 1] : r.perimeter) - r.at[i];
  const double t = len > 0 ? (s - r.at[i]) / len : 0;
  return (1 - t) * a + t * b;
}

/// The loop between arc positions s0 and s1 (going forward), ends included.
std::vector<Vec3> loop_between(const Ring& r, double s0, double s1) {
  if (s1 <= s0)
    s1 += r.perimeter;
  std::vector<Vec3> pts{loop_point(r, s0)};
  const size_t n = r.loop.size();
  for (int lap = 0; lap < 2; ++lap)
    for (size_t i = 0; i < n; ++i) {
      const double s = r.at[i] + lap * r.perimeter;
      if (s > s0 && s < s1)
        pts.push_back(r.loop[i]);
    }
  pts.push_back(loop_point(r, s1));
  return pts;
}

/// Arc-length position of the loop point closest to p.
double closest_on_loop(const Ring& r, const Vec3& p, double* distance = nullptr) {
  double best = std::numeric_limits<double>::infinity(), best_s = 0;
  const size_t n = r.loop.size();
  for (size_t i = 0; i < n; ++i) {
    const Vec3 &a = r.loop[i], &b = r.loop[(i + 1) % n];
    const double l2 = (b - a).squaredNorm();
    const double t = l2 > 0 ? std::clamp((p - a).dot(b - a) / l2, 0.0, 1.0) : 0.0;
    const double d = (a + t * (b - a) - p).norm();
    if (d < best) {
      best = d;
      best_s = r.at[i] + t * std::sqrt(l2);
    }
  }
  if (distance)
    *distance = best;
  return best_s;
}

/// The shortest way along the surface between a and b inside the plane through
/// a, b and m: the shorter arc of the section that holds both points.
std::optional<std::vector<Vec3>> section_path(const SectionMesh& sm, const Vec3& a, const Vec3& b, const Vec3& m,
                                              const Vec3& fallback_axis, double tol) {
  Vec3 n = (b - a).cross(m - a);
  if (n.norm() < 1e-12 * (b - a).norm() * (m - a).norm())
    n = (b - a).cross(fallback_axis);
  if (n.norm() == 0)
    return std::nullopt;
  for (const Section& s : plane_sections(sm, a, n)) {
    Ring tmp;
    tmp.loop = s.points;
    if (!s.closed)
      continue;
    tmp.at.resize(tmp.loop.size());
    double acc = 0;
    for (size_t i = 0; i < tmp.loop.size(); ++i) {
      tmp.at[i] = acc;
      acc += (tmp.loop[(i + 1) % tmp.loop.size()] - tmp.loop[i]).norm();
    }
    tmp.perimeter = acc;
    double da = 0, db = 0;
    const double sa = closest_on_loop(tmp, a, &da), sb = closest_on_loop(tmp, b, &db);
    if (da > tol || db > tol)
      continue;
    const double forward = std::fmod(sb - sa + tmp.perimeter, tmp.perimeter);
    std::vector<Vec3> path = forward <= tmp.perimeter / 2 ? loop_between(tmp, sa, sb) : loop_between(tmp, sb, sa);
    if (forward > tmp.perimeter / 2)
      std::reverse(path.begin(), path.end());
    path.front() = a;
    path.back() = b;
    return path;
  }
  return std::nullopt;
}

double path_length(const std::vector<Vec3>& p) {
  double len = 0;
  for (size_t i = 1; i < p.size(); ++i)
    len += (p[i] - p[i - 1]).norm();
  return len;
}

/// Paths along the surface from a to b: the sections through the preferred
/// third points first, then those of planes turned about the line through a
/// and b, shortest first.
std::vector<std::vector<Vec3>> surface_paths(const SectionMesh& sm, const Vec3& a, const Vec3& b,
                                             const std::vector<Vec3>& preferred, double tol) {
  std::vector<std::vector<Vec3>> out;
  const Vec3 d = b - a;
  for (const Vec3& m : preferred)
    if (auto p = section_path(sm, a, b, m, d.unitOrthogonal(), tol))
      out.push_back(std::move(*p));
  std::vector<std::vector<Vec3>> swept;
  const Vec3 e1 = d.unitOrthogonal(), e2 = d.normalized().cross(e1);
  for (int k = 0; k < 12; ++k) {
    const double ang = std::numbers::pi * k / 12;
    const Vec3 m = (a + b) / 2 + d.norm() * (std::cos(ang) * e1 + std::sin(ang) * e2);
    if (auto p = section_path(sm, a, b, m, e1, tol))
      swept.push_back(std::move(*p));
  }
  std::sort(swept.begin(), swept.end(), [](const auto& x, const auto& y) { return path_length(x) < path_length(y); });
  out.insert(out.end(), swept.begin(), swept.end());
  return out;
}

std::vector<std::string> quoted(const std::string& text) {
  std::vector<std::string> out;
  static const std::regex re("'([^']+)'");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
    out.push_back((*it)[1]);
  return out;
}

/// How squarely a path along the surface crosses a ring at one of its ends
/// (at arc position s_at): the sine of the angle between the path's
/// direction over its first (or last) half edge length h and the ring.
double crossing_sine(const std::vector<Vec3>& path, const Ring& ring, double s_at, bool at_end, double h) {
  const Vec3& o = at_end ? path.back() : path.front();
  Vec3 d = Vec3::Zero();
  for (size_t k = 1; k < path.size(); ++k) {
    d = (at_end ? path[path.size() - 1 - k] : path[k]) - o;
    if (d.norm() >= 0.5 * h)
      break;
  }
  const Vec3 tangent = loop_point(ring, s_at + 1e-3 * ring.perimeter) - loop_point(ring, s_at - 1e-3 * ring.perimeter);
  return d.norm() > 0 && tangent.norm() > 0 ? d.normalized().cross(tangent.normalized()).norm() : 0.0;
}

/// The smallest closed section of the plane (point, axis) that winds around
/// `point`, as a ring: counter-clockwise about the axis, with its area
/// centroid and arc lengths.
std::optional<Ring> section_ring(const SectionMesh& sm, const Vec3& point, const Vec3& axis) {
  const Section* best = nullptr;
  const auto sections = plane_sections(sm, point, axis);
  for (const Section& s : sections)
    if (s.closed && s.points.size() >= 3 && winding_number(s.points, point, point, axis) != 0 &&
        (!best || s.length() < best->length()))
      best = &s;
  if (!best)
    return std::nullopt;
  Ring r;
  r.axis = axis.normalized();
  r.loop = best->points;
  const auto [u, v] = plane_basis(r.axis);
  double area = 0;
  Eigen::Vector2d c2 = Eigen::Vector2d::Zero();
  for (size_t i = 0; i < r.loop.size(); ++i) {
    const Vec3 a = r.loop[i] - point, b = r.loop[(i + 1) % r.loop.size()] - point;
    const double cr = a.dot(u) * b.dot(v) - a.dot(v) * b.dot(u);
    area += cr / 2;
    c2 += cr * Eigen::Vector2d(a.dot(u) + b.dot(u), a.dot(v) + b.dot(v)) / 6;
  }
  if (area == 0)
    return std::nullopt;
  if (area < 0)
    std::reverse(r.loop.begin(), r.loop.end());
  r.centre = point + (c2.x() / area) * u + (c2.y() / area) * v;
  double acc = 0;
  for (size_t i = 0; i < r.loop.size(); ++i) {
    r.at.push_back(acc);
    acc += (r.loop[(i + 1) % r.loop.size()] - r.loop[i]).norm();
  }
  r.perimeter = acc;
  return r;
}

/// The bones (by child joint) that pass through the ring's plane inside its
/// loop. Which side of the plane a bone's end lies on is an exact test.
std::vector<int> bones_inside(const Ring& r, const Vec3& point, const Skeleton& sk) {
  const auto [u, v] = plane_basis(r.axis);
  const Vec3 o1 = point + u, o2 = point + v;
  std::vector<int> inside;
  for (int c = 0; c < static_cast<int>(sk.parent.size()); ++c) {
    const int p = sk.parent[c];
    if (p < 0)
      continue;
    const Vec3 &a = sk.origin[p], &b = sk.origin[c];
    const int sa = orient3d(point, o1, o2, a), sb = orient3d(point, o1, o2, b);
    if (sa == 0 || sb == 0 || sa == sb)
      continue;
    const double da = (a - point).dot(r.axis), db = (b - point).dot(r.axis);
    const Vec3 x = a + (da / (da - db)) * (b - a);
    if (winding_number(r.loop, x, point, r.axis) != 0)
      inside.push_back(c);
  }
  return inside;
}

/// A bone (by child joint) that starts or ends at one of `joints`.
bool incident(int bone, const std::vector<int>& joints, const Skeleton& sk) {
  return std::any_of(joints.begin(), joints.end(), [&](int j) { return bone == j || sk.parent[bone] == j; });
}

/// A ring's section is local to its joints when no bone but theirs (those
/// that start or end at one of them) passes through the plane inside the
/// loop. Returns the first foreign bone inside, or -1.
int foreign_bone_inside(const Ring& r, const Vec3& point, const std::vector<int>& own, const Skeleton& sk) {
  for (int c : bones_inside(r, point, sk))
    if (!incident(c, own, sk))
      return c;
  return -1;
}

/// Nodes at angles 2 pi k / N about the axis from r.ref, where rays from the
/// centre meet the loop; spread by arc length when they do not meet it in
/// order. Returns false in that case.
bool place_nodes(Ring& r, int N, double first_angle_deg) {
  Vec3 ref = r.ref - r.ref.dot(r.axis) * r.axis;
  if (ref.norm() < 1e-9)
    ref = plane_basis(r.axis)[0];
  ref.normalize();
  const Vec3 side = r.axis.cross(ref);
  std::vector<double> pos;
  for (int k = 0; k < N; ++k) {
    const double ang = 2 * std::numbers::pi * k / N + first_angle_deg * std::numbers::pi / 180;
    const Vec3 dir = std::cos(ang) * ref + std::sin(ang) * side;
    const Vec3 perp = r.axis.cross(dir);
    // Nearest crossing of the ray from the centre with the loop.
    double best = std::numeric_limits<double>::infinity(), best_s = -1;
    for (size_t q = 0; q < r.loop.size(); ++q) {
      const Vec3 a = r.loop[q] - r.centre, b = r.loop[(q + 1) % r.loop.size()] - r.centre;
      // Solve lambda * dir = a + t (b - a) in the plane (2D, basis dir / perp).
      const double ax = a.dot(dir), ay = a.dot(perp), bx = b.dot(dir), by = b.dot(perp);
      if ((ay > 0) == (by > 0) && ay != 0 && by != 0)
        continue;
      const double t = ay != by ? ay / (ay - by) : 0;
      const double lambda = ax + t * (bx - ax);
      if (lambda > 0 && lambda < best) {
        best = lambda;
        best_s = r.at[q] + t * (b - a).norm();
      }
    }
    pos.push_back(best_s);
  }
  bool in_order = pos[0] >= 0;
  for (int k = 1; k < N && in_order; ++k) {
    const double prev = std::fmod(pos[k - 1] - pos[0] + r.perimeter, r.perimeter);
    const double cur = std::fmod(pos[k] - pos[0] + r.perimeter, r.perimeter);
    in_order = pos[k] >= 0 && cur > prev;
  }
  if (!in_order) {
    const double s0 = pos[0] >= 0 ? pos[0] : 0;
    for (int k = 0; k < N; ++k)
      pos[k] = std::fmod(s0 + r.perimeter * k / N, r.perimeter);
  }
  r.base_nodes = pos;
  return in_order;
}

} // namespace

StarterResult make_starter(const SurfaceMesh& mesh, const std::vector<Joint>& joints, const StarterOptions& opt) {
  if (joints.empty())
    throw InputError(mesh.source, "skeleton", "has no joints");
  if (opt.nodes_per_ring < 2)
    throw Error("starter: at least 2 nodes per ring are needed");
  if (opt.rings_per_bone < 1)
    throw Error("starter: at least 1 ring per bone is needed");
  if (joints.size() > 1 &&
      std::all_of(joints.begin(), joints.end(), [](const Joint& j) { return !j.parent.has_value(); }))
    throw InputError(mesh.source, "skeleton",
                     "its " + std::to_string(joints.size()) +
                         " joints are all roots (a flat hierarchy, as some XR hand assets have): the starter needs "
                         "bones from parent to child; give a skeleton with --skeleton");
  StarterResult result;
  auto say = [&](const std::string& m) {
    result.messages.push_back(m);
    if (opt.message)
      opt.message(m);
  };
  const Skeleton sk(joints);
  const SectionMesh sm(mesh);
  const double diag = mesh.bbox_diagonal(), h = mesh.mean_edge_length();
  const double tol = 1e-6 * diag;
  const int N = opt.nodes_per_ring;
  const int nj = static_cast<int>(joints.size());
  std::map<int, std::string> ringless; // joint -> why it has no ring (the latest reason)
  auto bone_name = [&](int c) { return "'" + joints[sk.parent[c]].name + "'-'" + joints[c].name + "'"; };
  auto percent = [](double t) { return std::to_string(static_cast<int>(std::lround(100 * t))) + "%"; };

  // 1. Candidate rings, local to their bones.
  struct Probe {
    std::optional<Ring> ring;
    int foreign = -1;
  };
  auto probe_shared = [&](const std::vector<int>& own, const Placement& pl, double t) {
    Probe q;
    q.ring = section_ring(sm, pl.point(t), pl.axis(t));
    if (q.ring) {
      q.foreign = foreign_bone_inside(*q.ring, pl.point(t), own, sk);
      q.ring->place = pl;
      q.ring->t = t;
      q.ring->joint = own.front();
      q.ring->own = own;
    }
    return q;
  };
  auto probe = [&](int j, const Placement& pl, double t) { return probe_shared({j}, pl, t); };
  auto local = [&](const Probe& q) { return q.ring && q.foreign < 0 && static_cast<int>(q.ring->loop.size()) >= N; };
  // The first local ring in the placement's range, moved on past where the
  // section first becomes local.
  auto first_local = [&](int j, const Placement& pl, std::string& why) -> std::optional<Ring> {
    constexpr int steps = 10;
    const bool range = pl.t_max > pl.t_min;
    double prev = pl.t_min;
    int foreign = -1, small = 0;
    for (int k = 0; k <= (range ? steps : 0); ++k) {
      const double t = pl.t_min + (pl.t_max - pl.t_min) * k / steps;
      const Probe q = probe(j, pl, t);
      if (local(q)) {
        if (k == 0)
          return q.ring;
        double lo = prev, hi = t;
        for (int it = 0; it < 6; ++it) {
          const double mid = (lo + hi) / 2;
          (local(probe(j, pl, mid)) ? hi : lo) = mid;
        }
        // Clear of a fork by a third of the radius, clear of the surface's
        // rounded end (no section before) by a whole radius; by at most a
        // quarter of the bone.
        const double len = pl.step.norm();
        const double clear = std::min(0.25, (foreign >= 0 ? 1.0 / 3 : 1.0) * q.ring->radius() / len);
        // The furthest of a few steps back from there that is local.
        for (const double back : {0.0, 0.25, 0.5, 0.75})
          if (Probe m = probe(j, pl, std::min(pl.t_max, hi + (1 - back) * clear)); local(m))
            return m.ring;
        return q.ring;
      }
      if (q.ring && q.foreign >= 0)
        foreign = q.foreign;
      else if (q.ring)
        ++small;
      prev = t;
    }
    why = foreign >= 0 ? "every section across its bone" + (range ? " up to " + percent(pl.t_max) + " along it" : "") +
                             " also encloses bone " + bone_name(foreign) + " (a shared trunk)"
          : small ? "its section crosses fewer mesh edges than " + std::to_string(N) + " nodes need"
                  : "no section there winds around its bone (outside the mesh)";
    return std::nullopt;
  };

  // Where no section across the bone is local (a thumb's metacarpal in the
  // ball of the thumb), the narrowest local section through the bone's
  // middle part whose plane is tilted from the bone by up to 45 degrees.
  auto tilted_local = [&](int j, const Placement& pl) -> std::optional<Ring> {
    std::optional<Ring> best;
    const auto [u, v] = plane_basis(pl.along);
    for (int it = 3; it <= 9; ++it)
      for (const double tilt : {15.0, 30.0, 45.0})
        for (int az = 0; az < 8; ++az) {
          const double a = az * std::numbers::pi / 4, b = tilt * std::numbers::pi / 180;
          const Vec3 axis = std::cos(b) * pl.along + std::sin(b) * (std::cos(a) * u + std::sin(a) * v);
          Probe q = probe(j, {pl.base + pl.step * (it / 10.0), Vec3::Zero(), axis, axis, 0, 0}, 0);
          if (local(q) && (!best || q.ring->perimeter < best->perimeter))
            best = std::move(q.ring);
        }
    return best;
  };
  // A joint's ring moves at most part of the way to the next ring spot
  // along the bone (1 / rings_per_bone), so rings stay in order along a chain.
  std::vector<Ring> rings;
  struct Start {
    Vec3 point, axis;
    double radius;
    std::vector<int> inside; ///< bones through the section
  };
  std::map<int, Start> shared_start; // joint -> its section through the joint, where that is not local
  const int R = opt.rings_per_bone;
  auto suffix = [&](int i) { return R > 1 ? "_" + std::to_string(i) : std::string(); };
  for (int j = 0; j < nj; ++j) {
    const int p = sk.parent[j];
    const auto& kids = sk.kids[j];
    const std::string& name = joints[j].name;
    Placement pl;
    std::optional<Ring> own;
    if (!kids.empty() && p >= 0 && kids.size() == 1) {
      // Through the joint across the bisector of its two bones; if that
      // section is not local, along the bone out of it.
      const Vec3 in = sk.origin[j] - sk.origin[p], out = sk.origin[kids[0]] - sk.origin[j];
      if (out.norm() > 0) {
        Vec3 start = in.norm() > 0 ? in.normalized() : out.normalized();
        if (in.norm() > 0 && (start + out.normalized()).norm() > 1e-6)
          start = (start + out.normalized()).normalized();
        pl = {sk.origin[j], out, out.normalized(), start, 0, 0.75 / R};
      }
    } else if (!kids.empty() && p >= 0) { // several children: back up the bone into the joint
      const Vec3 in = sk.origin[j] - sk.origin[p];
      if (in.norm() > 0)
        pl = {sk.origin[j], -in, in.normalized(), in.normalized(), 0, 0.6 / R};
    } else if (!kids.empty()) { // a root: toward its trunk, the child with the largest subtree (ties averaged)
      int most = 0;
      for (int c : kids)
        most = std::max(most, sk.subtree[c]);
      Vec3 step = Vec3::Zero();
      int tied = 0;
      for (int c : kids)
        if (sk.subtree[c] == most) {
          step += sk.origin[c] - sk.origin[j];
          ++tied;
        }
      step /= tied;
      if (step.norm() > 0)
        pl = {sk.origin[j], step, step.normalized(), step.normalized(), 0, 0.7 / R};
    } else if (p >= 0) {
      // A leaf: at the joint if the limb goes on past it by half a bone,
      // else half-way from the last ring spot on its bone to the joint.
      const Vec3 in = sk.origin[j] - sk.origin[p];
      if (in.norm() > 0) {
        pl = {sk.origin[j], in, in.normalized(), in.normalized(), 0, 0.5};
        const Probe q = probe(j, pl, 0);
        if (local(q) && section_ring(sm, sk.origin[j] + in / 2, in))
          own = q.ring;
        else
          pl = {sk.origin[p], in, in.normalized(), in.normalized(), 1 - 0.5 / R, 1 - 0.2 / R};
      }
    }
    // Extra rings along the bone into the joint.
    if (p >= 0 && R > 1) {
      const Vec3 bone = sk.origin[j] - sk.origin[p];
      for (int i = 1; i < R && bone.norm() > 0; ++i) {
        const double f = static_cast<double>(i) / R;
        std::string why;
        if (auto r = first_local(j, {sk.origin[p], bone, bone.normalized(), bone.normalized(), f, f + 0.5 / R}, why)) {
          r->id = name + suffix(i);
          r->frac = f;
          rings.push_back(std::move(*r));
        } else {
          say("ring '" + name + suffix(i) + "' not made: " + why);
        }
      }
    }
    if (!kids.empty() && p >= 0 && pl.step.norm() > 0) // the joint's own section, for shared trunks below
      if (const Probe q = probe(j, pl, 0); q.ring && q.foreign >= 0)
        shared_start[j] = {pl.point(0), pl.axis(0), q.ring->radius(), bones_inside(*q.ring, pl.point(0), sk)};
    std::string why = "its bone has no length";
    if (!own && pl.step.norm() > 0)
      own = first_local(j, pl, why);
    if (!own && !kids.empty() && pl.step.norm() > 0)
      own = tilted_local(j, pl);
    if (own) {
      own->id = name + suffix(R);
      own->frac = 1;
      rings.push_back(std::move(*own));
    } else {
      ringless[j] = why;
      say("joint '" + name + "' has no ring: " + why);
    }
  }
  // Shared trunks: joints whose sections through the joint enclose each
  // other's bones, and lie near each other's planes (the knuckles of a
  // palm, the hips of a pelvis), get one
  // ring between them, across the trunk at the fork: through their mean
  // position, normal to their mean axis, local to all their bones. It comes
  // before their own rings along each chain.
  {
    std::map<int, int> group; // joint -> representative
    std::function<int(int)> find = [&](int j) { return group[j] == j ? j : group[j] = find(group[j]); };
    for (const auto& [j, st] : shared_start)
      group[j] = j;
    auto related = [&](int a, int b) {
      for (int x = a; x >= 0; x = sk.parent[x])
        if (x == b)
          return true;
      for (int x = b; x >= 0; x = sk.parent[x])
        if (x == a)
          return true;
      return false;
    };
    // a's section holds one of b's bones, and b lies near a's plane.
    auto encloses = [&](int a, int b) {
      const Start& st = shared_start[a];
      return std::abs(st.axis.dot(sk.origin[b] - st.point)) < st.radius / 3 &&
             std::any_of(st.inside.begin(), st.inside.end(), [&](int c) { return incident(c, {b}, sk); });
    };
    for (const auto& [a, sa] : shared_start)
      for (const auto& [b, sb] : shared_start)
        if (a < b && !related(a, b) && encloses(a, b) && encloses(b, a))
          group[find(a)] = find(b);
    std::map<int, std::vector<int>> members;
    for (const auto& [j, st] : shared_start)
      members[find(j)].push_back(j);
    for (auto& [rep, list] : members) {
      if (list.size() < 2)
        continue;
      std::sort(list.begin(), list.end());
      Vec3 point = Vec3::Zero(), axis = Vec3::Zero(), out = Vec3::Zero(), in = Vec3::Zero();
      for (int j : list) {
        point += shared_start[j].point / static_cast<double>(list.size());
        in += (sk.origin[j] - sk.origin[sk.parent[j]]) / static_cast<double>(list.size());
        axis += shared_start[j].axis;
        for (int c : sk.kids[j])
          out += (sk.origin[c] - sk.origin[j]) / static_cast<double>(list.size() * sk.kids[j].size());
      }
      std::string names;
      for (int j : list)
        names += (names.empty() ? "'" : ", '") + joints[j].name + "'";
      if (axis.norm() == 0 || out.norm() == 0)
        continue;
      const Placement pl{point - opt.weights.blend * in, out, axis.normalized(), axis.normalized(), 0, 0.25 / R};
      Probe q = probe_shared(list, pl, 0);
      if (!local(q)) {
        say("no trunk ring for " + names + ": " +
            (q.ring && q.foreign >= 0 ? "its section also encloses bone " + bone_name(q.foreign) : "no section there"));
        continue;
      }
      q.ring->id = joints[list.front()].name + "_trunk";
      q.ring->frac = 0;
      say("ring '" + q.ring->id + "' crosses the trunk that joints " + names + " share");
      rings.push_back(std::move(*q.ring));
    }
  }
  if (rings.empty())
    throw InputError(
        mesh.source, "skeleton",
        "lies outside the mesh: no plane through a joint cuts a loop around it (check the skeleton's space and units)");

  // 2. Keep rings greedily, smallest first. A ring too close to one already
  //    kept (the gap scales with the smaller ring's radius) is moved along
  //    its bone, and dropped only when that does not clear it.
  auto gap = [&](const Ring& a, const Ring& b) { return opt.ring_gap * std::min(a.radius(), b.radius()); };
  // Profiles that share no node keep half the ring gap of the limb they are
  // on, and at most 0.75 % of the diagonal on a thick body.
  auto profile_clearance = [&](double radius) { return std::min(opt.ring_gap / 2 * radius, 0.0075 * diag); };
  auto conflict_with = [&](const Ring& r, const std::vector<int>& among, int self) {
    for (int k : among)
      if (k != self && polyline_distance(r.loop, true, rings[k].loop, true) < gap(r, rings[k]))
        return k;
    return -1;
  };
  // One step (a tenth of its range's bone) further along its bone, if the
  // section there is local.
  // Puts the ring at t of its placement, if the section there is local.
  auto place_at = [&](Ring& r, double t) {
    Probe q = probe_shared(r.own, r.place, t);
    if (!local(q))
      return false;
    r.t = t;
    r.centre = q.ring->centre;
    r.axis = q.ring->axis;
    r.loop = std::move(q.ring->loop);
    r.at = std::move(q.ring->at);
    r.perimeter = q.ring->perimeter;
    return true;
  };
  auto move_on = [&](Ring& r) {
    for (double t = r.t + 0.1; t <= r.place.t_max + 1e-9; t += 0.1)
      if (place_at(r, t))
        return true;
    return false;
  };
  std::vector<int> order(rings.size());
  for (size_t i = 0; i < order.size(); ++i)
    order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return rings[a].perimeter < rings[b].perimeter; });
  std::vector<int> kept;
  for (int i : order) {
    Ring& r = rings[i];
    const double t0 = r.t;
    int conflict = conflict_with(r, kept, i);
    const int first_conflict = conflict;
    double last_close = r.t;
    while (conflict >= 0) {
      last_close = r.t;
      if (!move_on(r))
        break;
      conflict = conflict_with(r, kept, i);
    }
    if (first_conflict >= 0 && conflict < 0) { // the least move that clears it, found by bisection
      double lo = last_close, hi = r.t;
      for (int it = 0; it < 6; ++it) {
        const double mid = (lo + hi) / 2;
        (place_at(r, mid) && conflict_with(r, kept, i) < 0 ? hi : lo) = mid;
      }
      place_at(r, hi);
    }
    if (conflict >= 0) {
      r.replaced_by = conflict;
      const std::string m = "ring '" + r.id + "' dropped: it comes within " + std::to_string(gap(r, rings[conflict])) +
                            " of ring '" + rings[conflict].id + "'" +
                            (r.place.t_max > t0 ? ", moved as far along its bone as it goes" : "");
      say(m);
      if (r.frac == 1)
        ringless[r.joint] = m;
      continue;
    }
    if (first_conflict >= 0)
      say("ring '" + r.id + "' moved along its bone (" + percent(t0) + " to " + percent(r.t) +
          "): it came too close to ring '" + rings[first_conflict].id + "'");
    r.active = true;
    kept.push_back(i);
  }
  auto resolve = [&](int i) {
    for (int guard = 0; i >= 0 && !rings[i].active && guard < static_cast<int>(rings.size()); ++guard)
      i = rings[i].replaced_by;
    return i >= 0 && rings[i].active ? i : -1;
  };

  // 3. Each ring's parent: the ring at the nearest position up the skeleton.
  std::map<int, std::vector<int>> at_joint; // joint -> candidate rings, by frac descending
  for (size_t i = 0; i < rings.size(); ++i)
    for (int j : rings[i].own)
      at_joint[j].push_back(static_cast<int>(i));
  for (auto& [j, list] : at_joint)
    std::sort(list.begin(), list.end(), [&](int a, int b) { return rings[a].frac > rings[b].frac; });
  std::map<int, int> parent_ring;
  for (int i : kept) {
    int found = -1;
    for (int c : at_joint[rings[i].joint])
      if (rings[c].frac < rings[i].frac && (found = resolve(c)) >= 0 && found != i)
        break;
      else
        found = -1;
    for (int a = sk.parent[rings[i].joint]; a >= 0 && found < 0; a = sk.parent[a])
      for (int c : at_joint[a]) {
        const int r = resolve(c);
        if (r >= 0 && r != i) {
          found = r;
          break;
        }
      }
    parent_ring[i] = found;
  }
  for (int i : kept) { // no cycles through replacements
    int p = parent_ring[i];
    for (size_t steps = 0; p >= 0 && steps <= kept.size(); ++steps) {
      if (p == i) {
        parent_ring[i] = -1;
        break;
      }
      p = parent_ring[p];
    }
  }

  // 4. Nodes at consistent angles: node 0's direction is carried from each
  //    ring's parent ring; a ring with none starts from its chain root's
  //    local X axis.
  std::vector<int> by_depth = kept;
  auto depth = [&](int i) {
    int d = 0;
    for (int p = parent_ring[i]; p >= 0 && d <= static_cast<int>(kept.size()); p = parent_ring[p])
      ++d;
    return d;
  };
  std::stable_sort(by_depth.begin(), by_depth.end(), [&](int a, int b) { return depth(a) < depth(b); });
  for (int i : by_depth) {
    Ring& r = rings[i];
    Vec3 ref = Vec3::Zero();
    if (parent_ring[i] >= 0)
      ref = rings[parent_ring[i]].ref - rings[parent_ring[i]].ref.dot(r.axis) * r.axis;
    if (ref.norm() < 0.3) {
      int root = r.joint;
      while (sk.parent[root] >= 0 && sk.kids[sk.parent[root]].size() == 1)
        root = sk.parent[root];
      ref = sk.rotation[root].col(0);
      ref -= ref.dot(r.axis) * r.axis;
      if (ref.norm() < 0.3) {
        ref = sk.rotation[root].col(2);
        ref -= ref.dot(r.axis) * r.axis;
      }
    }
    r.ref = ref.norm() > 1e-9 ? Vec3(ref.normalized()) : plane_basis(r.axis)[0];
    if (!place_nodes(r, N, opt.first_angle_deg))
      say("ring '" + r.id + "': nodes spread by arc length (the section is not star-shaped about its centre)");
  }

  // 5. Build, embed, and on a failure move or drop what failed; repeat.
  std::set<int> dropped;
  std::map<int, int> join_attempt; // 2 * child ring + slot -> 0: new node on parent, 1: parent's nearest node, 2: none
  std::map<int, std::string> join_failure; // child ring -> why its last join was given up
  for (int attempt = 0;; ++attempt) {
    Rig rig;
    rig.coverage = opt.coverage;
    rig.has_skeleton = true;
    rig.joints = joints;
    // profile -> (kind: a arc, l longitudinal, j join; ring, or 2 * child ring + slot for a join)
    std::map<std::string, std::pair<char, int>> owner;
    std::map<std::string, double> scale; // profile -> the radius of the limb it is on
    std::vector<int> active;
    for (int i : kept)
      if (!dropped.count(i))
        active.push_back(i);
    auto effective_parent = [&](int i) {
      int p = parent_ring[i];
      while (p >= 0 && dropped.count(p))
        p = parent_ring[p];
      return p;
    };
    std::map<int, std::vector<int>> children;
    for (int i : active)
      if (effective_parent(i) >= 0)
        children[effective_parent(i)].push_back(i);
    // Series: a parent with one child ring, or the child that carries its
    // trunk on (the one ring ahead along its axis and at least 0.6 its size), gets
    // N profiles along the chain; every other child joins its parent by
    // profiles that leave it on the two sides of the fork (the back and the
    // palm of a hand, the front and back of a hip or shoulder).
    std::map<int, int> series_child;
    std::map<int, Vec3> across; // parent -> the direction the join nodes face
    for (auto& [p, list] : children) {
      const Ring& pr = rings[p];
      if (list.size() == 1) {
        series_child[p] = list[0];
        continue;
      }
      std::vector<int> ahead;
      for (int c : list) {
        const Vec3 d = rings[c].centre - pr.centre;
        if (d.norm() > 0 && rings[c].perimeter >= 0.6 * pr.perimeter &&
            d.normalized().dot(pr.axis) > std::cos(35.0 * std::numbers::pi / 180.0))
          ahead.push_back(c);
      }
      if (ahead.size() == 1) // several peers ahead (the fingers of a palm) all join
        series_child[p] = ahead[0];
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      for (int c : list) {
        Vec3 d = rings[c].centre - pr.centre;
        d -= d.dot(pr.axis) * pr.axis;
        cov += d * d.transpose();
      }
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
      Vec3 w = pr.axis.cross(es.eigenvectors().col(2));
      if (w.norm() < 1e-9)
        w = pr.ref;
      w.normalize();
      if (w.dot(pr.ref) < 0 || (w.dot(pr.ref) == 0 && w.dot(pr.axis.cross(pr.ref)) < 0))
        w = -w; // a sign from the skeleton, not from the eigen solver
      across[p] = w;
    }
    // Extra nodes on parents where joins land.
    std::map<int, std::vector<std::pair<double, std::string>>> extra; // ring -> (arc pos, node id)
    struct Join {
      int child, parent, slot, child_node;
      std::string target;
      Vec3 to;
      std::optional<std::vector<Vec3>> path;
    };
    std::vector<Join> joins;
    std::vector<int> unjoined;
    for (int c : active) {
      const int p = effective_parent(c);
      if (p < 0 || (series_child.count(p) && series_child[p] == c))
        continue;
      const Ring &pr = rings[p], &cr = rings[c];
      std::vector<int> nodes_used;
      bool any = false;
      for (int slot = 0; slot < 2; ++slot) {
        const int mode = join_attempt[2 * c + slot];
        // The child's node furthest to this slot's side.
        int best_k = 0;
        for (int k = 1; k < N; ++k) {
          const double side = slot == 0 ? 1 : -1;
          if (side * across[p].dot(loop_point(cr, cr.base_nodes[k]) - cr.centre) >
              side * across[p].dot(loop_point(cr, cr.base_nodes[best_k]) - cr.centre))
            best_k = k;
        }
        if (std::find(nodes_used.begin(), nodes_used.end(), best_k) != nodes_used.end())
          continue;
        nodes_used.push_back(best_k);
        if (mode >= 2)
          continue;
        any = true;
        const Vec3 from = loop_point(cr, cr.base_nodes[best_k]);
        double best_s = closest_on_loop(pr, from);
        Join jn{c, p, slot, best_k, "", Vec3::Zero(), std::nullopt};
        // A landing next to one of the parent's nodes (or another join's)
        // lands on that node.
        int near_node = -1;
        std::string near_extra;
        for (int k = 0; k < N; ++k)
          if ((loop_point(pr, pr.base_nodes[k]) - loop_point(pr, best_s)).norm() < opt.ring_gap * pr.radius())
            near_node = k;
        for (const auto& [s_extra, id] : extra[p])
          if (near_node < 0 && (loop_point(pr, s_extra) - loop_point(pr, best_s)).norm() < opt.ring_gap * pr.radius())
            near_extra = id, best_s = s_extra;
        if (mode == 0 && !near_extra.empty()) {
          jn.target = near_extra;
          jn.to = loop_point(pr, best_s);
        } else if (mode == 0 && near_node < 0) {
          jn.to = loop_point(pr, best_s);
        } else {
          int nk = mode == 0 ? near_node : 0;
          for (int k = 1; k < N && mode > 0; ++k)
            if ((loop_point(pr, pr.base_nodes[k]) - from).norm() < (loop_point(pr, pr.base_nodes[nk]) - from).norm())
              nk = k;
          jn.target = pr.id + "_" + std::to_string(nk);
          jn.to = loop_point(pr, pr.base_nodes[nk]);
        }
        // The plane holds the outward direction at the target, so the join
        // meets the parent ring square rather than glancing along it.
        Vec3 out = jn.to - pr.centre;
        out -= out.dot(pr.axis) * pr.axis;
        // Of the candidate paths, take the first that meets the ring at a
        // clear angle (at least 35 degrees); stop it where it first meets the ring.
        const double min_sin = std::sin(35.0 * std::numbers::pi / 180.0);
        double best_sin = -1;
        // The first plane tried also holds the child's axis at its node, so
        // the join leaves the child ring square too.
        for (auto& path : surface_paths(sm, from, jn.to,
                                        {from - cr.radius() * cr.axis, jn.to + out, (pr.centre + cr.centre) / 2}, tol)) {
          double s_hit = -1;
          size_t cut = path.size() - 1;
          for (size_t i = 0; i + 1 < path.size() && s_hit < 0; ++i) {
            Vec3 hit = Vec3::Zero();
            for (size_t q = 0; q < pr.loop.size(); ++q)
              if (segment_distance(path[i], path[i + 1], pr.loop[q], pr.loop[(q + 1) % pr.loop.size()], &hit) < tol) {
                s_hit = closest_on_loop(pr, hit);
                cut = i;
                break;
              }
          }
          if (s_hit < 0)
            continue;
          if (!jn.target.empty() && (loop_point(pr, s_hit) - jn.to).norm() > tol)
            continue; // it would cross the ring before reaching its node
          const Vec3 end = jn.target.empty() ? loop_point(pr, s_hit) : jn.to;
          path.resize(cut + 1);
          path.push_back(end);
          // It must keep clear of every other ring, its own child ring
          // included, away from its two ends.
          bool clear = true;
          for (int o : active) {
            const double c = profile_clearance(std::min(cr.radius(), rings[o].radius()));
            std::vector<Vec3> middle;
            for (const Vec3& q : path)
              if ((q - from).norm() > 2 * c && (q - end).norm() > 2 * c)
                middle.push_back(q);
            if (middle.size() >= 2 && polyline_distance(middle, false, rings[o].loop, true) < c) {
              clear = false;
              break;
            }
          }
          if (!clear)
            continue;
          // The directions over the first and last half edge length,
          // against the rings' tangents: the join must leave its ring and
          // meet the other at a clear angle.
          const double sine = std::min(crossing_sine(path, pr, s_hit, true, h),
                                       crossing_sine(path, cr, cr.base_nodes[jn.child_node], false, h));
          if (sine > best_sin) {
            best_sin = sine;
            jn.path = path;
            jn.to = end;
            if (jn.target.empty())
              best_s = s_hit;
          }
          if (sine >= min_sin)
            break;
        }
        if (jn.target.empty()) {
          jn.target = pr.id + "_" + cr.id + (slot == 0 ? "_a" : "_b"); // named by the child: the same on every mesh
          extra[p].emplace_back(best_s, jn.target);
        }
        joins.push_back(jn);
      }
      if (!any)
        unjoined.push_back(c);
    }
    // Nodes and arcs of every ring.
    for (int i : active) {
      const Ring& r = rings[i];
      std::vector<std::pair<double, std::string>> nodes;
      for (int k = 0; k < N; ++k)
        nodes.emplace_back(r.base_nodes[k], r.id + "_" + std::to_string(k));
      for (const auto& e : extra[i])
        nodes.push_back(e);
      std::sort(nodes.begin(), nodes.end());
      for (const auto& [s, id] : nodes)
        rig.nodes.push_back({id, loop_point(r, s)});
      for (size_t k = 0; k < nodes.size(); ++k) {
        const auto& a = nodes[k];
        const auto& b = nodes[(k + 1) % nodes.size()];
        Profile pr;
        pr.id = r.id + "_arc" + std::to_string(k);
        pr.from = a.second;
        pr.to = b.second;
        pr.curve.points = loop_between(r, a.first, b.first);
        owner[pr.id] = {'a', i};
        scale[pr.id] = r.radius();
        rig.profiles.push_back(std::move(pr));
      }
    }
    std::string failure; // the first reason this net cannot be used
    // Along each chain.
    for (const auto& [p, c] : series_child) {
      const Vec3 mid = (rings[p].centre + rings[c].centre) / 2;
      for (int k = 0; k < N; ++k) {
        const Vec3 a = loop_point(rings[p], rings[p].base_nodes[k]), b = loop_point(rings[c], rings[c].base_nodes[k]);
        Profile pr;
        pr.id = rings[p].id + "-" + rings[c].id + "_" + std::to_string(k);
        pr.from = rings[p].id + "_" + std::to_string(k);
        pr.to = rings[c].id + "_" + std::to_string(k);
        // The first path that meets both rings at a clear angle (at least
        // 35 degrees), or the squarest.
        std::optional<std::vector<Vec3>> path;
        double best_sine = -1;
        for (auto& candidate : surface_paths(sm, a, b, {mid}, tol)) {
          const double sine = std::min(crossing_sine(candidate, rings[p], rings[p].base_nodes[k], false, h),
                                       crossing_sine(candidate, rings[c], rings[c].base_nodes[k], true, h));
          if (sine > best_sine) {
            best_sine = sine;
            path = std::move(candidate);
          }
          if (best_sine >= std::sin(35.0 * std::numbers::pi / 180.0))
            break;
        }
        if (!path && failure.empty())
          failure = "no plane section joins the ends of profile '" + pr.id + "' along the surface";
        pr.curve.points = path ? *path : std::vector<Vec3>{a, b};
        owner[pr.id] = {'l', c};
        scale[pr.id] = std::min(rings[p].radius(), rings[c].radius());
        rig.profiles.push_back(std::move(pr));
      }
    }
    for (const Join& jn : joins) {
      Profile pr;
      pr.id = rings[jn.child].id + "-" + rings[jn.parent].id + (jn.slot == 0 ? "_join" : "_join1");
      pr.from = rings[jn.child].id + "_" + std::to_string(jn.child_node);
      pr.to = jn.target;
      if (!jn.path && failure.empty())
        failure = "no plane section joins the ends of profile '" + pr.id + "' along the surface";
      pr.curve.points =
          jn.path ? *jn.path
                  : std::vector<Vec3>{loop_point(rings[jn.child], rings[jn.child].base_nodes[jn.child_node]), jn.to};
      owner[pr.id] = {'j', 2 * jn.child + jn.slot};
      scale[pr.id] = std::min(rings[jn.child].radius(), rings[jn.parent].radius());
      rig.profiles.push_back(std::move(pr));
    }
    for (const Node& n : rig.nodes) {
      for (const auto& [j, w] : auto_weights(joints, n.position, opt.weights))
        rig.weights[n.id][joints[j].name] = w;
    }
    // Check it: profiles that share no node keep a clearance that scales
    // with the limbs they are on, and the net embeds here.
    if (failure.empty()) {
      auto clearance = [&](const Profile& a, const Profile& b) {
        return profile_clearance(std::min(scale[a.id], scale[b.id]));
      };
      std::map<std::string, Vec3> node_at;
      for (const Node& n : rig.nodes)
        node_at[n.id] = n.position;
      std::vector<Eigen::AlignedBox3d> box(rig.profiles.size());
      for (size_t a = 0; a < rig.profiles.size(); ++a)
        for (const auto& q : rig.profiles[a].curve.points)
          box[a].extend(q);
      // The part of a profile that keeps away from the given nodes.
      auto away_from = [&](const std::vector<Vec3>& pts, const std::vector<Vec3>& shared, double c) {
        std::vector<Vec3> out;
        for (const Vec3& q : pts)
          if (std::all_of(shared.begin(), shared.end(), [&](const Vec3& n) { return (q - n).norm() > 2 * c; }))
            out.push_back(q);
        return out;
      };
      for (size_t a = 0; a < rig.profiles.size() && failure.empty(); ++a)
        for (size_t b = a + 1; b < rig.profiles.size() && failure.empty(); ++b) {
          const Profile &pa = rig.profiles[a], &pb = rig.profiles[b];
          const auto oa = owner[pa.id], ob = owner[pb.id];
          if (oa.first == 'a' && ob.first == 'a' && oa.second == ob.second)
            continue; // pieces of one plane section: they cannot cross
          const double c = clearance(pa, pb);
          if (box[a].exteriorDistance(box[b]) >= c)
            continue;
          std::vector<Vec3> shared;
          for (const std::string& n : {pa.from, pa.to})
            if (n == pb.from || n == pb.to)
              shared.push_back(node_at[n]);
          const auto qa = away_from(pa.curve.points, shared, c), qb = away_from(pb.curve.points, shared, c);
          if (qa.size() < 2 || qb.size() < 2)
            continue;
          if (polyline_distance(qa, false, qb, false) < c)
            failure = "profiles '" + pa.id + "' and '" + pb.id + "' come closer than " + std::to_string(c);
        }
    }
    // Profiles that leave one node must part at a clear angle.
    if (failure.empty()) {
      std::map<std::string, std::vector<std::pair<Vec3, std::string>>> leaving;
      auto direction = [&](const std::vector<Vec3>& pts, bool from_start) {
        const Vec3 o = from_start ? pts.front() : pts.back();
        for (size_t i = 1; i < pts.size(); ++i) {
          const Vec3& q = from_start ? pts[i] : pts[pts.size() - 1 - i];
          if ((q - o).norm() >= 0.5 * h || i + 1 == pts.size())
            return Vec3((q - o).normalized());
        }
        return Vec3(Vec3::Zero());
      };
      for (const Profile& pr : rig.profiles) {
        leaving[pr.from].emplace_back(direction(pr.curve.points, true), pr.id);
        leaving[pr.to].emplace_back(direction(pr.curve.points, false), pr.id);
      }
      const double min_cos = std::cos(20.0 * std::numbers::pi / 180.0);
      for (const auto& [node, dirs] : leaving)
        for (size_t a = 0; a < dirs.size() && failure.empty(); ++a)
          for (size_t b = a + 1; b < dirs.size() && failure.empty(); ++b)
            if (dirs[a].first.dot(dirs[b].first) > min_cos)
              failure = "profiles '" + dirs[a].second + "' and '" + dirs[b].second + "' leave node '" + node +
                        "' less than 20 degrees apart";
    }
    try {
      const Embedding e = failure.empty() ? embed(mesh, rig) : Embedding(nullptr);
      if (failure.empty() && e.report().ok) {
        result.rig = std::move(rig);
        result.rings = static_cast<int>(active.size());
        result.joins = static_cast<int>(joins.size());
        result.unjoined = static_cast<int>(unjoined.size());
        result.net_components = e.report().components;
        for (int c : unjoined)
          say("ring '" + rings[c].id + "' is not joined to ring '" + rings[effective_parent(c)].id +
              "': " + join_failure[c]);
        if (!unjoined.empty())
          say(std::to_string(unjoined.size()) + " chain(s) could not be joined to their parent ring; the net has " +
              std::to_string(result.net_components) + " components, and the expected region count accounts for them");
        std::set<int> ringed;
        for (int i : active)
          if (rings[i].frac > 0) // a trunk's ring is not a joint's own
            ringed.insert(rings[i].joint);
        for (int j = 0; j < nj; ++j)
          if (!ringed.count(j))
            result.ringless.emplace_back(joints[j].name, ringless.count(j) ? ringless[j] : "its ring was dropped");
        // Say so in the rig itself.
        auto quote = [](const std::string& t) {
          std::string q = "\"";
          for (char ch : t) {
            if (ch == '"' || ch == '\\')
              q += '\\';
            if (static_cast<unsigned char>(ch) >= 0x20)
              q += ch;
          }
          return q + "\"";
        };
        std::string ext = "{\"rings\": [";
        for (size_t k = 0; k < active.size(); ++k)
          ext += (k ? ", " : "") + quote(rings[active[k]].id);
        ext += "], \"unjoined\": [";
        for (size_t k = 0; k < unjoined.size(); ++k)
          ext += (k ? ", " : "") + quote(rings[unjoined[k]].id);
        ext += "], \"ringless\": {";
        for (size_t k = 0; k < result.ringless.size(); ++k)
          ext += (k ? ", " : "") + quote(result.ringless[k].first) + ": " + quote(result.ringless[k].second);
        ext += "}, \"net_components\": " + std::to_string(result.net_components) + ", \"notes\": [";
        for (size_t k = 0; k < result.messages.size(); ++k)
          ext += (k ? ", " : "") + quote(result.messages[k]);
        ext += "]}";
        result.rig.extensions["x_starter"] = ext;
        return result;
      }
      if (failure.empty())
        failure = e.report().problems.empty() ? "not ok" : e.report().problems[0];
    } catch (const EmbedError& e) {
      failure = e.what();
    }
    if (attempt > 6 * static_cast<int>(rings.size()) + 8)
      throw EmbedError("starter: could not make a net that embeds: " + failure);
    // Find what to give up, of what the failure names: a join first, then
    // the child ring of a longitudinal, then the ring of an arc; a trunk's
    // ring last of all.
    int culprit = -1, best_rank = 4;
    char kind = 0;
    for (const std::string& id : quoted(failure)) {
      auto it = owner.find(id);
      if (it == owner.end())
        continue;
      const auto [k, who] = it->second;
      const int rank = k == 'j' ? 0 : rings[who].frac == 0 ? 3 : k == 'l' ? 1 : 2;
      if (rank < best_rank) {
        best_rank = rank;
        kind = k;
        culprit = who;
      }
    }
    if (culprit < 0) {
      // No profile named (for example a wrong region count): drop the largest ring.
      for (int i : active)
        if (culprit < 0 || rings[i].perimeter > rings[culprit].perimeter)
          culprit = i;
      kind = 'a';
    }
    if (kind == 'j') {
      const int m = ++join_attempt[culprit];
      const std::string& child = rings[culprit / 2].id;
      say("join " + std::string(culprit % 2 ? "1 " : "") + "of ring '" + child + "' " +
          (m >= 2 ? "abandoned" : "moved to an existing node") + ": " + failure);
      if (m >= 2)
        join_failure[culprit / 2] = failure;
      continue;
    }
    Ring& r = rings[culprit];
    std::vector<int> others;
    for (int i : active)
      if (i != culprit)
        others.push_back(i);
    const double t0 = r.t;
    const Ring before = r;
    bool moved = false;
    while (move_on(r))
      if (conflict_with(r, others, culprit) < 0) {
        moved = true;
        break;
      }
    if (moved) {
      place_nodes(r, N, opt.first_angle_deg);
      say("ring '" + r.id + "' moved along its bone (" + percent(t0) + " to " + percent(r.t) + "): " + failure);
      continue;
    }
    r = before;
    dropped.insert(culprit);
    const std::string m = "ring '" + r.id + "' dropped: " + failure;
    say(m);
    if (r.frac == 1)
      ringless[r.joint] = m;
    if (dropped.size() == kept.size())
      throw EmbedError("starter: could not make a net that embeds: " + failure);
  }
}

} // namespace curvenet
