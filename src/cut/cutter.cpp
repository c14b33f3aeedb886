#include "cut/cutter.hpp"

#include "core/predicates.hpp"
#include "curvenet/errors.hpp"

#include <algorithm>
#include <map>
#include <set>

namespace curvenet::detail {
namespace {

using Kind = SurfacePoint::Kind;

struct EdgeSplit {
  double t;
  int owner_profile; // -1 for a node
  int owner_node;
  Vertex vertex;
};

/// Input edges that contain a surface point.
std::vector<int> edges_of(const TraceMesh& tm, const SurfacePoint& p) {
  if (p.kind == Kind::Edge)
    return {p.edge};
  if (p.kind != Kind::Vertex)
    return {};
  const auto l = tm.vertex_edges(p.vertex);
  return {l.begin(), l.end()};
}

int seg_cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c, const Eigen::Vector2d& d) {
  // 1 when the closed segments ab and cd intersect, 0 otherwise.
  const int o1 = orient2d(a, b, c), o2 = orient2d(a, b, d), o3 = orient2d(c, d, a), o4 = orient2d(c, d, b);
  if (o1 * o2 < 0 && o3 * o4 < 0)
    return 1;
  auto on = [](const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& r) {
    return std::min(p.x(), q.x()) <= r.x() && r.x() <= std::max(p.x(), q.x()) && std::min(p.y(), q.y()) <= r.y() &&
           r.y() <= std::max(p.y(), q.y());
  };
  if (o1 == 0 && on(a, b, c))
    return 1;
  if (o2 == 0 && on(a, b, d))
    return 1;
  if (o3 == 0 && on(c, d, a))
    return 1;
  if (o4 == 0 && on(c, d, b))
    return 1;
  return 0;
}

} // namespace

