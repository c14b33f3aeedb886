// The starter's rings (docs/starter.md, steps 1 to 4): candidate rings
// local to each joint's bone, rings across shared trunks, the clearance
// between rings, and each ring's parent and nodes.

#include "core/predicates.hpp"
#include "starter/stages.hpp"

#include <algorithm>
#include <iomanip>
#include <sstream>
#include <cmath>
#include <limits>

namespace curvenet::detail {

Skeleton::Skeleton(const std::vector<Joint>& joints) {
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

StarterContext::StarterContext(const SurfaceMesh& m, const std::vector<Joint>& j,
                               std::function<void(const std::string&)> message)
    : mesh(m), joints(j), sk(j), sm(m), diag(m.bbox_diagonal()), h(m.mean_edge_length()), tol(1e-6 * m.bbox_diagonal()),
      say(std::move(message)) {
  std::vector<std::pair<int, int>> pairs;
  for (int f = 0; f < m.num_faces(); ++f) {
    const auto c = m.face(f);
    for (size_t k = 0; k < c.size(); ++k) {
      pairs.emplace_back(c[k], c[(k + 1) % c.size()]);
      pairs.emplace_back(c[(k + 1) % c.size()], c[k]);
    }
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  next_offset.assign(static_cast<size_t>(m.num_vertices()) + 1, 0);
  for (const auto& [a, b] : pairs)
    ++next_offset[a + 1];
  for (int v = 0; v < m.num_vertices(); ++v)
    next_offset[v + 1] += next_offset[v];
  next_vertex.reserve(pairs.size());
  for (const auto& [a, b] : pairs)
    next_vertex.push_back(b);
}

std::string StarterContext::bone_name(int c) const {
  return "'" + joints[sk.parent[c]].name + "'-'" + joints[c].name + "'";
}

RingOptions RingOptions::from(const StarterOptions& o) {
  RingOptions r;
  r.nodes_per_ring = o.nodes_per_ring;
  r.rings_per_bone = o.rings_per_bone;
  r.first_angle_deg = o.first_angle_deg;
  r.ring_gap = o.ring_gap;
  r.trunk_setback = o.weights.blend;
  r.deforming = o.deforming;
  return r;
}

double RingOptions::gap(const Ring& a, const Ring& b) const {
  return ring_gap * std::min(a.radius(), b.radius());
}

NetOptions NetOptions::from(const StarterOptions& o) {
  NetOptions n;
  n.nodes_per_ring = o.nodes_per_ring;
  n.middle_nodes = o.middle_nodes;
  n.ring_gap = o.ring_gap;
  n.coverage = o.coverage;
  return n;
}

double NetOptions::profile_clearance(double diagonal, double radius) const {
  return std::min(ring_gap / 2 * radius, 0.0075 * diagonal);
}

NodeWeightOptions NodeWeightOptions::from(const StarterOptions& o) {
  NodeWeightOptions w;
  w.rule = o.weights;
  w.skin = o.skin;
  w.deforming = o.deforming;
  return w;
}

std::string percent(double t) {
  return std::to_string(static_cast<int>(std::lround(100 * t))) + "%";
}

// ---- loops --------------------------------------------------------------

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

double closest_on_loop(const Ring& r, const Vec3& p, double* distance) {
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

// ---- stage 1: rings -----------------------------------------------------

namespace {

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

struct Probe {
  std::optional<Ring> ring;
  int foreign = -1;
};

Probe probe(const StarterContext& c, const std::vector<int>& own, const Placement& pl, double t) {
  Probe q;
  q.ring = section_ring(c.sm, pl.point(t), pl.axis(t));
  if (q.ring) {
    q.foreign = foreign_bone_inside(*q.ring, pl.point(t), own, c.sk);
    q.ring->place = pl;
    q.ring->t = t;
    q.ring->joint = own.front();
    q.ring->own = own;
  }
  return q;
}

bool is_local(const StarterContext& /*c*/, const RingOptions& ro, const Probe& q) {
  return q.ring && q.foreign < 0 && static_cast<int>(q.ring->loop.size()) >= ro.nodes_per_ring;
}

/// The first local ring in the placement's range, moved on past where the
/// section first becomes local; `why` says why there is none.
std::optional<Ring> first_local(const StarterContext& c, const RingOptions& ro, int j, const Placement& pl,
                                std::string& why, std::vector<int> own = {}) {
  if (own.empty())
    own = {j};
  constexpr int steps = 10;
  const bool range = pl.t_max > pl.t_min;
  double prev = pl.t_min;
  int foreign = -1, small = 0;
  for (int k = 0; k <= (range ? steps : 0); ++k) {
    const double t = pl.t_min + (pl.t_max - pl.t_min) * k / steps;
    const Probe q = probe(c, own, pl, t);
    if (is_local(c, ro, q)) {
      if (k == 0)
        return q.ring;
      double lo = prev, hi = t;
      for (int it = 0; it < 6; ++it) {
        const double mid = (lo + hi) / 2;
        (is_local(c, ro, probe(c, own, pl, mid)) ? hi : lo) = mid;
      }
      // Clear of a fork by a third of the radius, clear of the surface's
      // rounded end (no section before) by a whole radius; by at most a
      // quarter of the bone.
      const double len = pl.step.norm();
      const double clear = std::min(0.25, (foreign >= 0 ? 1.0 / 3 : 1.0) * q.ring->radius() / len);
      // The furthest of a few steps back from there that is local.
      for (const double back : {0.0, 0.25, 0.5, 0.75})
        if (Probe m = probe(c, own, pl, std::min(pl.t_max, hi + (1 - back) * clear)); is_local(c, ro, m))
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
                           " also encloses bone " + c.bone_name(foreign) + " (a shared trunk)"
        : small ? "its section crosses fewer mesh edges than " + std::to_string(ro.nodes_per_ring) + " nodes need"
                : "no section there winds around its bone (outside the mesh)";
  return std::nullopt;
}

/// Where no section across the bone is local (a thumb's metacarpal in the
/// ball of the thumb), the narrowest local section through the bone's
/// middle part whose plane is tilted from the bone by up to 45 degrees.
std::optional<Ring> tilted_local(const StarterContext& c, const RingOptions& ro, int j, const Placement& pl) {
  std::optional<Ring> best;
  const auto [u, v] = plane_basis(pl.along);
  for (int it = 3; it <= 9; ++it)
    for (const double tilt : {15.0, 30.0, 45.0})
      for (int az = 0; az < 8; ++az) {
        const double a = az * std::numbers::pi / 4, b = tilt * std::numbers::pi / 180;
        const Vec3 axis = std::cos(b) * pl.along + std::sin(b) * (std::cos(a) * u + std::sin(a) * v);
        Probe q = probe(c, {j}, {pl.base + pl.step * (it / 10.0), Vec3::Zero(), axis, axis, 0, 0}, 0);
        if (is_local(c, ro, q) && (!best || q.ring->perimeter < best->perimeter))
          best = std::move(q.ring);
      }
  return best;
}

/// Where joint j's own ring may sit (docs/starter.md, step 1), or a
/// placement with no step when its bone has no length. A leaf whose limb
/// goes on past it gets its ring at the joint at once (`own`).
Placement joint_placement(const StarterContext& c, const RingOptions& ro, int j, std::optional<Ring>& own) {
  const Skeleton& sk = c.sk;
  const int p = sk.parent[j], R = ro.rings_per_bone;
  const auto& kids = sk.kids[j];
  Placement pl;
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
    for (int k : kids)
      most = std::max(most, sk.subtree[k]);
    Vec3 step = Vec3::Zero();
    int tied = 0;
    for (int k : kids)
      if (sk.subtree[k] == most) {
        step += sk.origin[k] - sk.origin[j];
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
      const Probe q = probe(c, {j}, pl, 0);
      if (is_local(c, ro, q) && section_ring(c.sm, sk.origin[j] + in / 2, in))
        own = q.ring;
      else
        pl = {sk.origin[p], in, in.normalized(), in.normalized(), 1 - 0.5 / R, 1 - 0.2 / R};
    }
  }
  return pl;
}

constexpr double kSmallestCap = 0.01; ///< of the diagonal: the smallest ring a cap ring goes beyond

/// A ring across the cap beyond ring `own` of leaf joint j (the part of
/// the surface past its plane, reached from it without crossing back: a
/// foot past the shin's ring, a head past the neck's), half-way from the
/// joint to the cap's furthest point and square to that line; none when the
/// ring is under 1 % of the diagonal across, the cap is short, or no local
/// section crosses it.
std::optional<Ring> cap_ring(const StarterContext& c, const RingOptions& ro, int j, const Ring& own) {
  if (own.radius() < kSmallestCap * c.diag) // an ear's tip: too small to be worth a ring, and finer than a coarse LOD
    return std::nullopt;
  const auto& P = c.mesh.positions;
  const int nv = c.mesh.num_vertices();
  const Vec3& n = own.axis; // along the bone, out of the body
  auto beyond = [&](int v) { return (P[v] - own.centre).dot(n) > 0; };
  Eigen::AlignedBox3d box;
  for (const Vec3& q : own.loop)
    box.extend(q);
  box.extend(box.min() - Vec3::Constant(2 * c.h)).extend(box.max() + Vec3::Constant(2 * c.h));
  std::vector<char> seen(nv, 0);
  std::vector<int> stack;
  for (int v = 0; v < nv; ++v)
    if (beyond(v) && box.contains(P[v]) && (P[v] - own.centre).dot(n) < 2 * c.h) {
      double d = 0;
      closest_on_loop(own, P[v], &d);
      if (d < 2 * c.h) {
        seen[v] = 1;
        stack.push_back(v);
      }
    }
  // And the far ends of the edges the ring crosses: a tail's tip is a cone
  // of long thin faces, whose vertices beyond the ring lie many mean edge
  // lengths from it.
  for (int v = 0; v < nv; ++v) {
    if (seen[v] || !beyond(v))
      continue;
    for (int k = c.next_offset[v]; k < c.next_offset[v + 1] && !seen[v]; ++k) {
      const int u = c.next_vertex[k];
      const double du = (P[u] - own.centre).dot(n), dv = (P[v] - own.centre).dot(n);
      if (!(du <= 0))
        continue;
      const Vec3 x = P[u] + (du / (du - dv)) * (P[v] - P[u]); // where the edge crosses the ring's plane
      double d = 0;
      closest_on_loop(own, x, &d);
      if (d <= c.tol) {
        seen[v] = 1;
        stack.push_back(v);
      }
    }
  }
  const Vec3& o = c.sk.origin[j];
  int far = -1;
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    if (far < 0 || (P[v] - o).norm() > (P[far] - o).norm())
      far = v;
    for (int k = c.next_offset[v]; k < c.next_offset[v + 1]; ++k)
      if (const int u = c.next_vertex[k]; !seen[u] && beyond(u)) {
        seen[u] = 1;
        stack.push_back(u);
      }
  }
  if (far < 0)
    return std::nullopt;
  const Vec3 step = P[far] - o;
  if (step.norm() < 2 * own.radius()) // too short for a ring of its own
    return std::nullopt;
  std::string why;
  return first_local(c, ro, j, {o, step, step.normalized(), step.normalized(), 0.4, 0.7}, why);
}

} // namespace

RingsResult candidate_rings(const StarterContext& c, const RingOptions& ro) {
  const Skeleton& sk = c.sk;
  const int R = ro.rings_per_bone, nj = static_cast<int>(c.joints.size());
  auto suffix = [&](int i) { // appended, not "_" + ...: GCC 12 warns falsely on that (its bug 105329)
    std::string s;
    if (R > 1)
      s.append("_").append(std::to_string(i));
    return s;
  };
  RingsResult out;
  for (int j = 0; j < nj; ++j) {
    const int p = sk.parent[j];
    const std::string& name = c.joints[j].name;
    std::optional<Ring> own;
    const Placement pl = joint_placement(c, ro, j, own);
    // Extra rings along the bone into the joint, at most part of the way to
    // the next ring spot (1 / rings_per_bone), so rings stay in order.
    if (p >= 0 && R > 1) {
      const Vec3 bone = sk.origin[j] - sk.origin[p];
      for (int i = 1; i < R && bone.norm() > 0; ++i) {
        const double f = static_cast<double>(i) / R;
        std::string why;
        if (auto r = first_local(c, ro, j, {sk.origin[p], bone, bone.normalized(), bone.normalized(), f, f + 0.5 / R},
                                 why)) {
          r->id = name + suffix(i);
          r->frac = f;
          out.rings.push_back(std::move(*r));
        } else {
          c.say("ring '" + name + suffix(i) + "' not made: " + why);
        }
      }
    }
    if (!sk.kids[j].empty() && p >= 0 && pl.step.norm() > 0) // the joint's own section, for shared trunks
      if (const Probe q = probe(c, {j}, pl, 0); q.ring && q.foreign >= 0)
        out.shared_start[j] = {pl.point(0), pl.axis(0), q.ring->radius(), bones_inside(*q.ring, pl.point(0), sk)};
    std::string why = "its bone has no length";
    if (!own && pl.step.norm() > 0)
      own = first_local(c, ro, j, pl, why);
    if (!own && !sk.kids[j].empty() && pl.step.norm() > 0)
      own = tilted_local(c, ro, j, pl);
    // A leaf whose siblings' bones start inside it (a head, and the ears
    // that hang from the neck's last joint): its ring may enclose them
    // where they leave the joint they share.
    if (!own && sk.kids[j].empty() && p >= 0 && pl.step.norm() > 0) {
      std::string shared_why;
      own = first_local(c, ro, j, pl, shared_why, {j, p});
    }
    // A weighted joint that ends its chain (a foot, a head) gets a second
    // ring out in what lies beyond its own (step 8 gives it that joint's
    // weight alone).
    if (own && p >= 0 && sk.kids[j].empty() && ro.deforming.count(name))
      if (auto end = cap_ring(c, ro, j, *own)) {
        end->id = name + "_end";
        end->frac = 2;
        out.rings.push_back(std::move(*end));
      }
    if (own) {
      own->id = name + suffix(R);
      own->frac = 1;
      out.rings.push_back(std::move(*own));
    } else {
      out.ringless[j] = why;
      c.say("joint '" + name + "' has no ring: " + why);
    }
  }
  return out;
}

bool place_ring_at(const StarterContext& c, const RingOptions& ro, Ring& r, double t) {
  Probe q = probe(c, r.own, r.place, t);
  if (!is_local(c, ro, q))
    return false;
  r.t = t;
  r.centre = q.ring->centre;
  r.axis = q.ring->axis;
  r.loop = std::move(q.ring->loop);
  r.at = std::move(q.ring->at);
  r.perimeter = q.ring->perimeter;
  return true;
}

// ---- stage 2: trunks ------------------------------------------------------

void trunk_rings(const StarterContext& c, const RingOptions& ro, const std::map<int, SharedStart>& shared_start,
                 std::vector<Ring>& rings) {
  // Joints whose sections through the joint enclose each other's bones, and
  // lie near each other's planes (the knuckles of a palm, the hips of a
  // pelvis), get one ring between them, across the trunk at the fork:
  // through their mean position, normal to their mean axis, local to all
  // their bones. It comes before their own rings along each chain.
  const Skeleton& sk = c.sk;
  const int R = ro.rings_per_bone;
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
    const SharedStart& st = shared_start.at(a);
    return std::abs(st.axis.dot(sk.origin[b] - st.point)) < st.radius / 3 &&
           std::any_of(st.inside.begin(), st.inside.end(), [&](int k) { return incident(k, {b}, sk); });
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
      point += shared_start.at(j).point / static_cast<double>(list.size());
      in += (sk.origin[j] - sk.origin[sk.parent[j]]) / static_cast<double>(list.size());
      axis += shared_start.at(j).axis;
      for (int k : sk.kids[j])
        out += (sk.origin[k] - sk.origin[j]) / static_cast<double>(list.size() * sk.kids[j].size());
    }
    std::string names;
    for (int j : list)
      names += (names.empty() ? "'" : ", '") + c.joints[j].name + "'";
    if (axis.norm() == 0 || out.norm() == 0)
      continue;
    const Placement pl{point - ro.trunk_setback * in, out, axis.normalized(), axis.normalized(), 0, 0.25 / R};
    Probe q = probe(c, list, pl, 0);
    if (!is_local(c, ro, q)) {
      c.say(
          "no trunk ring for " + names + ": " +
          (q.ring && q.foreign >= 0 ? "its section also encloses bone " + c.bone_name(q.foreign) : "no section there"));
      continue;
    }
    q.ring->id = c.joints[list.front()].name + "_trunk";
    q.ring->frac = 0;
    // Joints that fork from one parent whose own ring already crosses the
    // trunk there (the bones of a palm from its wrist) need no other.
    const int common = sk.parent[list.front()];
    if (common >= 0 && std::all_of(list.begin(), list.end(), [&](int j) { return sk.parent[j] == common; })) {
      const auto parents_ring = std::find_if(rings.begin(), rings.end(), [&](const Ring& r) {
        return r.joint == common && r.frac == 1 &&
               polylines_within(r.loop, true, q.ring->loop, true, ro.gap(r, *q.ring));
      });
      if (parents_ring != rings.end()) {
        c.say("no trunk ring for " + names + ": the ring of '" + c.joints[common].name + "' crosses it");
        continue;
      }
    }
    c.say("ring '" + q.ring->id + "' crosses the trunk that joints " + names + " share");
    rings.push_back(std::move(*q.ring));
  }
}

// ---- stage 3: clearance ---------------------------------------------------

int ring_conflict(const StarterContext& /*c*/, const RingOptions& ro, const Ring& r, const std::vector<Ring>& rings,
                  const std::vector<int>& among, int self) {
  for (int k : among)
    if (k != self && polylines_within(r.loop, true, rings[k].loop, true, ro.gap(r, rings[k])))
      return k;
  return -1;
}

bool move_ring_on(const StarterContext& c, const RingOptions& ro, Ring& r) {
  for (double t = r.t + 0.1; t <= r.place.t_max + 1e-9; t += 0.1)
    if (place_ring_at(c, ro, r, t))
      return true;
  return false;
}

std::vector<int> keep_clear_rings(const StarterContext& c, const RingOptions& ro, std::vector<Ring>& rings,
                                  std::map<int, std::string>& ringless) {
  std::vector<int> order(rings.size());
  for (size_t i = 0; i < order.size(); ++i)
    order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return rings[a].perimeter < rings[b].perimeter; });
  std::vector<int> kept;
  for (int i : order) {
    Ring& r = rings[i];
    const double t0 = r.t;
    int conflict = ring_conflict(c, ro, r, rings, kept, i);
    const int first_conflict = conflict;
    double last_close = r.t;
    while (conflict >= 0) {
      last_close = r.t;
      if (!move_ring_on(c, ro, r))
        break;
      conflict = ring_conflict(c, ro, r, rings, kept, i);
    }
    if (first_conflict >= 0 && conflict < 0) { // the least move that clears it, found by bisection
      double lo = last_close, hi = r.t;
      for (int it = 0; it < 6; ++it) {
        const double mid = (lo + hi) / 2;
        (place_ring_at(c, ro, r, mid) && ring_conflict(c, ro, r, rings, kept, i) < 0 ? hi : lo) = mid;
      }
      place_ring_at(c, ro, r, hi);
    }
    if (conflict >= 0) {
      r.replaced_by = conflict;
      std::ostringstream gap; // three digits at any scale (std::to_string gave 0.000000 at 1e-30)
      gap << std::setprecision(3) << ro.gap(r, rings[conflict]);
      const std::string m = "ring '" + r.id + "' dropped: it comes within " + gap.str() + " of ring '" +
                            rings[conflict].id + "'" +
                            (r.place.t_max > t0 ? ", moved as far along its bone as it goes" : "");
      c.say(m);
      if (r.frac == 1)
        ringless[r.joint] = m;
      continue;
    }
    if (first_conflict >= 0)
      c.say("ring '" + r.id + "' moved along its bone (" + percent(t0) + " to " + percent(r.t) +
            "): it came too close to ring '" + rings[first_conflict].id + "'");
    r.active = true;
    kept.push_back(i);
  }
  return kept;
}

