#include "core/plane_section.hpp"

#include "core/predicates.hpp"
#include "core/tolerances.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

namespace curvenet::detail {

SectionMesh::SectionMesh(const SurfaceMesh& mesh) : mesh_(mesh) {
  std::map<std::pair<int, int>, int> edge_of;
  auto edge_id = [&](int a, int b, int t) {
    const auto key = std::make_pair(std::min(a, b), std::max(a, b));
    auto [it, fresh] = edge_of.emplace(key, static_cast<int>(edge_.size()));
    if (fresh) {
      edge_.push_back({key.first, key.second});
      edge_tri_.push_back({t, -1});
    } else {
      edge_tri_[it->second][1] = t;
    }
    return it->second;
  };
  // A polygon's fan diagonals are its own, shared by two of its triangles
  // alone: keyed by their corners, the diagonal of one twisted n-gon could
  // be another's edge or diagonal, an edge of three triangles.
  auto diagonal = [&](int a, int b, int t) {
    edge_.push_back({std::min(a, b), std::max(a, b)});
    edge_tri_.push_back({t, t + 1});
    return static_cast<int>(edge_.size()) - 1;
  };
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const auto c = mesh.face(f);
    int before = -1; // the diagonal the last triangle shares with this one
    for (size_t k = 1; k + 1 < c.size(); ++k) {
      const int t = static_cast<int>(tri_.size());
      tri_.push_back({c[0], c[k], c[k + 1]});
      const int first = k == 1 ? edge_id(c[0], c[k], t) : before;
      const int last = k + 2 == c.size() ? edge_id(c[k + 1], c[0], t) : diagonal(c[k + 1], c[0], t);
      tri_edge_.push_back({first, edge_id(c[k], c[k + 1], t), last});
      before = last;
    }
  }
  if (tri_.empty())
    return;
  std::vector<Vec3> centre(tri_.size());
  order_.resize(tri_.size());
  for (size_t t = 0; t < tri_.size(); ++t) {
    const auto& c = tri_[t];
    centre[t] = (mesh.positions[c[0]] + mesh.positions[c[1]] + mesh.positions[c[2]]) / 3;
    order_[t] = static_cast<int>(t);
  }
  node_.reserve(2 * tri_.size() / 4 + 1);
  build(0, static_cast<int>(tri_.size()), centre);
}

// A node over order_[begin, end): a leaf of at most four triangles, or two
// halves split at the median centre along the box's longest side.
int SectionMesh::build(int begin, int end, std::vector<Vec3>& centre) {
  const int id = static_cast<int>(node_.size());
  node_.emplace_back();
  Eigen::AlignedBox3d box;
  for (int i = begin; i < end; ++i)
    for (int v : tri_[order_[i]])
      box.extend(mesh_.positions[v]);
  node_[id].box = box;
  node_[id].begin = begin;
  node_[id].end = end;
  if (end - begin <= 4)
    return id;
  Eigen::Index axis = 0;
  box.sizes().maxCoeff(&axis);
  const int mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](int a, int b) { return centre[a][axis] < centre[b][axis]; });
  build(begin, mid, centre);
  const int second = build(mid, end, centre);
  node_[id].second = second;
  return id;
}

void SectionMesh::triangles_near_plane(const Vec3& origin, const Vec3& n, std::vector<int>& out) const {
  out.clear();
  if (node_.empty())
    return;
  std::vector<int> stack{0};
  while (!stack.empty()) {
    const Node& node = node_[stack.back()];
    stack.pop_back();
    // The box's points lie at signed distances d +- r from the plane.
    // Rounding in d (and in the plane the exact test uses, made from the
    // same unit vectors) is far below the slack; a box that is not clearly
    // off (NaN included) is visited.
    const Vec3 c = node.box.center(), h = node.box.sizes() / 2;
    const double d = (c - origin).dot(n), r = n.cwiseAbs().dot(h);
    const double slack = Tolerances::plane_prune_rel * ((c - origin).norm() + h.norm());
    if (std::abs(d) - r > slack)
      continue;
    if (node.second < 0) {
      out.insert(out.end(), order_.begin() + node.begin, order_.begin() + node.end);
    } else {
      stack.push_back(node.second);
      stack.push_back(static_cast<int>(&node - node_.data()) + 1);
    }
  }
}