CutResult cut_mesh(CutMesh& mesh, const TraceMesh& tm, const CutInput& in,
                   const std::function<void()>& after_mutation) {
  auto mutated = [&] {
    if (after_mutation)
      after_mutation();
  };
  const int nn = static_cast<int>(in.node_points.size());
  const int np = static_cast<int>(in.traces.size());
  CutResult res;
  res.node_vertex.assign(nn, Vertex());
  res.chains.resize(np);

  std::vector<char> node_used(nn, 0);
  for (int p = 0; p < np; ++p)
    node_used[in.profile_from[p]] = node_used[in.profile_to[p]] = 1;

  std::map<int, std::vector<EdgeSplit>> splits; // input edge -> splits
  std::map<int, std::vector<int>> interior;     // input face -> nodes inside it
  std::map<int, int> vertex_node;               // input vertex -> node on it
  auto describe_edge = [&](int e) {
    const auto ends = tm.edge_ends(e);
    return "input edge " + std::to_string(ends[0]) + "-" + std::to_string(ends[1]);
  };

  // 1. Nodes first, each as one vertex.
  for (int i = 0; i < nn; ++i) {
    if (!node_used[i])
      continue;
    const SurfacePoint& sp = in.node_points[i];
    if (sp.kind == Kind::Vertex) {
      auto [it, fresh] = vertex_node.emplace(sp.vertex, i);
      if (!fresh)
        throw EmbedError("cut: nodes '" + in.node_ids[it->second] + "' and '" + in.node_ids[i] +
                         "' land on the same input vertex " + std::to_string(sp.vertex));
      res.node_vertex[i] = Vertex(sp.vertex);
    } else if (sp.kind == Kind::Edge) {
      splits[sp.edge].push_back({sp.t, -1, i, Vertex()});
    } else {
      interior[tm.tri_face(sp.tri)].push_back(i);
    }
  }
  // 2. Claim every vertex hit and edge crossing for its profile.
  std::map<int, int> vertex_owner; // input vertex -> profile
  for (int p = 0; p < np; ++p) {
    const auto& pts = in.traces[p].points;
    for (size_t k = 1; k + 1 < pts.size(); ++k) {
      const SurfacePoint& sp = pts[k].at;
      if (sp.kind == Kind::Vertex) {
        if (auto it = vertex_node.find(sp.vertex); it != vertex_node.end())
          throw EmbedError("cut: profile '" + in.profile_ids[p] + "' passes through node '" + in.node_ids[it->second] +
                           "' near sample " + std::to_string(pts[k].sample) + ", which is not one of its ends");
        auto [it, fresh] = vertex_owner.emplace(sp.vertex, p);
        if (!fresh)
          throw ProfilesMeet("cut: profiles '" + in.profile_ids[it->second] + "' and '" + in.profile_ids[p] +
                                 "' touch at input vertex " + std::to_string(sp.vertex) +
                                 ", away from any node (sample " + std::to_string(pts[k].sample) + " of '" +
                                 in.profile_ids[p] + "')",
                             it->second, p, sp.pos, "input vertex " + std::to_string(sp.vertex));
      } else if (sp.kind == Kind::Edge) {
        splits[sp.edge].push_back({sp.t, p, -1, Vertex()});
      }
    }
  }
  // 3. Split the edges, in order along each edge.
  for (auto& [e, list] : splits) {
    std::sort(list.begin(), list.end(), [](const EdgeSplit& a, const EdgeSplit& b) { return a.t < b.t; });
    for (size_t i = 1; i < list.size(); ++i)
      if (list[i].t == list[i - 1].t) {
        auto name = [&](const EdgeSplit& s) {
          return s.owner_profile >= 0 ? "profile '" + in.profile_ids[s.owner_profile] + "'"
                                      : "node '" + in.node_ids[s.owner_node] + "'";
        };
        const std::string what = "cut: " + name(list[i - 1]) + " and " + name(list[i]) + " cross " + describe_edge(e) +
                                 " at the same point, away from any node";
        const auto ends = tm.edge_ends(e);
        const Vec3 at = (1 - list[i].t) * tm.position(ends[0]) + list[i].t * tm.position(ends[1]);
        if (list[i].owner_profile >= 0 && list[i - 1].owner_profile >= 0)
          throw ProfilesMeet(what, list[i - 1].owner_profile, list[i].owner_profile, at, describe_edge(e));
        throw EmbedError(what);
      }
    const auto ends = tm.edge_ends(e);
    Halfedge h(2 * e);
    for (auto& s : list) {
      const Vec3 pos = (1 - s.t) * tm.position(ends[0]) + s.t * tm.position(ends[1]);
      s.vertex = mesh.split_edge(h, pos, {VertexOrigin::Kind::OnEdge, e, s.t});
      if (s.owner_node >= 0)
        res.node_vertex[s.owner_node] = s.vertex;
      h = mesh.next(h);
      mutated();
    }
  }
  // Who owns each cut vertex: a profile (a crossing or vertex hit), or a node.
  std::map<int, int> owner; // cut vertex -> profile, or -1 for a node
  for (const auto& [e, list] : splits)
    for (const auto& sp : list)
      owner[sp.vertex.idx] = sp.owner_profile;
  for (const auto& [v, p] : vertex_owner)
    owner[v] = p;
  for (const auto& [v, n] : vertex_node)
    owner[v] = -1;
  auto edge_vertex = [&](int e, double t) {
    const auto it = splits.find(e);
    if (it == splits.end())
      throw TopologyError("cut: a path point on " + describe_edge(e) + " was never split into it");
    for (const auto& s : it->second)
      if (s.t == t)
        return s.vertex;
    throw TopologyError("cut: lost the split of an edge");
  };
  // Interior nodes become isolated vertices, connected when their face is split.
  for (auto& [f, nodes] : interior)
    for (int i : nodes) {
      const SurfacePoint& sp = in.node_points[i];
      res.node_vertex[i] = mesh.add_isolated_vertex(sp.pos, {VertexOrigin::Kind::InFace, f, 0});
    }
  // A sample inside a face becomes a vertex of its own there (called once
  // per path point).
  auto vertex_of = [&](const PathPoint& pp) {
    if (pp.node >= 0)
      return res.node_vertex[pp.node];
    if (pp.at.kind == Kind::Vertex)
      return Vertex(pp.at.vertex);
    if (pp.at.kind == Kind::Edge)
      return edge_vertex(pp.at.edge, pp.at.t);
    return mesh.add_isolated_vertex(pp.at.pos, {VertexOrigin::Kind::InFace, tm.tri_face(pp.at.tri), 0});
  };
  auto t_on_edge = [&](Vertex v, int e) {
    const VertexOrigin& o = mesh.origin(v);
    if (o.kind == VertexOrigin::Kind::OnEdge)
      return o.t;
    return tm.edge_ends(e)[0] == v.idx ? 0.0 : 1.0;
  };

  // 4. Walk each profile: runs along input edges are tagged now; segments
  //    across faces are collected per face.
  struct PendingChord {
    int profile;
    size_t slot; // index into the chain's half-edges
    Chord chord;
  };
  std::map<int, std::vector<PendingChord>> chords; // input face -> chords
  for (int p = 0; p < np; ++p) {
    const auto& pts = in.traces[p].points;
    CutChain& chain = res.chains[p];
    chain.vertices.push_back(vertex_of(pts[0]));
    chain.point.push_back(0);
    for (size_t k = 1; k < pts.size(); ++k) {
      const Vertex va = chain.vertices.back(), vb = vertex_of(pts[k]);
      if (va == vb)
        continue;
      const PathPoint &a = pts[k - 1], &b = pts[k];
      // Along an input edge?
      int along = -1;
      for (int e : edges_of(tm, a.at))
        for (int g : edges_of(tm, b.at))
          if (e == g)
            along = e;
      if (along >= 0) {
        const double ta = t_on_edge(va, along), tb = t_on_edge(vb, along);
        Vertex cur = va;
        int guard = 0;
        while (cur != vb) {
          Halfedge step;
          for (Halfedge h : mesh.outgoing(cur)) {
            if (mesh.edge_origin(h) != along)
              continue;
            const double tn = t_on_edge(mesh.to(h), along);
            if ((tb > ta) == (tn > t_on_edge(cur, along)))
              step = h;
          }
          if (!step.is_valid() || ++guard > mesh.num_halfedges())
            throw TopologyError("cut: lost the way along " + describe_edge(along));
          if (mesh.tag(step).is_curve())
            throw ProfilesMeet("cut: profiles '" + in.profile_ids[mesh.tag(step).profile] + "' and '" +
                                   in.profile_ids[p] + "' run along the same part of " + describe_edge(along),
                               mesh.tag(step).profile, p, (mesh.position(cur) + mesh.position(mesh.to(step))) / 2,
                               describe_edge(along));
          mesh.set_tag(step, {p, true});
          chain.halfedges.push_back(step);
          cur = mesh.to(step);
          if (cur != vb)
            if (auto it = owner.find(cur.idx); it != owner.end() && it->second != p) {
              const std::string what =
                  "cut: profiles '" + in.profile_ids[p] + "' and " +
                  (it->second >= 0 ? "'" + in.profile_ids[it->second] + "'" : std::string("a node")) + " touch on " +
                  describe_edge(along) + ", away from any node";
              if (it->second >= 0)
                throw ProfilesMeet(what, it->second, p, mesh.position(cur), describe_edge(along));
              throw EmbedError(what);
            }
          chain.vertices.push_back(cur);
          chain.point.push_back(static_cast<int>(k));
        }
        continue;
      }
      std::vector<int> fa = tm.faces_of(a.at), fb = tm.faces_of(b.at), common;
      std::set_intersection(fa.begin(), fa.end(), fb.begin(), fb.end(), std::back_inserter(common));
      if (common.empty())
        throw EmbedError("cut: profile '" + in.profile_ids[p] + "', sample " + std::to_string(b.sample) +
                         ": consecutive path points share no input face");
      // A straight chord that would leave a face whose layout is not
      // convex (a bent quad) passes inside it, over the diagonals between
      // (checked as step 5 checks chords against the face's boundary).
      const int f = common[0];
      std::vector<Vertex> stops;
      const Face face(f);
      auto p2 = [&](Vertex v) { return mesh.to_face_plane(face, v); };
      bool leaves = false;
      for (Halfedge h : mesh.face_loop(face)) {
        const Vertex x = mesh.from(h), y = mesh.to(h);
        if (x != va && x != vb && y != va && y != vb && seg_cross(p2(va), p2(vb), p2(x), p2(y))) {
          leaves = true;
          break;
        }
      }
      if (leaves)
        for (const Vec3& q : mesh.detour(face, va, vb))
          stops.push_back(mesh.add_isolated_vertex(q, {VertexOrigin::Kind::InFace, f, 0}));
      stops.push_back(vb);
      Vertex prev = va;
      for (const Vertex stop : stops) {
        chords[f].push_back({p, chain.halfedges.size(), {prev, stop, {p, true}}});
        chain.halfedges.emplace_back();
        chain.vertices.push_back(stop);
        chain.point.push_back(static_cast<int>(k));
        prev = stop;
      }
    }
  }
  // 5. Split each crossed face along its chords, after checking that no two cross.
  std::set<int> faces;
  for (const auto& [f, c] : chords)
    faces.insert(f);
  for (const auto& [f, n] : interior)
    faces.insert(f);
  for (int f : faces) {
    auto& list = chords[f];
    const Face face(f);
    std::vector<Chord> cs;
    for (const auto& pc : list)
      cs.push_back(pc.chord);
    for (int i : interior[f])
      if (std::none_of(cs.begin(), cs.end(),
                       [&](const Chord& c) { return c.a == res.node_vertex[i] || c.b == res.node_vertex[i]; }))
        throw EmbedError("cut: node '" + in.node_ids[i] + "' lies inside input face " + std::to_string(f) +
                         " but no profile leaves it there");
    if (cs.empty())
      continue;
    // Check: chords against each other and against the face boundary, in
    // the face's layout (the same one subdivide_face uses).
    auto p2 = [&](Vertex v) { return mesh.to_face_plane(face, v); };
    for (size_t i = 0; i < cs.size(); ++i) {
      for (size_t j = i + 1; j < cs.size(); ++j) {
        const Chord &c = cs[i], &d = cs[j];
        const bool same_pair = (c.a == d.a && c.b == d.b) || (c.a == d.b && c.b == d.a);
        int shared = (c.a == d.a) + (c.a == d.b) + (c.b == d.a) + (c.b == d.b);
        bool bad = same_pair;
        if (!bad && shared == 0)
          bad = seg_cross(p2(c.a), p2(c.b), p2(d.a), p2(d.b));
        if (!bad && shared == 1) {
          // Sharing one end: they overlap only when collinear and on the same side.
          const Vertex s = (c.a == d.a || c.a == d.b) ? c.a : c.b;
          const Vertex x = c.a == s ? c.b : c.a, y = d.a == s ? d.b : d.a;
          const Eigen::Vector2d S = p2(s), X = p2(x), Y = p2(y);
          bad = orient2d(S, X, Y) == 0 && (X - S).dot(Y - S) > 0;
        }
        if (bad) {
          const std::string a = in.profile_ids[c.tag.profile], b = in.profile_ids[d.tag.profile];
          const Vec3 at = (mesh.position(c.a) + mesh.position(c.b) + mesh.position(d.a) + mesh.position(d.b)) / 4;
          throw ProfilesMeet("cut: profiles '" + a + "' and '" + b + "' cross in input face " + std::to_string(f) +
                                 (a == b ? " (the profile crosses itself)" : ", away from any node"),
                             c.tag.profile, d.tag.profile, at, "input face " + std::to_string(f), f);
        }
      }
    }
    for (const Chord& c : cs)
      for (Halfedge h : mesh.face_loop(face)) {
        const Vertex x = mesh.from(h), y = mesh.to(h);
        if (x == c.a || x == c.b || y == c.a || y == c.b)
          continue;
        if (seg_cross(p2(c.a), p2(c.b), p2(x), p2(y)))
          throw EmbedError("cut: profile '" + in.profile_ids[c.tag.profile] + "' leaves input face " +
                           std::to_string(f) +
                           " between two of its crossings (the face is not flat enough, or the path folds)");
      }
    const std::vector<Halfedge> hs = mesh.subdivide_face(face, cs);
    mutated();
    for (size_t i = 0; i < list.size(); ++i)
      res.chains[list[i].profile].halfedges[list[i].slot] = hs[i];
  }
  for (const auto& [e, list] : splits)
    for (const auto& sp : list)
      res.crossings += sp.owner_profile >= 0;
  res.crossings += static_cast<int>(vertex_owner.size());
  return res;
}

