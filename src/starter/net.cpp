// The starter's net (docs/starter.md, steps 5 to 7): arcs of every ring,
// profiles along each chain, joins on both sides of each fork, and the
// checks a net must pass before it is embedded.

#include "core/polyline_distance.hpp"
#include "starter/stages.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <queue>

namespace curvenet::detail {

namespace {

const double kClearSine = std::sin(35.0 * std::numbers::pi / 180.0);

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
std::vector<std::vector<Vec3>> surface_paths_uncached(const SectionMesh& sm, const Vec3& a, const Vec3& b,
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

const std::vector<std::vector<Vec3>>& surface_paths(const StarterContext& c, const Vec3& a, const Vec3& b,
                                                    const std::vector<Vec3>& preferred) {
  std::vector<double> key{a.x(), a.y(), a.z(), b.x(), b.y(), b.z()};
  for (const Vec3& m : preferred)
    key.insert(key.end(), {m.x(), m.y(), m.z()});
  auto it = c.path_cache.find(key);
  if (it == c.path_cache.end())
    it = c.path_cache.emplace(std::move(key), surface_paths_uncached(c.sm, a, b, preferred, c.tol)).first;
  return it->second;
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

/// Which child of each fork carries the chain on, and the direction the
/// branch joins face (docs/starter.md, step 6).
struct Forks {
  std::map<int, int> series_child; ///< parent ring -> the child joined along the chain
  std::map<int, Vec3> across;      ///< parent ring -> the direction the join nodes face
};

Forks fork_layout(const std::vector<Ring>& rings, const std::map<int, std::vector<int>>& children) {
  // A parent with one child ring, or the child that carries its trunk on
  // (the one ring ahead along its axis and at least 0.6 its size), gets N
  // profiles along the chain; every other child joins its parent by
  // profiles that leave it on the two sides of the fork (the back and the
  // palm of a hand, the front and back of a hip or shoulder).
  Forks f;
  for (const auto& [p, list] : children) {
    const Ring& pr = rings[p];
    if (list.size() == 1) {
      f.series_child[p] = list[0];
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
      f.series_child[p] = ahead[0];
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
    f.across[p] = w;
  }
  return f;
}

struct Join {
  int child, parent, slot, child_node;
  std::string target;
  Vec3 to;
  std::optional<std::vector<Vec3>> path;
};

/// A join along the mesh's edges, where no plane section makes one: the
/// shortest path from `from` (on the child ring) to the first vertex next
/// to the parent ring, through vertices that keep the limb's clearance from
/// every other ring (and from the child ring, away from `from`), then on to
/// the parent ring's nearest point. Empty when there is none.
std::vector<Vec3> edge_path_join(const StarterContext& c, const NetOptions& no, const std::vector<Ring>& rings,
                                 const std::vector<int>& active, int child, int parent, const Vec3& from,
                                 const std::optional<Vec3>& node) {
  const auto& P = c.mesh.positions;
  const int nv = c.mesh.num_vertices();
  const Ring &pr = rings[parent], &cr = rings[child];
  const double cl = no.profile_clearance(c.diag, std::min(cr.radius(), pr.radius()));
  // Each ring's box, and how far its loop strays from its plane (none, or
  // rounding, for a plane section): a point further than that plus d from
  // the plane is no nearer than d to the loop.
  std::vector<Eigen::AlignedBox3d> box(rings.size());
  std::vector<double> slab(rings.size(), 0);
  for (int o : active)
    for (const Vec3& q : rings[o].loop) {
      box[o].extend(q);
      slab[o] = std::max(slab[o], std::abs((q - rings[o].centre).dot(rings[o].axis)));
    }
  auto near_ring = [&](int o, const Vec3& x, double d) {
    Eigen::AlignedBox3d b = box[o];
    b.extend(b.min() - Vec3::Constant(d)).extend(b.max() + Vec3::Constant(d));
    if (!b.contains(x) || std::abs((x - rings[o].centre).dot(rings[o].axis)) - slab[o] > d)
      return false;
    double dist = 0;
    closest_on_loop(rings[o], x, &dist);
    return dist < d;
  };
  std::vector<signed char> known(nv, -1); // blocked(v), once found
  auto blocked = [&](int v) {
    if (known[v] >= 0)
      return known[v] != 0;
    known[v] = 0;
    const Vec3& x = P[v];
    for (int o : active) {
      if (o == parent)
        continue;
      if (o == child && (x - from).norm() < 3 * cl)
        continue;
      if (near_ring(o, x, cl)) {
        known[v] = 1;
        return true;
      }
    }
    return false;
  };
  // The first vertex next to the parent ring, or next to its given node.
  auto target = [&](int v) {
    return node ? (P[v] - *node).norm() < std::max(cl, c.h) : near_ring(parent, P[v], std::max(cl, c.h));
  };
  // Start from the vertices of the edge `from` lies on (the nearest two).
  std::vector<double> dist(nv, INFINITY);
  std::vector<int> prev(nv, -1);
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  std::array<std::pair<double, int>, 2> nearest{{{INFINITY, -1}, {INFINITY, -1}}}; // in order
  for (int v = 0; v < nv; ++v) {
    const std::pair<double, int> dv((P[v] - from).norm(), v);
    if (dv < nearest[0]) {
      nearest[1] = nearest[0];
      nearest[0] = dv;
    } else if (dv < nearest[1]) {
      nearest[1] = dv;
    }
  }
  for (const auto& [d, v] : nearest)
    if (v >= 0) {
      dist[v] = d;
      queue.push({d, v});
    }
  int end = -1;
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > dist[v])
      continue;
    if (target(v) && (P[v] - from).norm() > 2 * cl) {
      end = v;
      break;
    }
    for (int k = c.next_offset[v]; k < c.next_offset[v + 1]; ++k) {
      const int u = c.next_vertex[k];
      const double nd = d + (P[u] - P[v]).norm();
      if (nd < dist[u] && !blocked(u)) {
        dist[u] = nd;
        prev[u] = v;
        queue.push({nd, u});
      }
    }
  }
  if (end < 0) {
    return {};
  }
  std::vector<Vec3> path;
  for (int v = end; v >= 0; v = prev[v])
    path.push_back(P[v]);
  path.push_back(from);
  std::reverse(path.begin(), path.end());
  path.push_back(node ? *node : loop_point(pr, closest_on_loop(pr, P[end])));
  return path;
}

/// The path of a join from `from` on the child ring to `jn.to` on the parent
/// ring: the first candidate that meets the parent ring where the join is
/// meant to, keeps clear of every ring away from its ends, and leaves and
/// meets its rings at a clear angle (or the squarest such). Sets jn.path
/// and jn.to, and `landing` (the arc position on the parent) for a new node.
void route_join(const StarterContext& c, const NetOptions& no, const std::vector<Ring>& rings,
                const std::vector<int>& active, Join& jn, const Vec3& from, double& landing) {
  const Ring &pr = rings[jn.parent], &cr = rings[jn.child];
  // The plane holds the outward direction at the target, so the join meets
  // the parent ring square rather than glancing along it; the first plane
  // tried also holds the child's axis at its node, so the join leaves the
  // child ring square too.
  Vec3 out = jn.to - pr.centre;
  out -= out.dot(pr.axis) * pr.axis;
  double best_sin = -1;
  // The parent ring's segments as balls (middle, half length): a segment
  // of a path further from a ball than twice the tolerance cannot meet it.
  // And a segment with both ends off the ring's plane, on one side, by more
  // than the loop strays from it plus twice the tolerance, meets none.
  const size_t nq = pr.loop.size();
  std::vector<Vec3> mid(nq);
  std::vector<double> rad(nq);
  double slab = 0;
  for (size_t q = 0; q < nq; ++q) {
    mid[q] = (pr.loop[q] + pr.loop[(q + 1) % nq]) / 2;
    rad[q] = (pr.loop[(q + 1) % nq] - pr.loop[q]).norm() / 2;
    slab = std::max(slab, std::abs((pr.loop[q] - pr.centre).dot(pr.axis)));
  }
  auto off_plane = [&](const Vec3& a, const Vec3& b) {
    const double da = (a - pr.centre).dot(pr.axis), db = (b - pr.centre).dot(pr.axis);
    return std::min(da, db) > slab + 2 * c.tol || std::max(da, db) < -slab - 2 * c.tol;
  };
  for (std::vector<Vec3> path :
       surface_paths(c, from, jn.to, {from - cr.radius() * cr.axis, jn.to + out, (pr.centre + cr.centre) / 2})) {
    double s_hit = -1;
    size_t cut = path.size() - 1;
    for (size_t i = 0; i + 1 < path.size() && s_hit < 0; ++i) {
      Vec3 hit = Vec3::Zero();
      if (off_plane(path[i], path[i + 1]))
        continue;
      const Vec3 m = (path[i] + path[i + 1]) / 2;
      const double r = (path[i + 1] - path[i]).norm() / 2;
      for (size_t q = 0; q < nq; ++q)
        if ((m - mid[q]).norm() - r - rad[q] < 2 * c.tol &&
            segment_distance(path[i], path[i + 1], pr.loop[q], pr.loop[(q + 1) % nq], &hit) < c.tol) {
          s_hit = closest_on_loop(pr, hit);
          cut = i;
          break;
        }
    }
    if (s_hit < 0)
      continue;
    if (!jn.target.empty() && (loop_point(pr, s_hit) - jn.to).norm() > c.tol)
      continue; // it would cross the ring before reaching its node
    const Vec3 end = jn.target.empty() ? loop_point(pr, s_hit) : jn.to;
    path.resize(cut + 1);
    path.push_back(end);
    // It must keep clear of every other ring, its own child ring included,
    // away from its two ends.
    bool clear = true;
    for (int o : active) {
      const double cl = no.profile_clearance(c.diag, std::min(cr.radius(), rings[o].radius()));
      std::vector<Vec3> middle;
      for (const Vec3& q : path)
        if ((q - from).norm() > 2 * cl && (q - end).norm() > 2 * cl)
          middle.push_back(q);
      if (middle.size() >= 2 && polylines_within(middle, false, rings[o].loop, true, cl)) {
        clear = false;
        break;
      }
    }
    if (!clear)
      continue;
    // The directions over the first and last half edge length, against the
    // rings' tangents: the join must leave its ring and meet the other at a
    // clear angle.
    const double sine = std::min(crossing_sine(path, pr, s_hit, true, c.h),
                                 crossing_sine(path, cr, cr.base_nodes[jn.child_node], false, c.h));
    if (sine > best_sin) {
      best_sin = sine;
      jn.path = path;
      jn.to = end;
      if (jn.target.empty())
        landing = s_hit;
    }
    if (sine >= kClearSine)
      break;
  }
  if (!jn.path) { // no plane section joins them: along the mesh's edges
    std::vector<Vec3> path = edge_path_join(c, no, rings, active, jn.child, jn.parent, from,
                                            jn.target.empty() ? std::nullopt : std::optional<Vec3>(jn.to));
    if (!path.empty()) {
      jn.to = path.back();
      if (jn.target.empty())
        landing = closest_on_loop(pr, jn.to);
      jn.path = std::move(path);
    }
  }
}

/// The joins of every branch child to its parent: two, from the child's
/// nodes facing the two sides of the fork, each landing on a new node of
/// the parent ring (or, on a retry, on the parent's nearest node).
std::vector<Join> branch_joins(const StarterContext& c, const NetOptions& no, const std::vector<Ring>& rings,
                               const std::vector<int>& active, const std::function<int(int)>& parent_of,
                               const Forks& forks, const JoinAttempts& attempts,
                               std::map<int, std::vector<std::pair<double, std::string>>>& extra,
                               std::vector<int>& unjoined) {
  const int N = no.nodes_per_ring;
  std::vector<Join> joins;
  for (int ch : active) {
    const int p = parent_of(ch);
    if (p < 0 || (forks.series_child.count(p) && forks.series_child.at(p) == ch))
      continue;
    const Ring &pr = rings[p], &cr = rings[ch];
    std::vector<int> nodes_used;
    bool any = false;
    for (int slot = 0; slot < 2; ++slot) {
      const auto at = attempts.find(2 * ch + slot);
      const int mode = at == attempts.end() ? 0 : at->second;
      // The child's node furthest to this slot's side.
      int best_k = 0;
      const double side = slot == 0 ? 1 : -1;
      for (int k = 1; k < N; ++k)
        if (side * forks.across.at(p).dot(loop_point(cr, cr.base_nodes[k]) - cr.centre) >
            side * forks.across.at(p).dot(loop_point(cr, cr.base_nodes[best_k]) - cr.centre))
          best_k = k;
      if (std::find(nodes_used.begin(), nodes_used.end(), best_k) != nodes_used.end())
        continue;
      nodes_used.push_back(best_k);
      if (mode >= kJoinTries)
        continue;
      any = true;
      const Vec3 from = loop_point(cr, cr.base_nodes[best_k]);
      double best_s = closest_on_loop(pr, from);
      Join jn{ch, p, slot, best_k, "", Vec3::Zero(), std::nullopt};
      // A landing next to one of the parent's nodes (or another join's)
      // lands on that node.
      int near_node = -1;
      std::string near_extra;
      for (int k = 0; k < N; ++k)
        if ((loop_point(pr, pr.base_nodes[k]) - loop_point(pr, best_s)).norm() < no.ring_gap * pr.radius())
          near_node = k;
      for (const auto& [s_extra, id] : extra[p])
        if (near_node < 0 && (loop_point(pr, s_extra) - loop_point(pr, best_s)).norm() < no.ring_gap * pr.radius())
          near_extra = id, best_s = s_extra;
      if (mode == 0 && !near_extra.empty()) {
        jn.target = near_extra;
        jn.to = loop_point(pr, best_s);
      } else if (mode == 0 && near_node < 0) {
        jn.to = loop_point(pr, best_s);
      } else if (mode >= 2) {                        // the middle of the (mode - 1)-th nearest arc
        std::vector<std::pair<double, double>> mids; // (distance from `from`, arc position)
        for (int k = 0; k < N; ++k) {
          const double a = pr.base_nodes[k], b = pr.base_nodes[(k + 1) % N];
          const double s = a + std::fmod(b - a + pr.perimeter, pr.perimeter) / 2;
          mids.emplace_back((loop_point(pr, s) - from).norm(), s);
        }
        std::sort(mids.begin(), mids.end());
        best_s = mids[std::min<size_t>(mode - 2, mids.size() - 1)].second;
        jn.to = loop_point(pr, best_s);
      } else {
        int nk = mode == 0 ? near_node : 0;
        for (int k = 1; k < N && mode > 0; ++k)
          if ((loop_point(pr, pr.base_nodes[k]) - from).norm() < (loop_point(pr, pr.base_nodes[nk]) - from).norm())
            nk = k;
        jn.target = pr.id + "_" + std::to_string(nk);
        jn.to = loop_point(pr, pr.base_nodes[nk]);
      }
      route_join(c, no, rings, active, jn, from, best_s);
      if (jn.target.empty()) {
        jn.target = pr.id + "_" + cr.id + (slot == 0 ? "_a" : "_b"); // named by the child: the same on every mesh
        extra[p].emplace_back(best_s, jn.target);
      }
      joins.push_back(jn);
    }
    if (!any)
      unjoined.push_back(ch);
  }
  return joins;
}

/// N profiles from ring p to ring ch, node k to node k: the first path
/// that meets both rings at a clear angle, or the squarest; where no plane
/// section makes one, along the mesh's edges.
void chain_profiles(const StarterContext& c, const NetOptions& no, const std::vector<Ring>& rings,
                    const std::vector<int>& active, int p, int ch, const PathSkips& skips, NetResult& net) {
  const Vec3 mid = (rings[p].centre + rings[ch].centre) / 2;
  for (int k = 0; k < no.nodes_per_ring; ++k) {
    const Vec3 a = loop_point(rings[p], rings[p].base_nodes[k]), b = loop_point(rings[ch], rings[ch].base_nodes[k]);
    Profile pr;
    pr.id = rings[p].id + "-" + rings[ch].id + "_" + std::to_string(k);
    pr.from = rings[p].id + "_" + std::to_string(k);
    pr.to = rings[ch].id + "_" + std::to_string(k);
    std::optional<std::vector<Vec3>> path;
    double best_sine = -1;
    const auto skip = skips.find(pr.id);
    int left_out = skip == skips.end() ? 0 : skip->second; // given up by the repairs
    for (const auto& candidate : surface_paths(c, a, b, {mid})) {
      if (left_out-- > 0)
        continue;
      const double sine = std::min(crossing_sine(candidate, rings[p], rings[p].base_nodes[k], false, c.h),
                                   crossing_sine(candidate, rings[ch], rings[ch].base_nodes[k], true, c.h));
      if (sine > best_sine) {
        best_sine = sine;
        path = candidate;
      }
      if (best_sine >= kClearSine)
        break;
    }
    if (!path) {
      std::vector<Vec3> edges = edge_path_join(c, no, rings, active, ch, p, b, a);
      if (!edges.empty()) {
        std::reverse(edges.begin(), edges.end());
        path = std::move(edges);
      }
    }
    if (!path && net.failure.empty())
      net.failure = "no plane section joins the ends of profile '" + pr.id + "' along the surface";
    pr.curve.points = path ? *path : std::vector<Vec3>{a, b};
    net.owner[pr.id] = {'l', ch};
    net.scale[pr.id] = std::min(rings[p].radius(), rings[ch].radius());
    net.rig.profiles.push_back(std::move(pr));
  }
}

} // namespace

NetResult build_net(const StarterContext& c, const NetOptions& no, const std::vector<Ring>& rings,
                    const std::vector<int>& active, const std::function<int(int)>& parent_of,
                    const JoinAttempts& attempts, const PathSkips& skips) {
  NetResult net;
  net.rig.coverage = no.coverage;
  net.rig.has_skeleton = true;
  net.rig.joints = c.joints;
  std::map<int, std::vector<int>> children;
  for (int i : active)
    if (parent_of(i) >= 0)
      children[parent_of(i)].push_back(i);
  const Forks forks = fork_layout(rings, children);
  std::map<int, std::vector<std::pair<double, std::string>>> extra; // ring -> (arc pos, node id) where joins land
  const std::vector<Join> joins = branch_joins(c, no, rings, active, parent_of, forks, attempts, extra, net.unjoined);
  net.joins = static_cast<int>(joins.size());
  // Nodes and arcs of every ring.
  for (int i : active) {
    const Ring& r = rings[i];
    std::vector<std::pair<double, std::string>> nodes;
    for (int k = 0; k < no.nodes_per_ring; ++k)
      nodes.emplace_back(r.base_nodes[k], r.id + "_" + std::to_string(k));
    for (const auto& e : extra[i])
      nodes.push_back(e);
    std::sort(nodes.begin(), nodes.end());
    for (const auto& [s, id] : nodes) {
      net.rig.nodes.push_back({id, loop_point(r, s)});
      net.node_ring.push_back(i);
      net.node_middle.push_back(0);
    }
    for (size_t k = 0; k < nodes.size(); ++k) {
      const auto& a = nodes[k];
      const auto& b = nodes[(k + 1) % nodes.size()];
      Profile pr;
      pr.id = r.id + "_arc" + std::to_string(k);
      pr.from = a.second;
      pr.to = b.second;
      pr.curve.points = loop_between(r, a.first, b.first);
      net.owner[pr.id] = {'a', i};
      net.scale[pr.id] = r.radius();
      net.rig.profiles.push_back(std::move(pr));
    }
  }
  for (const auto& [p, ch] : forks.series_child)
    chain_profiles(c, no, rings, active, p, ch, skips, net);
  for (const Join& jn : joins) {
    Profile pr;
    pr.id = rings[jn.child].id + "-" + rings[jn.parent].id + (jn.slot == 0 ? "_join" : "_join1");
    pr.from = rings[jn.child].id + "_" + std::to_string(jn.child_node);
    pr.to = jn.target;
    if (!jn.path && net.failure.empty())
      net.failure = "no plane section joins the ends of profile '" + pr.id + "' along the surface";
    pr.curve.points =
        jn.path ? *jn.path
                : std::vector<Vec3>{loop_point(rings[jn.child], rings[jn.child].base_nodes[jn.child_node]), jn.to};
    net.owner[pr.id] = {'j', 2 * jn.child + jn.slot};
    net.scale[pr.id] = std::min(rings[jn.child].radius(), rings[jn.parent].radius());
    net.rig.profiles.push_back(std::move(pr));
  }
  return net;
}

std::string check_net(const StarterContext& c, const NetOptions& no, const NetResult& net) {
  const Rig& rig = net.rig;
  // Profiles that share no node keep a clearance that scales with the limbs they are on.
  std::map<std::string, Vec3> node_at;
  for (const Node& n : rig.nodes)
    node_at[n.id] = n.position;
  std::vector<Eigen::AlignedBox3d> box(rig.profiles.size());
  for (size_t a = 0; a < rig.profiles.size(); ++a)
    for (const auto& q : rig.profiles[a].curve.points)
      box[a].extend(q);
  // The part of a profile that keeps away from the given nodes.
  auto away_from = [&](const std::vector<Vec3>& pts, const std::vector<Vec3>& shared, double cl) {
    std::vector<Vec3> out;
    for (const Vec3& q : pts)
      if (std::all_of(shared.begin(), shared.end(), [&](const Vec3& n) { return (q - n).norm() > 2 * cl; }))
        out.push_back(q);
    return out;
  };
  std::vector<std::pair<char, int>> owner(rig.profiles.size());
  std::vector<double> scale(rig.profiles.size());
  double largest = 0;
  for (size_t a = 0; a < rig.profiles.size(); ++a) {
    owner[a] = net.owner.at(rig.profiles[a].id);
    scale[a] = net.scale.at(rig.profiles[a].id);
    largest = std::max(largest, no.profile_clearance(c.diag, scale[a]));
  }
  for (size_t a = 0; a < rig.profiles.size(); ++a)
    for (size_t b = a + 1; b < rig.profiles.size(); ++b) {
      if (box[a].exteriorDistance(box[b]) >= largest)
        continue;
      const Profile &pa = rig.profiles[a], &pb = rig.profiles[b];
      const auto oa = owner[a], ob = owner[b];
      if (oa.first == 'a' && ob.first == 'a' && oa.second == ob.second)
        continue; // pieces of one plane section: they cannot cross
      const double cl = no.profile_clearance(c.diag, std::min(scale[a], scale[b]));
      if (box[a].exteriorDistance(box[b]) >= cl)
        continue;
      std::vector<Vec3> shared;
      for (const std::string& n : {pa.from, pa.to})
        if (n == pb.from || n == pb.to)
          shared.push_back(node_at[n]);
      const auto qa = away_from(pa.curve.points, shared, cl), qb = away_from(pb.curve.points, shared, cl);
      if (qa.size() < 2 || qb.size() < 2)
        continue;
      if (polylines_within(qa, false, qb, false, cl))
        return "profiles '" + pa.id + "' and '" + pb.id + "' come closer than " + std::to_string(cl);
    }
  // Profiles that leave one node must part at a clear angle.
  std::map<std::string, std::vector<std::pair<Vec3, std::string>>> leaving;
  auto direction = [&](const std::vector<Vec3>& pts, bool from_start) {
    const Vec3 o = from_start ? pts.front() : pts.back();
    for (size_t i = 1; i < pts.size(); ++i) {
      const Vec3& q = from_start ? pts[i] : pts[pts.size() - 1 - i];
      if ((q - o).norm() >= 0.5 * c.h || i + 1 == pts.size())
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
    for (size_t a = 0; a < dirs.size(); ++a)
      for (size_t b = a + 1; b < dirs.size(); ++b)
        if (dirs[a].first.dot(dirs[b].first) > min_cos)
          return "profiles '" + dirs[a].second + "' and '" + dirs[b].second + "' leave node '" + node +
                 "' less than 20 degrees apart";
  return {};
}

void split_profiles_at_middle(const StarterContext& c, const NetOptions& no, NetResult& net) {
  std::vector<Profile> out;
  out.reserve(net.rig.profiles.size());
  for (Profile& pr : net.rig.profiles) {
    const auto [kind, ring] = net.owner.at(pr.id);
    const std::vector<Vec3>& pts = pr.curve.points;
    double length = 0;
    for (size_t i = 1; i < pts.size(); ++i)
      length += (pts[i] - pts[i - 1]).norm();
    const bool split = (kind == 'l' || (kind == 'a' && net.scale.at(pr.id) >= no.arc_middle_radius * c.diag)) &&
                       length >= net.scale.at(pr.id) && pts.size() >= 2;
    if (!split) {
      out.push_back(std::move(pr));
      continue;
    }
    // The point at half the length: on a segment of the path, so on the
    // face the path crosses there.
    size_t i = 1;
    double before = 0;
    while (i + 1 < pts.size() && before + (pts[i] - pts[i - 1]).norm() < length / 2) {
      before += (pts[i] - pts[i - 1]).norm();
      ++i;
    }
    const double seg = (pts[i] - pts[i - 1]).norm();
    const double t = seg > 0 ? std::clamp((length / 2 - before) / seg, 0.0, 1.0) : 0.0;
    const Vec3 mid = pts[i - 1] + t * (pts[i] - pts[i - 1]);
    // Named by what stays the same on another tessellation: a profile along
    // a chain by its id, an arc by its end nodes (an arc's number depends
    // on how many joins land on its ring before it).
    const std::string node = (kind == 'a' ? pr.from + "-" + pr.to : pr.id) + "_mid";
    net.rig.nodes.push_back({node, mid});
    net.node_ring.push_back(ring);
    net.node_middle.push_back(kind == 'l' ? 1 : 0); // an arc's middle is one more node of its ring
    Profile a, b;
    a.id = pr.id + "_a";
    a.from = pr.from;
    a.to = node;
    a.curve.points.assign(pts.begin(), pts.begin() + static_cast<std::ptrdiff_t>(i)); // up to pts[i - 1]
    if (mid != a.curve.points.back())
      a.curve.points.push_back(mid);
    b.id = pr.id + "_b";
    b.from = node;
    b.to = pr.to;
    b.curve.points.push_back(mid);
    for (size_t k = i; k < pts.size(); ++k)
      if (pts[k] != b.curve.points.back())
        b.curve.points.push_back(pts[k]);
    if (a.curve.points.size() < 2 || b.curve.points.size() < 2) { // no length on one side: keep it whole
      net.rig.nodes.pop_back();
      net.node_ring.pop_back();
      net.node_middle.pop_back();
      out.push_back(std::move(pr));
      continue;
    }
    for (const Profile* half : {&a, &b}) {
      net.owner[half->id] = {kind, ring};
      net.scale[half->id] = net.scale.at(pr.id);
    }
    out.push_back(std::move(a));
    out.push_back(std::move(b));
  }
  net.rig.profiles = std::move(out);
}

} // namespace curvenet::detail