double Section::length() const {
  double l = 0;
  for (size_t i = 0; i + 1 < points.size(); ++i)
    l += (points[i + 1] - points[i]).norm();
  if (closed && points.size() > 1)
    l += (points.front() - points.back()).norm();
  return l;
}

std::array<Vec3, 2> plane_basis(const Vec3& n) {
  const Vec3 z = n.normalized();
  const Vec3 a = std::abs(z.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 u = z.cross(a).normalized();
  return {u, z.cross(u)};
}

std::vector<Section> plane_sections(const SectionMesh& m, const Vec3& origin, const Vec3& normal) {
  const auto [u, v] = plane_basis(normal);
  // Two more points of the plane, as far from the origin as the origin is
  // from zero: a unit step from a joint at 1e17 rounds back onto it, and
  // the plane through three equal points cut nothing (a starter at a scale
  // of 1e19 found no section anywhere).
  const auto& pos = m.mesh().positions;
  const double reach = std::max(origin.cwiseAbs().maxCoeff(), pos.empty() ? 0.0 : pos.front().cwiseAbs().maxCoeff());
  const double step = std::min(reach > 1 ? reach : 1.0, 1e300); // (past 1e300 the sum would overflow)
  const Vec3 o1 = origin + step * u, o2 = origin + step * v;
  const Vec3 n = u.cross(v);
  // Only the triangles near the plane are visited. Each vertex's side and
  // each crossed edge's place are kept in this thread's tables, stamped
  // with this call, so that no table of the whole mesh is cleared per call.
  thread_local std::vector<int> near;
  m.triangles_near_plane(origin, n.normalized(), near);
  struct Scratch {
    std::vector<unsigned> vertex_stamp, edge_stamp;
    std::vector<signed char> side;
    std::vector<int> slot;
    unsigned call = 0;
  };
  thread_local Scratch w;
  if (w.vertex_stamp.size() < pos.size()) {
    w.vertex_stamp.resize(pos.size(), 0);
    w.side.resize(pos.size());
  }
  if (w.edge_stamp.size() < static_cast<size_t>(m.num_edges())) {
    w.edge_stamp.resize(m.num_edges(), 0);
    w.slot.resize(m.num_edges());
  }
  if (++w.call == 0) { // the stamps wrapped round: forget them all
    std::fill(w.vertex_stamp.begin(), w.vertex_stamp.end(), 0);
    std::fill(w.edge_stamp.begin(), w.edge_stamp.end(), 0);
    w.call = 1;
  }
  const unsigned call = w.call;
  auto side = [&](int i) {
    if (w.vertex_stamp[i] != call) {
      w.vertex_stamp[i] = call;
      w.side[i] = orient3d(origin, o1, o2, pos[i]) >= 0 ? 1 : -1; // on the plane counts as above
    }
    return w.side[i];
  };
  auto crosses = [&](int e) { return side(m.edge(e)[0]) != side(m.edge(e)[1]); };
  std::vector<int> cut; // the crossed edges, in increasing order
  for (int t : near)
    for (int e : m.tri_edges(t))
      if (w.edge_stamp[e] != call && crosses(e)) {
        w.edge_stamp[e] = call;
        cut.push_back(e);
      }
  std::sort(cut.begin(), cut.end());
  for (size_t k = 0; k < cut.size(); ++k)
    w.slot[cut[k]] = static_cast<int>(k);
  auto point_on = [&](int e) {
    const Vec3 &a = pos[m.edge(e)[0]], &b = pos[m.edge(e)[1]];
    const double da = (a - origin).dot(n), db = (b - origin).dot(n);
    const double s = da != db ? std::clamp(da / (da - db), 0.0, 1.0) : 0.5;
    return Vec3((1 - s) * a + s * b);
  };
  // Each triangle that the plane crosses holds one segment between two crossed edges.
  auto other_edge = [&](int t, int e) {
    for (int f : m.tri_edges(t))
      if (f != e && crosses(f))
        return f;
    return -1;
  };
  // An edge's place in `cut`. Every edge a walk crosses is in it (its
  // triangles straddle the plane); one more slot stands for any other.
  auto slot = [&](int e) { return w.edge_stamp[e] == call ? static_cast<size_t>(w.slot[e]) : cut.size(); };
  std::vector<char> used(cut.size() + 1, 0);
  std::vector<int> walked(cut.size() + 1, -1); // the walk that last crossed each edge
  int walks = 0;
  std::vector<Section> out;
  // From crossed edge `start` through triangle `tri`: the crossed edges in
  // order, and whether the walk came back to `start`. A walk that comes
  // back to another of its edges stops there, open: where an edge has more
  // than two triangles (the triangulations of two twisted n-gons can share
  // a diagonal) the walk could go round that loop for ever.
  auto trace = [&](int start, int tri, bool& closed) {
    std::vector<int> edges{start};
    closed = false;
    const int walk = walks++;
    walked[slot(start)] = walk;
    int e = start, t = tri;
    while (t >= 0) {
      const int next = other_edge(t, e);
      if (next < 0)
        break;
      if (next == start) {
        closed = true;
        break;
      }
      if (walked[slot(next)] == walk)
        break;
      walked[slot(next)] = walk;
      edges.push_back(next);
      const auto& tt = m.edge_tris(next);
      t = tt[0] == t ? tt[1] : tt[0];
      e = next;
    }
    return edges;
  };
  for (size_t k = 0; k < cut.size(); ++k) {
    const int e0 = cut[k];
    if (used[k])
      continue;
    const auto& tt = m.edge_tris(e0);
    bool closed = false;
    std::vector<int> edges = trace(e0, tt[0], closed);
    if (!closed && tt[1] >= 0) { // open: extend backwards from e0 through its other triangle
      bool unused = false;
      std::vector<int> back = trace(e0, tt[1], unused);
      std::reverse(back.begin(), back.end());
      back.pop_back();
      back.insert(back.end(), edges.begin(), edges.end());
      edges = std::move(back);
    }
    Section s;
    s.closed = closed;
    for (int e : edges) {
      used[slot(e)] = 1;
      s.points.push_back(point_on(e));
    }
    if (s.points.size() >= 2)
      out.push_back(std::move(s));
  }
  return out;
}

int winding_number(const std::vector<Vec3>& loop, const Vec3& p, const Vec3& origin, const Vec3& normal) {
  const auto [u, v] = plane_basis(normal);
  auto to2 = [&](const Vec3& q) { return Eigen::Vector2d((q - origin).dot(u), (q - origin).dot(v)); };
  const Eigen::Vector2d P = to2(p);
  int wn = 0;
  for (size_t i = 0; i < loop.size(); ++i) {
    const Eigen::Vector2d a = to2(loop[i]), b = to2(loop[(i + 1) % loop.size()]);
    if (a.y() <= P.y()) {
      if (b.y() > P.y() && orient2d(a, b, P) > 0)
        ++wn;
    } else if (b.y() <= P.y() && orient2d(a, b, P) < 0) {
      --wn;
    }
  }
  return wn;
}

std::optional<std::vector<Vec3>> section_path_through(const SectionMesh& mesh, const Vec3& a, const Vec3& m,
                                                      const Vec3& b, double tol) {
  const Vec3 n = (m - a).cross(b - a);
  if (!(n.norm() > 1e-12 * (m - a).norm() * (b - a).norm()))
    return std::nullopt;
  // Where a point lies along a polyline: segment i, fraction t; and how far off.
  struct At {
    size_t seg = 0;
    double t = 0, off = std::numeric_limits<double>::infinity();
    [[nodiscard]] double key() const { return static_cast<double>(seg) + t; }
  };
  for (const Section& s : plane_sections(mesh, a, n)) {
    const auto& p = s.points;
    const size_t segs = s.closed ? p.size() : p.size() - 1;
    if (p.size() < 2)
      continue;
    auto locate = [&](const Vec3& q) {
      At best;
      for (size_t i = 0; i < segs; ++i) {
        const Vec3 &u = p[i], &v = p[(i + 1) % p.size()];
        const double len2 = (v - u).squaredNorm();
        const double t = len2 > 0 ? std::clamp((q - u).dot(v - u) / len2, 0.0, 1.0) : 0.0;
        const double d = (u + t * (v - u) - q).norm();
        if (d < best.off)
          best = {i, t, d};
      }
      return best;
    };
    const At la = locate(a), lm = locate(m), lb = locate(b);
    if (la.off > tol || lm.off > tol || lb.off > tol)
      continue;
    // Keys along the section (segment + fraction), measured from a forward;
    // backward is forward on the reversed section.
    const double n_seg = static_cast<double>(segs);
    auto from_a = [&](const At& x, bool fwd) {
      const double d = fwd ? x.key() - la.key() : la.key() - x.key();
      return s.closed ? std::fmod(d + 2 * n_seg, n_seg) : d;
    };
    bool fwd = true;
    if (!(from_a(lm, true) >= 0 && from_a(lm, true) <= from_a(lb, true))) {
      fwd = false;
      if (!(from_a(lm, false) >= 0 && from_a(lm, false) <= from_a(lb, false)))
        continue; // m is not between a and b on this section
    }
    const double ka = la.key(), span = from_a(lb, fwd);
    std::vector<Vec3> path{a};
    const auto count = static_cast<long long>(p.size());
    const auto wrap = [&](long long j) { return p[static_cast<size_t>(((j % count) + count) % count)]; };
    if (fwd) // the vertices with keys in (ka, ka + span]
      for (long long j = static_cast<long long>(std::floor(ka)) + 1; j <= static_cast<long long>(std::floor(ka + span));
           ++j)
        path.push_back(wrap(j));
    else // the vertices with keys in [ka - span, ka)
      for (long long j = static_cast<long long>(std::ceil(ka)) - 1; j >= static_cast<long long>(std::ceil(ka - span));
           --j)
        path.push_back(wrap(j));
    path.push_back(b);
    // Without repeated points.
    std::vector<Vec3> clean{path.front()};
    for (size_t k = 1; k + 1 < path.size(); ++k)
      if ((path[k] - clean.back()).norm() > 0 && (path[k] - b).norm() > 0)
        clean.push_back(path[k]);
    clean.push_back(b);
    return clean;
  }
  return std::nullopt;
}

double polyline_distance(const std::vector<Vec3>& a, bool ca, const std::vector<Vec3>& b, bool cb) {
  double best = std::numeric_limits<double>::infinity();
  if (a.empty() || b.empty())
    return best;
  const size_t na = ca ? a.size() : a.size() - 1, nb = cb ? b.size() : b.size() - 1;
  // Each segment as a ball (its middle, half its length): two segments are
  // no closer than their middles' distance less both radii, so most pairs
  // are passed over without the exact distance.
  std::vector<Vec3> mid(nb);
  std::vector<double> rad(nb);
  for (size_t j = 0; j < nb; ++j) {
    const Vec3 &p = b[j], &q = b[(j + 1) % b.size()];
    mid[j] = (p + q) / 2;
    rad[j] = (q - p).norm() / 2;
  }
  for (size_t i = 0; i < na; ++i) {
    const Vec3 &p = a[i], &q = a[(i + 1) % a.size()];
    const Vec3 m = (p + q) / 2;
    const double r = (q - p).norm() / 2;
    for (size_t j = 0; j < nb; ++j)
      if ((m - mid[j]).norm() - r - rad[j] < best)
        best = std::min(best, segment_distance(p, q, b[j], b[(j + 1) % b.size()]));
  }
  return best;
}

bool polylines_within(const std::vector<Vec3>& a, bool ca, const std::vector<Vec3>& b, bool cb, double d) {
  if (a.empty() || b.empty() || !(d > 0))
    return false;
  Eigen::AlignedBox3d ba, bb;
  for (const Vec3& p : a)
    ba.extend(p);
  for (const Vec3& p : b)
    bb.extend(p);
  if (ba.exteriorDistance(bb) >= d)
    return false;
  const size_t na = ca ? a.size() : a.size() - 1, nb = cb ? b.size() : b.size() - 1;
  for (size_t i = 0; i < na; ++i) {
    const Vec3 &p = a[i], &q = a[(i + 1) % a.size()];
    const Vec3 m = (p + q) / 2;
    const double r = (q - p).norm() / 2;
    if (bb.exteriorDistance(Eigen::AlignedBox3d(p.cwiseMin(q), p.cwiseMax(q))) >= d)
      continue;
    for (size_t j = 0; j < nb; ++j) {
      const Vec3 &u = b[j], &v = b[(j + 1) % b.size()];
      if ((m - (u + v) / 2).norm() - r - (v - u).norm() / 2 >= d)
        continue;
      if (segment_distance(p, q, u, v) < d)
        return true;
    }
  }
  return false;
}

} // namespace curvenet::detail