std::optional<std::string> validate_chains(const CutMesh& mesh, const CutInput& in, const CutResult& cut) {
  for (size_t p = 0; p < cut.chains.size(); ++p) {
    const CutChain& c = cut.chains[p];
    const std::string name = "chain '" + in.profile_ids[p] + "'";
    if (c.halfedges.empty())
      return name + ": no half-edges";
    if (c.vertices.size() != c.halfedges.size() + 1 || c.point.size() != c.vertices.size())
      return name + ": vertex, half-edge and path point counts disagree";
    if (c.vertices.front() != cut.node_vertex[in.profile_from[p]])
      return name + ": does not start at its from-node's vertex";
    if (c.vertices.back() != cut.node_vertex[in.profile_to[p]])
      return name + ": does not end at its to-node's vertex";
    for (size_t i = 0; i < c.halfedges.size(); ++i) {
      const Halfedge h = c.halfedges[i];
      if (!h.is_valid() || h.idx >= mesh.num_halfedges())
        return name + ": invalid half-edge " + std::to_string(i);
      if (mesh.from(h) != c.vertices[i] || mesh.to(h) != c.vertices[i + 1])
        return name + ": half-edge " + std::to_string(i) + " is not continuous";
      if (mesh.tag(h).profile != static_cast<int>(p) || !mesh.tag(h).forward)
        return name + ": half-edge " + std::to_string(i) + " carries the wrong tag";
    }
  }
  return std::nullopt;
}

} // namespace curvenet::detail
