#include "trace/tracer.hpp"

#include "core/polyline_distance.hpp"
#include "core/predicates.hpp"
#include "curvenet/errors.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <functional>
#include <sstream>
#include <unordered_map>

namespace curvenet::detail {

SurfacePoint place_node(const TraceMesh& mesh, const Vec3& p, const Tolerances& tol) {
  SurfacePoint sp = mesh.closest_point(p);
  const double snap = tol.node_snap();
  if (sp.kind == SurfacePoint::Kind::Face) {
    const auto& c = mesh.tri(sp.tri);
    for (int k = 0; k < 3; ++k)
      if ((mesh.position(c[k]) - sp.pos).norm() <= snap)
        return mesh.vertex_point(c[k]);
    for (int k = 0; k < 3; ++k) {
      const int e = mesh.side_edge(sp.tri, k);
      if (e < 0)
        continue;
      const auto ends = mesh.edge_ends(e);
      const Vec3 a = mesh.position(ends[0]), b = mesh.position(ends[1]);
      const double t = std::clamp((sp.pos - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
      const Vec3 q = (1 - t) * a + t * b;
      if ((q - sp.pos).norm() <= snap && t > 0 && t < 1) {
        sp.kind = SurfacePoint::Kind::Edge;
        sp.edge = e;
        sp.t = t;
        sp.pos = q;
        return sp;
      }
    }
  } else if (sp.kind == SurfacePoint::Kind::Edge) {
    const auto ends = mesh.edge_ends(sp.edge);
    for (int v : ends)
      if ((mesh.position(v) - sp.pos).norm() <= snap)
        return mesh.vertex_point(v);
  }
  return sp;
}

namespace {

std::string where(const TraceMesh& m, const SurfacePoint& p) {
  std::ostringstream s;
  switch (p.kind) {
  case SurfacePoint::Kind::Vertex:
    s << "vertex " << p.vertex;
    break;
  case SurfacePoint::Kind::Edge: {
    const auto e = m.edge_ends(p.edge);
    s << "edge " << e[0] << "-" << e[1];
    break;
  }
  case SurfacePoint::Kind::Face:
    s << "face " << m.tri_face(p.tri);
    break;
  }
  return s.str();
}

class Walker {
  struct WalkFailed : EmbedError {
    using EmbedError::EmbedError;
  };

public:
  Walker(const TraceMesh& m, const TraceInput& in, double mean_edge, const Tolerances& tol, TracedProfile& out)
      : m_(m), in_(in), mean_edge_(mean_edge), tol_(tol), out_(out) {}

  void emit(const SurfacePoint& p, int sample) {
    if (p.kind == SurfacePoint::Kind::Face)
      return;
    auto& pts = out_.points;
    if (!pts.empty()) {
      const PathPoint& last = pts.back();
      const SurfacePoint& l = last.at;
      if (l.pos == p.pos)
        return;
      if (p.kind == SurfacePoint::Kind::Vertex && l.kind == SurfacePoint::Kind::Vertex && l.vertex == p.vertex)
        return;
      if (p.kind == SurfacePoint::Kind::Edge && l.kind == SurfacePoint::Kind::Edge && l.edge == p.edge &&
          last.node < 0 && !last.on_curve) {
        // Crossed the edge and came back to it before meeting anything else:
        // the excursion is shorter than one face, keep the later point.
        pts.back().at = p;
        pts.back().sample = sample;
        pts.back().piece = piece;
        return;
      }
    }
    pts.push_back({p, -1, sample, piece});
  }

  int piece = 0; ///< the current walk's number, for the points it emits

  /// A sample, or a midpoint placed on the surface: kept even inside a face,
  /// so the cut follows the curve through the face instead of a chord.
  void emit_sample(const SurfacePoint& p, int sample) {
    auto& pts = out_.points;
    if (!pts.empty() && redundant(p, pts.back().at))
      return;
    if (p.kind != SurfacePoint::Kind::Face) {
      const size_t before = pts.size();
      emit(p, sample);
      if (pts.size() > before)
        pts.back().on_curve = true;
      return;
    }
    pts.push_back({p, -1, sample, piece, true});
  }

  /// A sample next to the point before it (within 1/100 of the fidelity
  /// tolerance) adds nothing but a sliver. It can go when every face it
  /// lies in holds that point too, so the path stays connected.
  bool redundant(const SurfacePoint& sample, const SurfacePoint& before) const {
    if ((sample.pos - before.pos).norm() > std::max(tol_.node_snap(), tol_.fidelity() / 100))
      return false;
    const std::vector<int> fs = m_.faces_of(sample), fb = m_.faces_of(before);
    return std::includes(fb.begin(), fb.end(), fs.begin(), fs.end());
  }

  Vec3 normal_at(const SurfacePoint& p) const {
    Vec3 n = Vec3::Zero();
    for (int t : m_.triangles_of(p))
      n += m_.tri_normal(t);
    return n;
  }

  /// Walks from a to b, emitting the edge crossings and vertex hits between.
  /// The cutting plane holds a, b and a surface normal. On a strongly curved
  /// part the section through one choice of normal can turn away from b; the
  /// walk then tries the normal at a alone, the normal at b alone, and
  /// finally walks from b back to a, before it gives up.
  void walk(const SurfacePoint& a, const SurfacePoint& b, int sample) {
    const size_t mark = out_.points.size();
    std::string first_error;
    for (int attempt = 0; attempt < 4; ++attempt) {
      try {
        if (attempt < 3) {
          walk_once(a, b, sample, attempt);
        } else {
          // Backwards into a list of its own; the path so far is put back
          // whether or not this walk succeeds.
          std::vector<PathPoint> back;
          std::swap(back, out_.points);
          try {
            walk_once(b, a, sample, 0);
          } catch (const WalkFailed&) {
            std::swap(back, out_.points);
            throw;
          }
          std::swap(back, out_.points);
          for (auto it = back.rbegin(); it != back.rend(); ++it)
            emit(it->at, sample);
        }
        return;
      } catch (const WalkFailed& e) {
        if (first_error.empty())
          first_error = e.what();
        out_.points.resize(mark);
      }
    }
    throw EmbedError(first_error);
  }

  void walk_once(const SurfacePoint& a, const SurfacePoint& b, int sample, int plane_mode) {
    const std::vector<int> target = m_.triangles_of(b);
    auto in_target = [&](int t) { return std::find(target.begin(), target.end(), t) != target.end(); };
    auto shares = [&](const SurfacePoint& p) {
      for (int t : m_.triangles_of(p))
        if (in_target(t))
          return true;
      return false;
    };
    if (shares(a))
      return;
    // Both ends on edges (or vertices) around one vertex: the path runs
    // through that vertex. This is the exact form of a curve along edges.
    if (a.kind != SurfacePoint::Kind::Face && b.kind != SurfacePoint::Kind::Face) {
      auto ends_of = [&](const SurfacePoint& p) -> std::vector<int> {
        if (p.kind == SurfacePoint::Kind::Vertex)
          return {p.vertex};
        const auto e = m_.edge_ends(p.edge);
        return {e[0], e[1]};
      };
      for (int u : ends_of(a))
        for (int w : ends_of(b))
          if (u == w) {
            emit(m_.vertex_point(u), sample);
            return;
          }
    }

    // The cutting plane contains a, b and the mean surface normal there.
    const Vec3 A = a.pos, B = b.pos;
    const double len = (B - A).norm();
    const Vec3 na = normal_at(a).normalized() * len, nb = normal_at(b).normalized() * len;
    Vec3 C = A + (plane_mode == 1 ? na : plane_mode == 2 ? nb : Vec3(na + nb));
    const Vec3 fallbacks[] = {A + normal_at(a).normalized() * len, A + Vec3::UnitX() * len, A + Vec3::UnitY() * len,
                              A + Vec3::UnitZ() * len};
    for (int i = 0; collinear3d(A, B, C) && i < 4; ++i)
      C = fallbacks[i];
    const Vec3 nrm = (B - A).cross(C - A);
    const Vec3 dir = B - A;
    std::unordered_map<int, int> side_memo;
    auto side = [&](int v) {
      auto it = side_memo.find(v);
      if (it != side_memo.end())
        return it->second;
      const int s = orient3d(A, B, C, m_.position(v));
      side_memo.emplace(v, s);
      return s;
    };
    auto sd = [&](int v) { return (m_.position(v) - A).dot(nrm); };
    // Crossing of side k of triangle t, as a surface point on the input edge (or inside the face on a diagonal).
    auto crossing = [&](int t, int k) {
      const auto& c = m_.tri(t);
      const int i = c[k], j = c[(k + 1) % 3];
      const double si = sd(i), sj = sd(j);
      const double s = (si - sj) != 0 ? si / (si - sj) : 0.5;
      // A crossing this close to an end of the edge goes through that end:
      // the path becomes a vertex hit instead of a sliver next to the vertex.
      if (!(s > Tolerances::crossing_min_param))
        return m_.vertex_point(i);
      if (!(s < 1 - Tolerances::crossing_min_param))
        return m_.vertex_point(j);
      SurfacePoint p;
      p.pos = (1 - s) * m_.position(i) + s * m_.position(j);
      const int e = m_.side_edge(t, k);
      if (e >= 0) {
        p.kind = SurfacePoint::Kind::Edge;
        p.edge = e;
        p.t = m_.edge_ends(e)[0] == i ? s : 1 - s;
      } else {
        p.kind = SurfacePoint::Kind::Face;
      }
      p.tri = t;
      return p;
    };
    auto enter = [&](int t, int k, int& came) {
      const auto& c = m_.tri(t);
      const int n = m_.neighbour(t, k);
      if (n < 0)
        fail(sample, "reached the boundary of the mesh at " + where(m_, crossing(t, k)));
      const auto& d = m_.tri(n);
      for (int q = 0; q < 3; ++q)
        if (d[q] == c[(k + 1) % 3] && d[(q + 1) % 3] == c[k])
          came = q;
      return n;
    };

    enum class State { InTri, AtVertex };
    State state;
    int tri = -1, came = -1, vertex = -1, came_vertex = -1, came_tri = -1;
    Vec3 pos = A;
    if (a.kind == SurfacePoint::Kind::Vertex) {
      state = State::AtVertex;
      vertex = a.vertex;
    } else {
      state = State::InTri;
      tri = a.tri;
      if (a.kind == SurfacePoint::Kind::Edge) {
        // Start on an edge: step into whichever adjacent triangle leads toward b.
        double best = -std::numeric_limits<double>::infinity();
        for (int t : m_.edge_triangles(a.edge)) {
          int k0 = -1;
          for (int k = 0; k < 3; ++k)
            if (m_.side_edge(t, k) == a.edge)
              k0 = k;
          for (const auto& cand : exits(t, k0, side, crossing)) {
            const double d = (cand.pos - A).dot(dir);
            if (d > best) {
              best = d;
              tri = t;
              came = k0;
            }
          }
        }
      }
    }
    const double max_len = Tolerances::walk_length_factor * len + Tolerances::walk_length_edges * mean_edge_;
    double travelled = 0;
    for (int steps = 0;; ++steps) {
      if (state == State::InTri) {
        if (in_target(tri))
          return;
        auto cands = exits(tri, came, side, crossing);
        if (cands.empty() && came < 0) {
          // The start lies on the triangle only up to rounding, and the plane
          // misses it: leave through the corner nearest to the plane.
          const auto& c = m_.tri(tri);
          int k = 0;
          for (int q = 1; q < 3; ++q)
            if (std::abs(sd(c[q])) < std::abs(sd(c[k])))
              k = q;
          cands.push_back({-1, c[k], m_.position(c[k])});
        }
        if (cands.empty())
          fail(sample, "the path has no way out of face " + std::to_string(m_.tri_face(tri)));
        const Exit* best = &cands[0];
        for (const auto& c : cands)
          if ((c.pos - pos).dot(dir) > (best->pos - pos).dot(dir))
            best = &c;
        travelled += (best->pos - pos).norm();
        pos = best->pos;
        if (best->vertex >= 0) {
          emit(m_.vertex_point(best->vertex), sample);
          state = State::AtVertex;
          vertex = best->vertex;
          came_tri = tri;
          came_vertex = -1;
        } else if (const SurfacePoint x = crossing(tri, best->side); x.kind == SurfacePoint::Kind::Vertex) {
          emit(x, sample);
          state = State::AtVertex;
          vertex = x.vertex;
          came_tri = tri;
          came_vertex = -1;
        } else {
          emit(x, sample);
          int nc = -1;
          const int nt = enter(tri, best->side, nc);
          tri = nt;
          came = nc;
        }
      } else {
        if (shares(m_.vertex_point(vertex)))
          return;
        // Leave the vertex through a triangle of its fan, or along an edge.
        struct Option {
          int tri = -1, side = -1, to = -1;
          Vec3 pos;
        };
        std::vector<Option> options;
        for (int t : m_.vertex_triangles(vertex)) {
          const auto& c = m_.tri(t);
          int i = 0;
          while (c[i] != vertex)
            ++i;
          const int v1 = c[(i + 1) % 3], v2 = c[(i + 2) % 3];
          const int s1 = side(v1), s2 = side(v2);
          if (s1 * s2 < 0 && t != came_tri)
            options.push_back({t, (i + 1) % 3, -1, crossing(t, (i + 1) % 3).pos});
          if (s1 == 0 && v1 != came_vertex)
            options.push_back({-1, -1, v1, m_.position(v1)});
          if (s2 == 0 && v2 != came_vertex)
            options.push_back({-1, -1, v2, m_.position(v2)});
        }
        if (options.empty()) {
          // The plane only touches the surface here: go along the edge that
          // points most toward b.
          for (int t : m_.vertex_triangles(vertex))
            for (int q : m_.tri(t))
              if (q != vertex && q != came_vertex)
                options.push_back({-1, -1, q, m_.position(q)});
        }
        if (options.empty())
          fail(sample, "the path stops at vertex " + std::to_string(vertex));
        const Vec3 here = m_.position(vertex);
        const Option* best = nullptr;
        double best_score = -std::numeric_limits<double>::infinity();
        for (const auto& o : options) {
          const Vec3 d = o.pos - here;
          const double score = d.norm() > 0 ? d.normalized().dot(dir.normalized()) : -2;
          if (score > best_score) {
            best_score = score;
            best = &o;
          }
        }
        travelled += (best->pos - here).norm();
        pos = best->pos;
        if (best->to >= 0) {
          emit(m_.vertex_point(best->to), sample);
          came_vertex = vertex;
          came_tri = -1;
          vertex = best->to;
        } else if (const SurfacePoint x = crossing(best->tri, best->side); x.kind == SurfacePoint::Kind::Vertex) {
          emit(x, sample);
          came_vertex = vertex;
          came_tri = best->tri;
          vertex = x.vertex;
        } else {
          emit(x, sample);
          int nc = -1;
          tri = enter(best->tri, best->side, nc);
          came = nc;
          state = State::InTri;
        }
      }
      if (travelled > max_len || steps > 4 * m_.num_triangles() + 16)
        fail(sample, "the path along the surface toward it grew to " +
                         std::to_string(travelled / std::max(len, 1e-300)) +
                         " times the distance between the samples without reaching " + where(m_, b) +
                         ": the curve spans a gap between two parts of the surface, or a part this mesh does not "
                         "have (draw it on the surface here)");
    }
  }

private:
  struct Exit {
    int side = -1;   // crossing of this side
    int vertex = -1; // or through this vertex
    Vec3 pos;
  };

  template <class Side, class Crossing> std::vector<Exit> exits(int t, int came, Side& side, Crossing& crossing) const {
    std::vector<Exit> out;
    const auto& c = m_.tri(t);
    for (int k = 0; k < 3; ++k) {
      if (k == came)
        continue;
      if (side(c[k]) * side(c[(k + 1) % 3]) < 0)
        out.push_back({k, -1, crossing(t, k).pos});
    }
    for (int k = 0; k < 3; ++k) {
      if (side(c[k]) != 0)
        continue;
      if (came >= 0 && (k == came || k == (came + 1) % 3))
        continue;
      out.push_back({-1, c[k], m_.position(c[k])});
    }
    return out;
  }

  [[noreturn]] void fail(int sample, const std::string& what) const {
    throw WalkFailed("trace: profile '" + in_.profile_id + "', sample " + std::to_string(sample) + ": " + what);
  }

  const TraceMesh& m_;
  const TraceInput& in_;
  double mean_edge_;
  const Tolerances& tol_;
  TracedProfile& out_;
};

} // namespace

TracedProfile trace_profile(const TraceMesh& mesh, const TraceInput& in, double mean_edge, const Tolerances& tol) {
  TracedProfile out;
  const int n = static_cast<int>(in.samples.size());
  out.samples = n;
  out.points.push_back({in.from, in.from_node, 0});
  auto folded = [&](const SurfacePoint& sp) {
    if (!in.inside_faces)
      return true;
    if (in.unfold_faces.empty())
      return false;
    for (int f : mesh.faces_of(sp))
      if (std::binary_search(in.unfold_faces.begin(), in.unfold_faces.end(), f))
        return true;
    return false;
  };
  auto reference = [&](const SurfacePoint& sp, int sample, int piece) {
    out.reference.push_back({sp.pos, sample, piece, sp.kind == SurfacePoint::Kind::Face && folded(sp)});
  };
  reference(in.from, 0, 0);
  Walker walker(mesh, in, mean_edge, tol, out);
  int pieces = 0;
  const int refine_budget = 10'000 + 64 * n;
  auto tolerance_near = [&](const Vec3& a, const Vec3& b) {
    double t = in.tolerance > 0 ? in.tolerance : tol.fidelity();
    for (const Tightening& g : in.tighter)
      if (point_segment_distance(g.centre, a, b) <= g.radius)
        t = std::min(t, g.tolerance);
    return t;
  };
  auto curve_at = [&](double t, const Vec3& ra, const Vec3& rb) -> Vec3 {
    return in.curve ? in.curve->at(t) : Vec3((ra + rb) / 2);
  };
  // Walks from a to b and compares the piece with the curve placed on the
  // surface there: a, the curve's midpoint m, b. A piece that strays
  // further than the tolerance, or a walk that fails, is redone as two
  // walks through m.
  std::function<void(const SurfacePoint&, double, const SurfacePoint&, double, int, int)> segment =
      [&](const SurfacePoint& a, double ta, const SurfacePoint& b, double tb, int sample, int depth) {
        const size_t mark = out.points.size();
        const double tm = (ta + tb) / 2;
        const SurfacePoint m = mesh.closest_point(curve_at(tm, a.pos, b.pos));
        std::exception_ptr failure;
        walker.piece = ++pieces;
        try {
          walker.walk(a, b, sample);
        } catch (const EmbedError&) {
          failure = std::current_exception();
        }
        // Bounded work: past a budget of midpoints per profile (a curve off
        // the surface along a fold), walks stand and the fidelity check judges.
        const bool last_level = depth >= Tolerances::refine_depth || (b.pos - a.pos).norm() <= tol.floor() ||
                                out.refinements >= refine_budget;
        if (!failure) {
          std::vector<Vec3> piece{a.pos};
          for (size_t k = mark; k < out.points.size(); ++k)
            piece.push_back(out.points[k].at.pos);
          piece.push_back(b.pos);
          const double limit = tolerance_near(a.pos, b.pos);
          // The curve placed on the surface between a and b: m, and more
          // placed points where it bends away from the chord, so the
          // reference stands within an eighth of the tolerance of the curve.
          std::vector<SurfacePoint> placed;
          std::function<void(const SurfacePoint&, double, const SurfacePoint&, double, const SurfacePoint&, int)> bend =
              [&](const SurfacePoint& x, double tx, const SurfacePoint& y, double ty, const SurfacePoint& mid,
                  int level) {
                const double tmid = (tx + ty) / 2;
                if (level < 3 && in.inside_faces && point_segment_distance(mid.pos, x.pos, y.pos) > limit / 8) {
                  bend(x, tx, mid, tmid, mesh.closest_point(curve_at((tx + tmid) / 2, x.pos, mid.pos)), level + 1);
                  placed.push_back(mid);
                  bend(mid, tmid, y, ty, mesh.closest_point(curve_at((tmid + ty) / 2, mid.pos, y.pos)), level + 1);
                } else {
                  placed.push_back(mid);
                }
              };
          bend(a, ta, b, tb, m, 0);
          std::vector<Vec3> curve{a.pos};
          for (const SurfacePoint& q : placed)
            curve.push_back(q.pos);
          curve.push_back(b.pos);
          if (!in.inside_faces || hausdorff(piece, curve) <= limit) {
            for (const SurfacePoint& q : placed)
              reference(q, sample, walker.piece);
            return;
          }
          if (last_level) {
            // Still astray at the finest level: a jump of the placed curve
            // when its ends lie much farther apart than the curve's own.
            const double drawn = (curve_at(tb, a.pos, b.pos) - curve_at(ta, a.pos, b.pos)).norm();
            if ((b.pos - a.pos).norm() > 2 * drawn + limit)
              out.jumps.push_back(walker.piece);
            reference(m, sample, walker.piece);
            return;
          }
        } else if (last_level) {
          std::rethrow_exception(failure);
        }
        // Redo the piece through the midpoint. When a walk that strayed
        // cannot be redone (a walk through the midpoint fails), it stands,
        // and the fidelity check judges it.
        std::vector<PathPoint> strayed(out.points.begin() + static_cast<long>(mark), out.points.end());
        const size_t ref_mark = out.reference.size();
        const int piece_before = walker.piece;
        const int refinements_before = out.refinements;
        out.points.resize(mark);
        try {
          ++out.refinements;
          segment(a, ta, m, tm, sample, depth + 1);
          walker.emit_sample(m, sample);
          reference(m, sample, walker.piece);
          segment(m, tm, b, tb, sample, depth + 1);
        } catch (const EmbedError&) {
          if (failure)
            throw;
          out.points.resize(mark);
          out.points.insert(out.points.end(), strayed.begin(), strayed.end());
          out.reference.resize(ref_mark);
          out.refinements = refinements_before;
          walker.piece = piece_before;
          reference(m, sample, walker.piece);
        }
      };
  SurfacePoint prev = in.from;
  for (int i = 1; i < n; ++i) {
    const Vec3 raw = (i == n - 1) ? in.to.pos : in.samples[i];
    const SurfacePoint cur = (i == n - 1) ? in.to : mesh.closest_point(raw);
    const double ta = in.t.empty() ? 0.0 : in.t[i - 1], tb = in.t.empty() ? 1.0 : in.t[i];
    segment(prev, ta, cur, tb, i, 0);
    if (i < n - 1)
      walker.emit_sample(cur, i);
    reference(cur, i, walker.piece);
    prev = cur;
  }
  // A path that comes back to a vertex it already passed made an excursion
  // shorter than a face or two around it (rounding near a vertex): drop the
  // excursion. A longer loop is a real self-touch, which the cut refuses.
  {
    auto& pts = out.points;
    for (size_t i = 0; i < pts.size(); ++i) {
      if (pts[i].at.kind != SurfacePoint::Kind::Vertex)
        continue;
      for (size_t j = pts.size() - 1; j > i + 1; --j) {
        if (pts[j].at.kind != SurfacePoint::Kind::Vertex || pts[j].at.vertex != pts[i].at.vertex)
          continue;
        if (pts[j].node >= 0 && pts[i].node >= 0)
          continue; // a closed loop through one node
        double len = 0;
        for (size_t k = i; k < j; ++k)
          len += (pts[k + 1].at.pos - pts[k].at.pos).norm();
        if (len <= 2 * mean_edge) {
          const int keep_node = pts[j].node >= 0 ? pts[j].node : pts[i].node;
          pts.erase(pts.begin() + static_cast<long>(i) + 1, pts.begin() + static_cast<long>(j) + 1);
          pts[i].node = keep_node;
        }
        break;
      }
    }
  }
  // A point in the middle of a run along one input edge adds nothing: the
  // run goes from the point before it to the point after it on that edge.
  // (When the middle point is an end of the edge, the path folded back on
  // the edge; dropping the point removes the fold.)
  {
    auto& pts = out.points;
    auto on_edge = [&](const SurfacePoint& p, int e) {
      if (p.kind == SurfacePoint::Kind::Edge)
        return p.edge == e;
      if (p.kind == SurfacePoint::Kind::Vertex) {
        const auto& ends = mesh.edge_ends(e);
        return p.vertex == ends[0] || p.vertex == ends[1];
      }
      return false;
    };
    auto edges_through = [&](const SurfacePoint& p) -> std::vector<int> {
      if (p.kind == SurfacePoint::Kind::Edge)
        return {p.edge};
      if (p.kind == SurfacePoint::Kind::Vertex) {
        const auto l = mesh.vertex_edges(p.vertex);
        return {l.begin(), l.end()};
      }
      return {};
    };
    std::vector<PathPoint> kept;
    for (size_t i = 0; i < pts.size(); ++i) {
      bool middle = false;
      if (i > 0 && i + 1 < pts.size() && pts[i].node < 0)
        for (int e : edges_through(pts[i].at))
          middle = middle || (on_edge(kept.back().at, e) && on_edge(pts[i + 1].at, e));
      if (!middle)
        kept.push_back(pts[i]);
    }
    pts = std::move(kept);
  }
  // The end node: merge with a vertex hit at the same place.
  auto& pts = out.points;
  if (pts.size() > 1 && pts.back().node < 0 &&
      ((in.to.kind == SurfacePoint::Kind::Vertex && pts.back().at.kind == SurfacePoint::Kind::Vertex &&
        pts.back().at.vertex == in.to.vertex) ||
       (pts.back().on_curve && walker.redundant(pts.back().at, in.to))))
    pts.pop_back();
  pts.push_back({in.to, in.to_node, n - 1, walker.piece});
  // A vertex hit right after the start node at the same place is the node itself.
  if (pts.size() > 2 && in.from.kind == SurfacePoint::Kind::Vertex && pts[1].node < 0 &&
      pts[1].at.kind == SurfacePoint::Kind::Vertex && pts[1].at.vertex == in.from.vertex)
    pts.erase(pts.begin() + 1);
  // Inside a face the chain needs only the samples that keep it within half
  // the tolerance of the curve (Douglas-Peucker on each run of samples
  // between two points on the face's boundary); the others would only add
  // cut vertices, and on a coarse mesh far from the curve, zig-zags.
  {
    auto& pts = out.points;
    std::vector<char> keep(pts.size(), 1);
    auto simplify = [&](size_t i, size_t j, double limit) {
      std::vector<Vec3> run;
      for (size_t k = i; k <= j; ++k)
        run.push_back(pts[k].at.pos);
      for (size_t k = i + 1; k < j; ++k)
        keep[k] = 0;
      for (size_t k : simplify_polyline(run, limit))
        keep[i + k] = 1;
    };
    auto in_face = [&](const PathPoint& p) { return p.node < 0 && p.at.kind == SurfacePoint::Kind::Face; };
    for (size_t i = 0; i + 1 < pts.size();) {
      size_t j = i + 1;
      while (j + 1 < pts.size() && in_face(pts[j]))
        ++j;
      if (j > i + 1) {
        if (folded(pts[i + 1].at)) {
          for (size_t k = i + 1; k < j; ++k)
            keep[k] = 0;
          pts[j].unmeasured = true;
        } else {
          simplify(i, j, tolerance_near(pts[i].at.pos, pts[j].at.pos) / 2);
        }
      }
      i = j;
    }
    std::vector<PathPoint> kept;
    for (size_t k = 0; k < pts.size(); ++k)
      if (keep[k])
        kept.push_back(pts[k]);
    pts = std::move(kept);
  }
  return out;
}

} // namespace curvenet::detail