// ---- stage 4: chains ------------------------------------------------------

std::map<int, int> chain_rings(const StarterContext& c, const RingOptions& ro, std::vector<Ring>& rings,
                               const std::vector<int>& kept) {
  const Skeleton& sk = c.sk;
  auto is_ancestor = [&](int a, int j) { // a is j or one of its ancestors
    for (int x = j, guard = 0; x >= 0 && guard <= static_cast<int>(sk.parent.size()); x = sk.parent[x], ++guard)
      if (x == a)
        return true;
    return false;
  };
  // A dropped ring stands for the ring that replaced it, as long as that
  // one belongs up the same chain (a trunk's, or an ancestor's): a ring
  // dropped for coming close to another limb's does not make that limb its parent.
  auto resolve = [&](int i, int below) {
    for (int guard = 0; i >= 0 && !rings[i].active && guard < static_cast<int>(rings.size()); ++guard) {
      const int r = rings[i].replaced_by;
      if (r < 0 || !std::any_of(rings[r].own.begin(), rings[r].own.end(), [&](int j) { return is_ancestor(j, below); }))
        return -1;
      i = r;
    }
    return i >= 0 && rings[i].active ? i : -1;
  };
  // Each ring's parent: the ring at the nearest position up the skeleton.
  std::map<int, std::vector<int>> at_joint; // joint -> candidate rings, by frac descending
  for (size_t i = 0; i < rings.size(); ++i)
    for (int j : rings[i].own)
      at_joint[j].push_back(static_cast<int>(i));
  for (auto& [j, list] : at_joint)
    std::sort(list.begin(), list.end(), [&](int a, int b) { return rings[a].frac > rings[b].frac; });
  std::map<int, int> parent_ring;
  for (int i : kept) {
    const int below = rings[i].joint;
    int found = -1;
    for (int k : at_joint[below])
      if (rings[k].frac < rings[i].frac && (found = resolve(k, below)) >= 0 && found != i)
        break;
      else
        found = -1;
    for (int a = sk.parent[below]; a >= 0 && found < 0; a = sk.parent[a])
      for (int k : at_joint[a]) {
        const int r = resolve(k, below);
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
  // Every chain joined: a ring left with no parent (its ancestors' rings
  // are dropped, or a second root's chain) joins the nearest ring of those
  // already joined to the first, the ring highest up the skeleton.
  auto depth_of = [&](int j) {
    int d = 0;
    for (int x = sk.parent[j]; x >= 0 && d <= static_cast<int>(sk.parent.size()); x = sk.parent[x])
      ++d;
    return d;
  };
  std::vector<int> orphans;
  for (int i : kept)
    if (parent_ring[i] < 0)
      orphans.push_back(i);
  std::stable_sort(orphans.begin(), orphans.end(), [&](int a, int b) {
    const int da = depth_of(rings[a].joint), db = depth_of(rings[b].joint);
    if (da != db)
      return da < db;
    return sk.subtree[rings[a].joint] > sk.subtree[rings[b].joint];
  });
  if (orphans.size() > 1) {
    auto root_of = [&](int i) {
      for (size_t steps = 0; parent_ring[i] >= 0 && steps <= kept.size(); ++steps)
        i = parent_ring[i];
      return i;
    };
    for (size_t k = 1; k < orphans.size(); ++k) {
      const int o = orphans[k];
      int best = -1;
      double best_d = INFINITY;
      for (int i : kept) {
        const int r = root_of(i);
        if (r == o || std::find(orphans.begin() + static_cast<long>(k), orphans.end(), r) != orphans.end())
          continue; // not joined to the first yet
        const double d = polyline_distance(rings[o].loop, true, rings[i].loop, true);
        if (d < best_d) {
          best_d = d;
          best = i;
        }
      }
      if (best >= 0) {
        parent_ring[o] = best;
        c.say("ring '" + rings[o].id + "' has no ring up its chain: it joins the nearest ring, '" + rings[best].id +
              "'");
      }
    }
  }
  // Nodes at consistent angles: node 0's direction is carried from each
  // ring's parent ring; a ring with none starts from its chain root's local
  // X axis.
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
    if (!place_nodes(r, ro.nodes_per_ring, ro.first_angle_deg))
      c.say("ring '" + r.id + "': nodes spread by arc length (the section is not star-shaped about its centre)");
  }
  return parent_ring;
}

} // namespace curvenet::detail
