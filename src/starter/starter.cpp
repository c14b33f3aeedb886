// The starter Curvenet (docs/starter.md): rings from plane sections through
// the joints, profiles along each chain, joins where chains branch, and a
// check that the result embeds.

#include "curvenet/starter.hpp"

#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "starter/plane_section.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <regex>
#include <set>

namespace curvenet {

using namespace detail;

namespace {

struct Skeleton {
  std::vector<Vec3> origin;
  std::vector<int> parent;
  std::vector<std::vector<int>> kids;
  std::vector<Eigen::Matrix3d> rotation;

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
  }
};

/// A ring: a closed section around a limb (or around several, a trunk).
struct Ring {
  std::string id;
  int joint = -1;  ///< the joint whose plane made it
  double frac = 1; ///< where on the bone into `joint` (1: at the joint)
  Vec3 centre = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ(); ///< the plane's normal, along the bone
  std::vector<Vec3> loop;    ///< counter-clockwise about `axis`
  std::vector<double> at;    ///< arc length of each loop point
  double perimeter = 0;
  int replaced_by = -1; ///< dropped: the ring that stands for it
  bool active = false;
  std::vector<double> base_nodes; ///< arc-length positions of nodes 0..N-1
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

std::optional<std::vector<Vec3>> surface_path(const SectionMesh& sm, const Vec3& a, const Vec3& b,
                                              const std::vector<Vec3>& preferred, double tol) {
  auto all = surface_paths(sm, a, b, preferred, tol);
  if (all.empty())
    return std::nullopt;
  return std::move(all.front());
}

std::vector<std::string> quoted(const std::string& text) {
  std::vector<std::string> out;
  static const std::regex re("'([^']+)'");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
    out.push_back((*it)[1]);
  return out;
}

} // namespace

StarterResult make_starter(const SurfaceMesh& mesh, const std::vector<Joint>& joints, const StarterOptions& opt) {
  if (joints.empty())
    throw InputError(mesh.source, "skeleton", "has no joints");
  if (opt.nodes_per_ring < 2)
    throw Error("starter: at least 2 nodes per ring are needed");
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

  // 1. Candidate rings: planes through each joint (and along each bone).
  std::vector<Ring> rings;
  for (int j = 0; j < nj; ++j) {
    const int p = sk.parent[j];
    std::vector<std::pair<double, Vec3>> spots; // (frac, point)
    Vec3 bone;
    if (p >= 0) {
      bone = sk.origin[j] - sk.origin[p];
      for (int i = 1; i <= opt.rings_per_bone; ++i)
        spots.emplace_back(static_cast<double>(i) / opt.rings_per_bone,
                           sk.origin[p] + bone * (static_cast<double>(i) / opt.rings_per_bone));
    } else if (sk.kids[j].size() == 1) {
      bone = sk.origin[sk.kids[j][0]] - sk.origin[j];
      spots.emplace_back(1.0, sk.origin[j]);
    }
    if (bone.norm() <= 0)
      continue;
    for (const auto& [frac, point] : spots) {
      Vec3 axis = bone.normalized();
      if (frac == 1.0 && p >= 0 && sk.kids[j].size() == 1) { // bisect the angle at the joint
        const Vec3 out = sk.origin[sk.kids[j][0]] - sk.origin[j];
        if (out.norm() > 0 && (axis + out.normalized()).norm() > 1e-6)
          axis = (axis + out.normalized()).normalized();
      }
      // The smallest closed section that winds around the joint.
      const Section* best = nullptr;
      const auto sections = plane_sections(sm, point, axis);
      for (const Section& s : sections)
        if (s.closed && s.points.size() >= 3 && winding_number(s.points, point, point, axis) != 0 &&
            (!best || s.length() < best->length()))
          best = &s;
      if (!best)
        continue;
      Ring r;
      r.id = joints[j].name + (opt.rings_per_bone > 1
                                   ? "_" + std::to_string(static_cast<int>(std::lround(frac * opt.rings_per_bone)))
                                   : "");
      r.joint = j;
      r.frac = frac;
      r.axis = axis;
      r.loop = best->points;
      // Counter-clockwise about the axis, and the area centroid.
      const auto [u, v] = plane_basis(axis);
      double area = 0;
      Eigen::Vector2d c2 = Eigen::Vector2d::Zero();
      for (size_t i = 0; i < r.loop.size(); ++i) {
        const Vec3 a = r.loop[i] - point, b = r.loop[(i + 1) % r.loop.size()] - point;
        const double cr = a.dot(u) * b.dot(v) - a.dot(v) * b.dot(u);
        area += cr / 2;
        c2 += cr * Eigen::Vector2d(a.dot(u) + b.dot(u), a.dot(v) + b.dot(v)) / 6;
      }
      if (area < 0)
        std::reverse(r.loop.begin(), r.loop.end());
      r.centre = point + (c2.x() / area) * u + (c2.y() / area) * v;
      double acc = 0;
      for (size_t i = 0; i < r.loop.size(); ++i) {
        r.at.push_back(acc);
        acc += (r.loop[(i + 1) % r.loop.size()] - r.loop[i]).norm();
      }
      r.perimeter = acc;
      rings.push_back(std::move(r));
    }
  }
  if (rings.empty())
    throw InputError(
        mesh.source, "skeleton",
        "lies outside the mesh: no plane through a joint cuts a loop around it (check the skeleton's space and units)");

  // 2. Keep rings greedily, smallest first; drop rings too small for their
  //    nodes, or too close to (or crossing) a ring already kept.
  const double gap = std::max(opt.min_ring_gap * diag, 0.5 * h);
  std::vector<int> order(rings.size());
  for (size_t i = 0; i < order.size(); ++i)
    order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return rings[a].perimeter < rings[b].perimeter; });
  std::vector<int> kept;
  for (int i : order) {
    Ring& r = rings[i];
    if (static_cast<int>(r.loop.size()) < N) {
      say("ring '" + r.id + "' dropped: too small for " + std::to_string(N) + " nodes at this mesh resolution");
      continue;
    }
    int conflict = -1;
    for (int k : kept)
      if (polyline_distance(r.loop, true, rings[k].loop, true) < gap) {
        conflict = k;
        break;
      }
    if (conflict >= 0) {
      r.replaced_by = conflict;
      say("ring '" + r.id + "' dropped: it comes within " + std::to_string(gap) + " of ring '" + rings[conflict].id +
          "'");
      continue;
    }
    r.active = true;
    kept.push_back(i);
  }
  auto resolve = [&](int i) {
    for (int guard = 0; i >= 0 && !rings[i].active && guard < static_cast<int>(rings.size()); ++guard)
      i = rings[i].replaced_by;
    return i >= 0 && rings[i].active ? i : -1;
  };

  // 3. Nodes at consistent angles: one reference direction per chain.
  for (int i : kept) {
    Ring& r = rings[i];
    int root = r.joint;
    while (sk.parent[root] >= 0 && sk.kids[sk.parent[root]].size() == 1)
      root = sk.parent[root];
    Vec3 ref = sk.rotation[root].col(0);
    ref -= ref.dot(r.axis) * r.axis;
    if (ref.norm() < 0.3) {
      ref = sk.rotation[root].col(2);
      ref -= ref.dot(r.axis) * r.axis;
    }
    if (ref.norm() < 1e-9)
      ref = plane_basis(r.axis)[0];
    ref.normalize();
    const Vec3 side = r.axis.cross(ref);
    std::vector<double> pos;
    for (int k = 0; k < N; ++k) {
      const double ang = 2 * std::numbers::pi * k / N + opt.first_angle_deg * std::numbers::pi / 180;
      const Vec3 dir = std::cos(ang) * ref + std::sin(ang) * side;
      const Vec3 perp = r.axis.cross(dir);
      // Nearest crossing of the ray from the centre with the loop.
      double best = std::numeric_limits<double>::infinity(), best_s = -1;
      for (size_t q = 0; q < r.loop.size(); ++q) {
        const Vec3 a = r.loop[q] - r.centre, b = r.loop[(q + 1) % r.loop.size()] - r.centre;
        // Solve lambda * dir = a + t (b - a) in the plane (2D, basis dir / side).
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
    // The loop must meet the rays in order around it; otherwise spread the
    // nodes evenly by arc length from node 0.
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
      say("ring '" + r.id + "': nodes spread by arc length (the section is not star-shaped about its centre)");
    }
    r.base_nodes = pos;
  }

  // 4. Each ring's parent: the ring at the nearest position up the skeleton.
  std::map<int, std::vector<int>> at_joint; // joint -> candidate rings, by frac descending
  for (size_t i = 0; i < rings.size(); ++i)
    at_joint[rings[i].joint].push_back(static_cast<int>(i));
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

  // 5. Build, embed, and on a failure drop what failed; repeat.
  std::set<int> dropped;
  std::map<int, int> join_attempt; // child ring -> 0: new node on parent, 1: parent's nearest node, 2: unjoined
  for (int attempt = 0;; ++attempt) {
    Rig rig;
    rig.coverage = opt.coverage;
    rig.has_skeleton = true;
    rig.joints = joints;
    std::map<std::string, std::pair<char, int>> owner; // profile -> (kind: a arc, l longitudinal, j join; ring)
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
    // Series: a parent with one child ring gets N profiles along the chain;
    // where a chain branches, each child ring joins its parent by one profile.
    std::map<int, int> series_child;
    for (auto& [p, list] : children)
      if (list.size() == 1)
        series_child[p] = list[0];
    // Extra nodes on parents where joins land.
    std::map<int, std::vector<std::pair<double, std::string>>> extra; // ring -> (arc pos, node id)
    struct Join {
      int child, parent, child_node;
      std::string target;
      Vec3 to;
      std::optional<std::vector<Vec3>> path;
    };
    std::vector<Join> joins;
    int unjoined = 0;
    for (int c : active) {
      const int p = effective_parent(c);
      if (p < 0 || (series_child.count(p) && series_child[p] == c))
        continue;
      const int mode = join_attempt[c];
      if (mode >= 2) {
        ++unjoined;
        continue;
      }
      // The child's node nearest to the parent's loop.
      int best_k = 0;
      double best_d = std::numeric_limits<double>::infinity(), best_s = 0;
      for (int k = 0; k < N; ++k) {
        double d = 0;
        const double s = closest_on_loop(rings[p], loop_point(rings[c], rings[c].base_nodes[k]), &d);
        if (d < best_d) {
          best_d = d;
          best_k = k;
          best_s = s;
        }
      }
      Join jn{c, p, best_k, "", Vec3::Zero(), std::nullopt};
      const Ring& pr = rings[p];
      const Vec3 from = loop_point(rings[c], rings[c].base_nodes[best_k]);
      if (mode == 0) {
        jn.to = loop_point(pr, best_s);
      } else {
        int nk = 0;
        for (int k = 1; k < N; ++k)
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
      for (auto& path : surface_paths(sm, from, jn.to, {jn.to + out, (pr.centre + rings[c].centre) / 2}, tol)) {
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
        if (mode == 1 && (loop_point(pr, s_hit) - jn.to).norm() > tol)
          continue; // it would cross the ring before reaching its node
        const Vec3 end = mode == 0 ? loop_point(pr, s_hit) : jn.to;
        path.resize(cut + 1);
        path.push_back(end);
        // The incoming direction over the last half edge length, against the ring's tangent.
        Vec3 in = Vec3::Zero();
        for (size_t i = path.size() - 1; i-- > 0;) {
          in = end - path[i];
          if (in.norm() >= 0.5 * h)
            break;
        }
        const Vec3 tangent = loop_point(pr, s_hit + 1e-3 * pr.perimeter) - loop_point(pr, s_hit - 1e-3 * pr.perimeter);
        const double sine =
            in.norm() > 0 && tangent.norm() > 0 ? in.normalized().cross(tangent.normalized()).norm() : 0;
        if (sine > best_sin) {
          best_sin = sine;
          jn.path = path;
          jn.to = end;
          if (mode == 0)
            best_s = s_hit;
        }
        if (sine >= min_sin)
          break;
      }
      if (mode == 0) {
        jn.target = pr.id + "_j" + std::to_string(extra[p].size());
        extra[p].emplace_back(best_s, jn.target);
      }
      joins.push_back(jn);
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
        rig.profiles.push_back(std::move(pr));
      }
    }
    std::string failure; // the first reason this net cannot be used
    // Along each chain.
    for (const auto& [p, c] : series_child) {
      if (dropped.count(c))
        continue;
      const Vec3 mid = (rings[p].centre + rings[c].centre) / 2;
      for (int k = 0; k < N; ++k) {
        const Vec3 a = loop_point(rings[p], rings[p].base_nodes[k]), b = loop_point(rings[c], rings[c].base_nodes[k]);
        Profile pr;
        pr.id = rings[p].id + "-" + rings[c].id + "_" + std::to_string(k);
        pr.from = rings[p].id + "_" + std::to_string(k);
        pr.to = rings[c].id + "_" + std::to_string(k);
        auto path = surface_path(sm, a, b, {mid}, tol);
        if (!path && failure.empty())
          failure = "no plane section joins the ends of profile '" + pr.id + "' along the surface";
        pr.curve.points = path ? *path : std::vector<Vec3>{a, b};
        owner[pr.id] = {'l', c};
        rig.profiles.push_back(std::move(pr));
      }
    }
    for (const Join& jn : joins) {
      Profile pr;
      pr.id = rings[jn.child].id + "-" + rings[jn.parent].id + "_join";
      pr.from = rings[jn.child].id + "_" + std::to_string(jn.child_node);
      pr.to = jn.target;
      if (!jn.path && failure.empty())
        failure = "no plane section joins the ends of profile '" + pr.id + "' along the surface";
      pr.curve.points =
          jn.path ? *jn.path
                  : std::vector<Vec3>{loop_point(rings[jn.child], rings[jn.child].base_nodes[jn.child_node]), jn.to};
      owner[pr.id] = {'j', jn.child};
      rig.profiles.push_back(std::move(pr));
    }
    for (const Node& n : rig.nodes) {
      for (const auto& [j, w] : auto_weights(joints, n.position, opt.weights))
        rig.weights[n.id][joints[j].name] = w;
    }
    // Check it: profiles that share no node keep a clearance (so that the
    // net also embeds on other tessellations), and the net embeds here.
    if (failure.empty()) {
      const double clearance = std::max(opt.min_ring_gap * diag / 2, 0.25 * h);
      std::map<std::string, Vec3> node_at;
      for (const Node& n : rig.nodes)
        node_at[n.id] = n.position;
      std::vector<Eigen::AlignedBox3d> box(rig.profiles.size());
      for (size_t a = 0; a < rig.profiles.size(); ++a)
        for (const auto& q : rig.profiles[a].curve.points)
          box[a].extend(q);
      // The part of a profile that keeps away from the given nodes.
      auto away_from = [&](const std::vector<Vec3>& pts, const std::vector<Vec3>& shared) {
        std::vector<Vec3> out;
        for (const Vec3& q : pts)
          if (std::all_of(shared.begin(), shared.end(), [&](const Vec3& n) { return (q - n).norm() > 2 * clearance; }))
            out.push_back(q);
        return out;
      };
      for (size_t a = 0; a < rig.profiles.size() && failure.empty(); ++a)
        for (size_t b = a + 1; b < rig.profiles.size() && failure.empty(); ++b) {
          if (box[a].exteriorDistance(box[b]) >= clearance)
            continue;
          const Profile &pa = rig.profiles[a], &pb = rig.profiles[b];
          std::vector<Vec3> shared;
          for (const std::string& n : {pa.from, pa.to})
            if (n == pb.from || n == pb.to)
              shared.push_back(node_at[n]);
          const auto qa = away_from(pa.curve.points, shared), qb = away_from(pb.curve.points, shared);
          if (qa.size() < 2 || qb.size() < 2)
            continue;
          if (polyline_distance(qa, false, qb, false) < clearance)
            failure = "profiles '" + pa.id + "' and '" + pb.id + "' come closer than " + std::to_string(clearance);
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
        result.unjoined = unjoined;
        result.net_components = e.report().components;
        if (unjoined > 0)
          say(std::to_string(unjoined) + " chain(s) could not be joined to their parent ring; the net has " +
              std::to_string(result.net_components) + " components, and the expected region count accounts for them");
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
        bool first = true;
        for (int c : active)
          if (effective_parent(c) >= 0 && join_attempt[c] >= 2) {
            ext += (first ? "" : ", ") + quote(rings[c].id);
            first = false;
          }
        ext += "], \"net_components\": " + std::to_string(result.net_components) + ", \"notes\": [";
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
    if (attempt > 4 * static_cast<int>(rings.size()) + 8)
      throw EmbedError("starter: could not make a net that embeds: " + failure);
    // Find what to give up: a join first, then the child ring of a longitudinal, then a ring.
    int culprit_ring = -1;
    char kind = 0;
    for (const std::string& id : quoted(failure)) {
      auto it = owner.find(id);
      if (it == owner.end())
        continue;
      if (it->second.first == 'j' || kind == 0 || (kind == 'a' && it->second.first == 'l')) {
        kind = it->second.first;
        culprit_ring = it->second.second;
      }
      if (kind == 'j')
        break;
    }
    if (culprit_ring < 0) {
      // No profile named (for example a wrong region count): drop the largest ring.
      for (int i : active)
        if (culprit_ring < 0 || rings[i].perimeter > rings[culprit_ring].perimeter)
          culprit_ring = i;
      kind = 'a';
    }
    if (kind == 'j') {
      const int m = ++join_attempt[culprit_ring];
      say("join of ring '" + rings[culprit_ring].id + "' " + (m >= 2 ? "abandoned" : "moved to an existing node") +
          ": " + failure);
    } else {
      dropped.insert(culprit_ring);
      say("ring '" + rings[culprit_ring].id + "' dropped: " + failure);
      if (dropped.size() == kept.size())
        throw EmbedError("starter: could not make a net that embeds: " + failure);
    }
  }
}

} // namespace curvenet
