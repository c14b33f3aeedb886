#include "cut/cut_mesh.hpp"

#include "core/polygon.hpp"
#include "core/predicates.hpp"
#include "core/tolerances.hpp"
#include "curvenet/errors.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <limits>
#include <map>
#include <unordered_map>

namespace curvenet::detail {

Halfedge CutMesh::new_edge(Vertex a, Vertex b, int edge_origin) {
  const int h = num_halfedges();
  to_.push_back(b);
  to_.push_back(a);
  next_.resize(h + 2);
  prev_.resize(h + 2);
  face_.resize(h + 2);
  tag_.resize(h + 2);
  edge_origin_.push_back(edge_origin);
  return Halfedge(h);
}

CutMesh CutMesh::from_surface(const SurfaceMesh& mesh) {
  CutMesh m;
  const int nv = mesh.num_vertices();
  m.position_ = mesh.positions;
  m.vertex_origin_.resize(nv);
  for (int v = 0; v < nv; ++v)
    m.vertex_origin_[v] = {VertexOrigin::Kind::Input, v, 0};
  m.vertex_halfedge_.assign(nv, Halfedge());
  // Input edges, numbered in the order they are first met, face by face:
  // the corners grouped by their edge's smaller vertex (compressed rows),
  // and each corner's edge found among the few of its group.
  const int nf = mesh.num_faces();
  const size_t corners = mesh.face_vertices.size();
  auto corner_ends = [&](size_t c, int f) {
    const auto loop = mesh.face(f);
    const size_t first = static_cast<size_t>(mesh.face_offsets[f]);
    const size_t i = c - first;
    return std::pair<int, int>{loop[i], loop[(i + 1) % loop.size()]};
  };
  std::vector<int> corner_face(corners);
  for (int f = 0; f < nf; ++f)
    for (int c = mesh.face_offsets[f]; c < mesh.face_offsets[f + 1]; ++c)
      corner_face[c] = f;
  std::vector<int> group_offset(static_cast<size_t>(nv) + 1, 0), group(corners), group_hi(corners);
  for (size_t c = 0; c < corners; ++c) {
    const auto [a, b] = corner_ends(c, corner_face[c]);
    ++group_offset[std::min(a, b) + 1];
  }
  for (int v = 0; v < nv; ++v)
    group_offset[v + 1] += group_offset[v];
  {
    std::vector<int> fill(group_offset.begin(), group_offset.end() - 1);
    for (size_t c = 0; c < corners; ++c) {
      const auto [a, b] = corner_ends(c, corner_face[c]);
      group_hi[fill[std::min(a, b)]] = std::max(a, b); // beside the corner: the scan below reads one run
      group[fill[std::min(a, b)]++] = static_cast<int>(c);
    }
  }
  std::vector<int> corner_edge(corners, -1);
  m.to_.reserve(corners + 16);
  m.next_.reserve(corners + 16);
  m.prev_.reserve(corners + 16);
  m.face_.reserve(corners + 16);
  m.tag_.reserve(corners + 16);
  m.edge_origin_.reserve(corners / 2 + 8);
  std::vector<Halfedge> loop;
  for (int f = 0; f < nf; ++f) {
    auto c = mesh.face(f);
    const int n = static_cast<int>(c.size());
    loop.clear();
    for (int i = 0; i < n; ++i) {
      const size_t corner = static_cast<size_t>(mesh.face_offsets[f] + i);
      const int a = c[i], b = c[(i + 1) % n];
      const int lo = std::min(a, b), hi = std::max(a, b);
      // The first corner of this edge, in face order (corners are numbered so).
      int first = static_cast<int>(corner);
      for (int g = group_offset[lo]; g < group_offset[lo + 1]; ++g)
        if (group_hi[g] == hi && group[g] < first)
          first = group[g];
      int e = corner_edge[first];
      if (e < 0) {
        e = m.num_edges();
        m.new_edge(Vertex(a), Vertex(b), e);
        m.input_edge_ends_.push_back({a, b});
      }
      corner_edge[corner] = e;
      Halfedge h(2 * e);
      if (m.to(h) != Vertex(b))
        h = twin(h);
      if (m.face_[h.idx].is_valid())
        throw TopologyError("input edge used twice in one direction");
      m.face_[h.idx] = Face(f);
      loop.push_back(h);
    }
    for (int i = 0; i < n; ++i) {
      m.next_[loop[i].idx] = loop[(i + 1) % n];
      m.prev_[loop[(i + 1) % n].idx] = loop[i];
    }
    m.face_halfedge_.push_back(loop[0]);
    m.face_origin_.push_back(f);
    m.input_first_corner_.push_back(c[0]);
  }
  // Boundary loops and vertex half-edges (a boundary one where there is one).
  std::vector<Halfedge> boundary_out(nv);
  for (int h = 0; h < m.num_halfedges(); ++h) {
    const Vertex a = m.from(Halfedge(h));
    if (!m.face_[h].is_valid())
      boundary_out[a.idx] = Halfedge(h);
    if (!m.vertex_halfedge_[a.idx].is_valid())
      m.vertex_halfedge_[a.idx] = Halfedge(h);
  }
  for (int h = 0; h < m.num_halfedges(); ++h) {
    if (m.face_[h].is_valid())
      continue;
    const Halfedge n = boundary_out[m.to(Halfedge(h)).idx];
    m.next_[h] = n;
    m.prev_[n.idx] = Halfedge(h);
  }
  for (int v = 0; v < nv; ++v)
    if (boundary_out[v].is_valid())
      m.vertex_halfedge_[v] = boundary_out[v];
  return m;
}

std::vector<ComponentInfo> input_components(const CutMesh& m, std::vector<int>& face_component) {
  const int nf = m.num_faces();
  std::vector<int> parent(nf);
  for (int f = 0; f < nf; ++f)
    parent[f] = f;
  auto find = [&](int x) {
    while (parent[x] != x)
      x = parent[x] = parent[parent[x]];
    return x;
  };
  for (int e = 0; e < m.num_edges(); ++e) {
    const Face a = m.face(Halfedge(2 * e)), b = m.face(Halfedge(2 * e + 1));
    if (a.is_valid() && b.is_valid()) {
      const int ra = find(a.idx), rb = find(b.idx);
      if (ra != rb)
        parent[std::max(ra, rb)] = std::min(ra, rb);
    }
  }
  // Number the components by their first face.
  std::vector<int> id(nf, -1);
  face_component.assign(nf, -1);
  std::vector<ComponentInfo> out;
  for (int f = 0; f < nf; ++f) {
    const int r = find(f);
    if (id[r] < 0) {
      id[r] = static_cast<int>(out.size());
      out.emplace_back();
    }
    face_component[f] = id[r];
    out[id[r]].faces++;
  }
  std::vector<int> nverts(out.size(), 0), nedges(out.size(), 0);
  std::vector<char> open(out.size(), 0);
  for (int e = 0; e < m.num_edges(); ++e) {
    const Halfedge h(2 * e);
    const Face f = m.face(h).is_valid() ? m.face(h) : m.face(CutMesh::twin(h));
    const int c = face_component[f.idx];
    nedges[c]++;
    if (m.is_boundary(h) || m.is_boundary(CutMesh::twin(h)))
      open[c] = 1;
  }
  for (int v = 0; v < m.num_vertices(); ++v) {
    const Halfedge h = m.halfedge(Vertex(v));
    if (!h.is_valid())
      continue;
    const Face f = m.face(h).is_valid() ? m.face(h) : m.face(CutMesh::twin(h));
    nverts[face_component[f.idx]]++;
  }
  for (size_t c = 0; c < out.size(); ++c) {
    out[c].closed = !open[c];
    out[c].euler = nverts[c] - nedges[c] + out[c].faces;
  }
  return out;
}

void CutMesh::set_tag(Halfedge h, CurveTag t) {
  tag_[h.idx] = t;
  tag_[h.idx ^ 1] = CurveTag{t.profile, !t.forward};
}

std::vector<Halfedge> CutMesh::face_loop(Face f) const {
  std::vector<Halfedge> loop;
  face_loop(f, loop);
  return loop;
}

void CutMesh::face_loop(Face f, std::vector<Halfedge>& loop) const {
  loop.clear();
  const Halfedge start = face_halfedge_[f.idx];
  Halfedge h = start;
  do {
    loop.push_back(h);
    h = next(h);
    if (static_cast<int>(loop.size()) > num_halfedges())
      throw TopologyError("face loop does not close");
  } while (h != start);
}

std::vector<Halfedge> CutMesh::outgoing(Vertex v) const {
  std::vector<Halfedge> out;
  const Halfedge start = vertex_halfedge_[v.idx];
  if (!start.is_valid())
    return out;
  Halfedge h = start;
  do {
    out.push_back(h);
    h = next(twin(h));
    if (static_cast<int>(out.size()) > num_halfedges())
      throw TopologyError("vertex rotation does not close");
  } while (h != start);
  return out;
}

Eigen::Vector3d CutMesh::face_normal(Face f) const {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  const Halfedge start = face_halfedge_[f.idx];
  Halfedge h = start;
  int steps = 0;
  do { // the loop walked in place (face_loop would allocate)
    n += position(from(h)).cross(position(to(h)));
    h = next(h);
    if (++steps > num_halfedges())
      throw TopologyError("face loop does not close");
  } while (h != start);
  return n;
}

double CutMesh::face_area(Face f) const {
  return 0.5 * face_normal(f).norm();
}

Vertex CutMesh::split_edge(Halfedge h, const Eigen::Vector3d& pos, const VertexOrigin& origin) {
  const Vertex v(num_vertices());
  position_.push_back(pos);
  vertex_origin_.push_back(origin);
  vertex_halfedge_.emplace_back();
  const Halfedge t = twin(h);
  const Vertex w = to(h);
  const Halfedge hn = next(h), tp = prev(t);
  const Halfedge n = new_edge(v, w, edge_origin_[h.idx / 2]); // n: v -> w, twin(n): w -> v
  const Halfedge nt = twin(n);
  to_[h.idx] = v; // h: u -> v; t keeps to() == u and now starts at v
  // Face of h: ... h -> n -> hn ...
  face_[n.idx] = face_[h.idx];
  next_[h.idx] = n;
  prev_[n.idx] = h;
  next_[n.idx] = hn;
  prev_[hn.idx] = n;
  // Face of t: ... tp -> nt -> t ...
  face_[nt.idx] = face_[t.idx];
  next_[tp.idx] = nt;
  prev_[nt.idx] = tp;
  next_[nt.idx] = t;
  prev_[t.idx] = nt;
  tag_[n.idx] = tag_[h.idx];
  tag_[nt.idx] = tag_[t.idx];
  if (vertex_halfedge_[w.idx] == t)
    vertex_halfedge_[w.idx] = nt;
  vertex_halfedge_[v.idx] = is_boundary(t) ? t : n;
  return v;
}

Vertex CutMesh::add_isolated_vertex(const Eigen::Vector3d& pos, const VertexOrigin& origin) {
  position_.push_back(pos);
  vertex_origin_.push_back(origin);
  vertex_halfedge_.emplace_back();
  return Vertex(num_vertices() - 1);
}

const CutMesh::Layout& CutMesh::layout(Face f) const {
  const int input_face = face_origin_[f.idx];
  if (auto it = layouts_.find(input_face); it != layouts_.end())
    return it->second;
  // The input face's corners, in the tracer's order: from the input face's
  // first corner (a split of an edge can move the start of the loop, and
  // how a polygon that is far from flat is triangulated depends on where
  // its corners start).
  Layout l;
  for (Halfedge h : face_loop(f))
    if (origin(from(h)).kind == VertexOrigin::Kind::Input)
      l.corners.push_back(from(h).idx);
  const auto first = std::find(l.corners.begin(), l.corners.end(), input_first_corner_[input_face]);
  if (first == l.corners.end())
    throw TopologyError("cut: face " + std::to_string(input_face) + " lost its first corner");
  std::rotate(l.corners.begin(), first, l.corners.end());
  std::vector<Eigen::Vector3d> pts;
  for (int v : l.corners)
    pts.push_back(position(Vertex(v)));
  l.tris = triangulate_polygon(pts);
  // Unfold the triangles across their shared diagonals (the dual of a
  // polygon's triangulation is a tree), each placed by its edge lengths.
  l.uv.assign(pts.size(), Eigen::Vector2d::Zero());
  std::vector<char> placed(pts.size(), 0), done(l.tris.size(), 0);
  const auto& t0 = l.tris[0];
  l.uv[t0[1]] = {(pts[t0[1]] - pts[t0[0]]).norm(), 0};
  placed[t0[0]] = placed[t0[1]] = 1;
  for (size_t round = 0; round < l.tris.size(); ++round)
    for (size_t t = 0; t < l.tris.size(); ++t) {
      const auto& c = l.tris[t];
      if (done[t])
        continue;
      for (int k = 0; k < 3; ++k) {
        const int a = c[k], b = c[(k + 1) % 3], x = c[(k + 2) % 3];
        if (!placed[a] || !placed[b])
          continue;
        // x to the left of a -> b (the triangle is counter-clockwise).
        const Eigen::Vector2d ab = l.uv[b] - l.uv[a];
        const double len = ab.norm(), ax = (pts[x] - pts[a]).norm(), bx = (pts[x] - pts[b]).norm();
        const double along = (ax * ax - bx * bx + len * len) / (2 * len);
        const double across = std::sqrt(std::max(0.0, ax * ax - along * along));
        const Eigen::Vector2d dir = ab / len, left(-dir.y(), dir.x());
        if (!placed[x])
          l.uv[x] = l.uv[a] + along * dir + across * left;
        placed[x] = 1;
        done[t] = 1;
        break;
      }
    }
  return layouts_.emplace(input_face, std::move(l)).first->second;
}

Eigen::Vector2d CutMesh::to_face_plane(Face f, Vertex v) const {
  const Layout& l = layout(f);
  auto corner = [&](int input_vertex) {
    const auto it = std::find(l.corners.begin(), l.corners.end(), input_vertex);
    return it == l.corners.end() ? -1 : static_cast<int>(it - l.corners.begin());
  };
  const VertexOrigin& o = origin(v);
  if (o.kind == VertexOrigin::Kind::Input)
    if (const int i = corner(o.index); i >= 0)
      return l.uv[i];
  if (o.kind == VertexOrigin::Kind::OnEdge) {
    const int a = corner(input_edge_ends_[o.index][0]), b = corner(input_edge_ends_[o.index][1]);
    if (a >= 0 && b >= 0)
      return (1 - o.t) * l.uv[a] + o.t * l.uv[b];
  }
  return to_face_plane(f, position(v));
}

std::pair<std::array<int, 3>, std::array<double, 3>> CutMesh::nearest_triangle(const Layout& l,
                                                                               const Eigen::Vector3d& p) const {
  double best = std::numeric_limits<double>::infinity();
  std::pair<std::array<int, 3>, std::array<double, 3>> out{{0, 0, 0}, {1, 0, 0}};
  for (const auto& c : l.tris) {
    const TriClosest cl = closest_on_triangle(p, position(Vertex(l.corners[c[0]])), position(Vertex(l.corners[c[1]])),
                                              position(Vertex(l.corners[c[2]])));
    const double d = (cl.point - p).squaredNorm();
    if (d < best) {
      best = d;
      out = {c, cl.bary};
    }
  }
  return out;
}

Eigen::Vector2d CutMesh::to_face_plane(Face f, const Eigen::Vector3d& p) const {
  // Through the nearest of the face's triangles.
  const Layout& l = layout(f);
  if (l.tris.empty())
    return Eigen::Vector2d::Zero();
  const auto [c, bary] = nearest_triangle(l, p);
  return bary[0] * l.uv[c[0]] + bary[1] * l.uv[c[1]] + bary[2] * l.uv[c[2]];
}

std::vector<Eigen::Vector3d> CutMesh::detour(Face f, Vertex a, Vertex b) const {
  const Layout& l = layout(f);
  if (l.tris.size() < 2)
    return {};
  const Eigen::Vector2d A = to_face_plane(f, a), B = to_face_plane(f, b);
  // The triangles of a and b, and the path between them in the
  // triangulation's dual tree.
  auto triangle_of = [&](Vertex v) {
    const auto [c, bary] = nearest_triangle(l, position(v));
    return static_cast<int>(std::find(l.tris.begin(), l.tris.end(), c) - l.tris.begin());
  };
  const int ta = triangle_of(a), tb = triangle_of(b), nt = static_cast<int>(l.tris.size());
  auto shared = [&](int s, int t, std::array<int, 2>& edge) {
    int k = 0;
    for (int x : l.tris[s])
      if (std::find(l.tris[t].begin(), l.tris[t].end(), x) != l.tris[t].end() && k < 2)
        edge[k++] = x;
    return k == 2;
  };
  std::vector<int> from(nt, -1);
  std::vector<int> queue{ta};
  from[ta] = ta;
  for (size_t q = 0; q < queue.size(); ++q)
    for (int t = 0; t < nt; ++t) {
      std::array<int, 2> e{};
      if (from[t] < 0 && shared(queue[q], t, e)) {
        from[t] = queue[q];
        queue.push_back(t);
      }
    }
  if (ta == tb || from[tb] < 0)
    return {};
  std::vector<int> path{tb};
  while (path.back() != ta)
    path.push_back(from[path.back()]);
  std::reverse(path.begin(), path.end());
  std::vector<Eigen::Vector3d> out;
  for (size_t k = 0; k + 1 < path.size(); ++k) {
    std::array<int, 2> e{};
    shared(path[k], path[k + 1], e);
    // Where the chord's line meets the diagonal, kept inside it (away from
    // its corners, so that no sliver is cut).
    const Eigen::Vector2d P = l.uv[e[0]], D = l.uv[e[1]] - P, AB = B - A;
    const double den = AB.x() * D.y() - AB.y() * D.x();
    double s = 0.5;
    if (den != 0)
      s = ((P.x() - A.x()) * AB.y() - (P.y() - A.y()) * AB.x()) / den;
    s = std::clamp(std::isfinite(s) ? s : 0.5, Tolerances::detour_margin, 1 - Tolerances::detour_margin);
    out.push_back((1 - s) * position(Vertex(l.corners[e[0]])) + s * position(Vertex(l.corners[e[1]])));
  }
  return out;
}

std::vector<std::pair<int, double>> CutMesh::input_weights(Vertex v) const {
  const VertexOrigin& o = origin(v);
  if (o.kind == VertexOrigin::Kind::Input)
    return {{o.index, 1.0}};
  if (o.kind == VertexOrigin::Kind::OnEdge)
    return {{input_edge_ends_[o.index][0], 1 - o.t}, {input_edge_ends_[o.index][1], o.t}};
  const auto it = layouts_.find(o.index); // a face with a vertex inside was laid out when it was split
  if (it == layouts_.end())
    throw Error("cut mesh: vertex " + std::to_string(v.idx) + " lies inside input face " + std::to_string(o.index) +
                ", which was never laid out");
  const Layout& l = it->second;
  if (l.tris.empty())
    return {};
  const auto [c, bary] = nearest_triangle(l, position(v));
  return {{l.corners[c[0]], bary[0]}, {l.corners[c[1]], bary[1]}, {l.corners[c[2]], bary[2]}};
}

std::vector<Halfedge> CutMesh::subdivide_face(Face f, std::span<const Chord> chords) {
  const std::vector<Halfedge> loop = face_loop(f);
  (void)layout(f); // fixed now, from the whole face, and inherited by its pieces
  struct Spoke {
    Vertex other;
    Halfedge out; // invalid: the outside of the face (incoming boundary only)
  };
  std::map<int, std::vector<Spoke>> spokes;
  std::vector<Halfedge> local;
  for (Halfedge h : loop) {
    if (spokes.count(from(h).idx) && !spokes[from(h).idx].empty() &&
        std::any_of(spokes[from(h).idx].begin(), spokes[from(h).idx].end(),
                    [](const Spoke& s) { return s.out.is_valid(); }))
      throw TopologyError("subdivide_face: face " + std::to_string(f.idx) + " visits a vertex twice");
    spokes[from(h).idx].push_back({to(h), h});
    spokes[to(h).idx].push_back({from(h), Halfedge()});
    local.push_back(h);
  }
  std::vector<Halfedge> result;
  for (const Chord& c : chords) {
    const Halfedge h = new_edge(c.a, c.b, -1);
    set_tag(h, c.tag);
    spokes[c.a.idx].push_back({c.b, h});
    spokes[c.b.idx].push_back({c.a, twin(h)});
    local.push_back(h);
    local.push_back(twin(h));
    result.push_back(h);
  }
  // Sort each vertex's spokes counter-clockwise by exact angle comparisons.
  for (auto& [vi, list] : spokes) {
    const Eigen::Vector2d c = to_face_plane(f, Vertex(vi));
    std::vector<Eigen::Vector2d> pts;
    for (const Spoke& s : list)
      pts.push_back(to_face_plane(f, s.other));
    auto upper = [&](const Eigen::Vector2d& p) { return !(p.y() < c.y() || (p.y() == c.y() && p.x() < c.x())); };
    std::vector<int> order(list.size());
    for (size_t i = 0; i < order.size(); ++i)
      order[i] = static_cast<int>(i);
    std::sort(order.begin(), order.end(), [&](int a, int b) {
      const bool ua = upper(pts[a]), ub = upper(pts[b]);
      if (ua != ub)
        return ua;
      return orient2d(c, pts[a], pts[b]) > 0;
    });
    std::vector<Spoke> sorted;
    for (int i : order)
      sorted.push_back(list[i]);
    list = std::move(sorted);
  }
  // next(h) for h arriving at v from u: the spoke just clockwise of u's.
  std::unordered_map<int, Halfedge> next_of;
  for (Halfedge h : local) {
    const Vertex u = from(h), v = to(h);
    const auto& list = spokes[v.idx];
    const bool on_loop = std::find(loop.begin(), loop.end(), h) != loop.end();
    int at = -1;
    for (size_t i = 0; i < list.size(); ++i)
      if (list[i].out.is_valid() ? list[i].out == twin(h) : (on_loop && list[i].other == u))
        at = static_cast<int>(i);
    if (at < 0)
      throw TopologyError("subdivide_face: missing spoke");
    const Spoke& cw = list[(at + list.size() - 1) % list.size()];
    if (!cw.out.is_valid())
      throw EmbedError("cut: a profile segment leaves input face " + std::to_string(face_origin_[f.idx]) +
                       " (cut face " + std::to_string(f.idx) + ") at vertex " + std::to_string(v.idx));
    next_of[h.idx] = cw.out;
  }
  // Trace the new loops.
  std::unordered_map<int, char> seen;
  bool first = true;
  const int origin = face_origin_[f.idx];
  for (Halfedge start : local) {
    if (seen[start.idx])
      continue;
    std::vector<Halfedge> piece;
    Halfedge h = start;
    do {
      if (seen[h.idx])
        throw EmbedError("cut: the profile segments in input face " + std::to_string(origin) +
                         " do not form simple faces");
      seen[h.idx] = 1;
      piece.push_back(h);
      h = next_of.at(h.idx);
    } while (h != start);
    // Twice the signed area, relative to the first corner (no cancellation
    // between large coordinates when the piece is a sliver).
    double area2 = 0;
    const Eigen::Vector2d o = to_face_plane(f, from(piece[0]));
    for (Halfedge g : piece) {
      const Eigen::Vector2d p = to_face_plane(f, from(g)) - o, q = to_face_plane(f, to(g)) - o;
      area2 += p.x() * q.y() - p.y() * q.x();
    }
    if (!(area2 > 0))
      throw EmbedError("cut: profile segments inside input face " + std::to_string(origin) +
                       " do not reach its boundary or cross it (a piece with no positive area)");
    Face pf = f;
    if (!first) {
      pf = Face(num_faces());
      face_halfedge_.emplace_back();
      face_origin_.push_back(origin);
    }
    first = false;
    face_halfedge_[pf.idx] = piece[0];
    for (size_t i = 0; i < piece.size(); ++i) {
      face_[piece[i].idx] = pf;
      next_[piece[i].idx] = piece[(i + 1) % piece.size()];
      prev_[piece[(i + 1) % piece.size()].idx] = piece[i];
    }
  }
  for (const Chord& c : chords)
    for (Vertex v : {c.a, c.b})
      if (!vertex_halfedge_[v.idx].is_valid()) {
        for (Halfedge h : result) {
          if (from(h) == v)
            vertex_halfedge_[v.idx] = h;
          if (to(h) == v)
            vertex_halfedge_[v.idx] = twin(h);
        }
      }
  return result;
}

std::optional<std::string> CutMesh::validate() const {
  const int nh = num_halfedges();
  auto he = [](int h) { return "half-edge " + std::to_string(h); };
  for (int h = 0; h < nh; ++h) {
    const Halfedge H(h);
    if (!to_[h].is_valid() || to_[h].idx >= num_vertices())
      return he(h) + ": invalid target vertex";
    if (to_[h] == to_[h ^ 1])
      return he(h) + ": both ends are the same vertex";
    if (!next_[h].is_valid() || !prev_[h].is_valid())
      return he(h) + ": next or prev missing";
    if (prev(next(H)) != H)
      return he(h) + ": prev(next(h)) != h";
    if (next(prev(H)) != H)
      return he(h) + ": next(prev(h)) != h";
    if (from(next(H)) != to(H))
      return he(h) + ": next(h) does not start where h ends";
    if (face(next(H)) != face(H))
      return he(h) + ": next(h) lies in another face";
    if (face(H).is_valid() && face(H).idx >= num_faces())
      return he(h) + ": invalid face";
    const CurveTag a = tag_[h], b = tag_[h ^ 1];
    if (a.profile != b.profile || (a.is_curve() && a.forward == b.forward))
      return he(h) + ": curve tag differs from its twin's";
  }
  std::vector<int> count(num_faces(), 0);
  for (int h = 0; h < nh; ++h)
    if (face_[h].is_valid())
      count[face_[h].idx]++;
  for (int f = 0; f < num_faces(); ++f) {
    const Halfedge start = face_halfedge_[f];
    if (!start.is_valid() || face(start) != Face(f))
      return "face " + std::to_string(f) + ": its half-edge lies in another face";
    int n = 0;
    Halfedge h = start;
    do {
      if (face(h) != Face(f))
        return "face " + std::to_string(f) + ": loop leaves the face";
      h = next(h);
      if (++n > nh)
        return "face " + std::to_string(f) + ": loop does not close";
    } while (h != start);
    if (n != count[f])
      return "face " + std::to_string(f) + ": " + std::to_string(count[f] - n) + " half-edges are not on its loop";
    if (n < 2)
      return "face " + std::to_string(f) + ": fewer than 2 half-edges";
  }
  for (int v = 0; v < num_vertices(); ++v) {
    const Halfedge h = vertex_halfedge_[v];
    if (h.is_valid() && from(h) != Vertex(v))
      return "vertex " + std::to_string(v) + ": its half-edge starts elsewhere";
  }
  return std::nullopt;
}

} // namespace curvenet::detail
