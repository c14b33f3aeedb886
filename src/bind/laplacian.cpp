#include "bind/laplacian.hpp"

#include "core/tolerances.hpp"

#include "core/polygon.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>

namespace curvenet::detail {
namespace {

/// Area of a triangle from its edge lengths (Kahan's stable Heron).
double area_from_lengths(double a, double b, double c) {
  if (a < b)
    std::swap(a, b);
  if (a < c)
    std::swap(a, c);
  if (b < c)
    std::swap(b, c);
  const double q = (a + (b + c)) * (c - (a - b)) * (c + (a - b)) * (a + (b - c));
  return q > 0 ? 0.25 * std::sqrt(q) : 0.0;
}

/// Cotangent of the angle opposite edge a in a triangle with sides a, b, c.
double cot_opposite(double a, double b, double c) {
  const double area = area_from_lengths(a, b, c);
  if (!(area > 0))
    return 0.0;
  return (b * b + c * c - a * a) / (4 * area);
}

/// A triangle mesh as half-edges, with lengths only, for intrinsic flips.
struct IntrinsicMesh {
  std::vector<int> origin, twin; // per half-edge; half-edge 3t+k goes from corner k to k+1 of triangle t
  std::vector<int> next;
  std::vector<double> length;

  [[nodiscard]] double cot_at(int h) const { // the angle opposite half-edge h, in h's triangle
    const int h1 = next[h], h2 = next[h1];
    return cot_opposite(length[h], length[h1], length[h2]);
  }
};

} // namespace

Eigen::SparseMatrix<double> intrinsic_delaunay_laplacian(int nv, const std::vector<Eigen::Vector3d>& pos,
                                                         const std::vector<std::array<int, 3>>& tris,
                                                         LaplacianStats* stats) {
  IntrinsicMesh m;
  const int nt = static_cast<int>(tris.size());
  m.origin.resize(3 * nt);
  m.twin.assign(3 * nt, -1);
  m.next.resize(3 * nt);
  m.length.resize(3 * nt);
  // Twins by sorting the half-edges on their (smaller, larger) end: a flat
  // table, no hashing. A pair with the same ends and opposite directions is
  // a pair of twins; a non-manifold edge (more than two) keeps none.
  std::vector<std::pair<std::uint64_t, int>> keys(3 * static_cast<size_t>(nt));
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) {
      const int h = 3 * t + k, a = tris[t][k], b = tris[t][(k + 1) % 3];
      m.origin[h] = a;
      m.next[h] = 3 * t + (k + 1) % 3;
      m.length[h] = (pos[a] - pos[b]).norm();
      const std::uint64_t lo = static_cast<std::uint32_t>(std::min(a, b)),
                          hi = static_cast<std::uint32_t>(std::max(a, b));
      keys[h] = {(lo << 32) | hi, h};
    }
  std::sort(keys.begin(), keys.end());
  for (size_t i = 0; i < keys.size();) {
    size_t j = i + 1;
    while (j < keys.size() && keys[j].first == keys[i].first)
      ++j;
    if (j - i == 2) {
      const int h = keys[i].second, g = keys[i + 1].second;
      if (m.origin[h] != m.origin[g]) {
        m.twin[h] = g;
        m.twin[g] = h;
      }
    }
    i = j;
  }
  // The cotangent opposite every half-edge, kept up to date through the flips.
  std::vector<double> cot(3 * static_cast<size_t>(nt));
  for (int h = 0; h < 3 * nt; ++h)
    cot[h] = m.cot_at(h);
  auto edge_weight = [&](int h) { return cot[h] + (m.twin[h] >= 0 ? cot[m.twin[h]] : 0.0); };
  LaplacianStats st;
  st.triangles = nt;
  for (int h = 0; h < 3 * nt; ++h)
    if ((m.twin[h] < 0 || h < m.twin[h]) && edge_weight(h) < -Tolerances::cot_weight_zero)
      ++st.negative_before;
  // Flip to intrinsic Delaunay.
  std::deque<int> queue;
  std::vector<char> queued(3 * nt, 0);
  for (int h = 0; h < 3 * nt; ++h)
    if (m.twin[h] >= 0 && h < m.twin[h]) {
      queue.push_back(h);
      queued[h] = 1;
    }
  const long max_flips = 64L * nt + 1024;
  while (!queue.empty() && st.flips < max_flips) {
    int h0 = queue.front();
    queue.pop_front();
    queued[h0] = 0;
    const int t0 = m.twin[h0];
    if (t0 < 0 || edge_weight(h0) >= -Tolerances::cot_weight_zero)
      continue;
    const int h1 = m.next[h0], h2 = m.next[h1], t1 = m.next[t0], t2 = m.next[t1];
    const int k = m.origin[h2], l = m.origin[t2]; // the corners opposite the edge i-j
    if (k == l)
      continue;
    // Lay the two triangles out in the plane: i at 0, j on the x axis.
    const double lij = m.length[h0];
    auto apex = [&](double di, double dj, double sign) { // point at distance di from i and dj from j
      const double x = (di * di - dj * dj + lij * lij) / (2 * lij);
      const double y = std::sqrt(std::max(0.0, di * di - x * x));
      return Eigen::Vector2d(x, sign * y);
    };
    const Eigen::Vector2d pk = apex(m.length[h2], m.length[h1], 1), pl = apex(m.length[t1], m.length[t2], -1);
    const double lkl = (pk - pl).norm();
    // Triangles (k, i, l) and (l, j, k).
    m.origin[h0] = l;
    m.origin[t0] = k;
    m.next[h2] = t1;
    m.next[t1] = h0;
    m.next[h0] = h2;
    m.next[t2] = h1;
    m.next[h1] = t0;
    m.next[t0] = t2;
    m.length[h0] = m.length[t0] = lkl;
    for (int e : {h0, h1, h2, t0, t1, t2})
      cot[e] = m.cot_at(e);
    ++st.flips;
    for (int e : {h1, h2, t1, t2}) {
      const int c = m.twin[e] >= 0 ? std::min(e, m.twin[e]) : e;
      if (m.twin[c] >= 0 && !queued[c]) {
        queue.push_back(c);
        queued[c] = 1;
      }
    }
  }
  // The matrix, column by column (no triplet sort): each edge once, its
  // weight off the diagonal at both ends and on both diagonals. After flips
  // two edges may join the same pair of vertices; their weights add.
  std::vector<int> count(static_cast<size_t>(nv) + 1, 0);
  for (int h = 0; h < 3 * nt; ++h) {
    if (m.twin[h] >= 0 && h > m.twin[h])
      continue;
    ++count[m.origin[h] + 1];
    ++count[m.origin[m.next[h]] + 1];
  }
  for (int v = 0; v < nv; ++v)
    count[v + 1] += count[v] + 1; // and the diagonal
  std::vector<std::pair<int, double>> entries(static_cast<size_t>(count[nv]));
  std::vector<int> fill(count.begin(), count.end() - 1);
  std::vector<double> diagonal(nv, 0.0);
  for (int h = 0; h < 3 * nt; ++h) {
    if (m.twin[h] >= 0 && h > m.twin[h])
      continue;
    const double w = 0.5 * edge_weight(h);
    if (w < -0.5 * Tolerances::cot_weight_zero) // a right angle's cotangent is zero to rounding, not negative
      ++st.negative_after;
    const int a = m.origin[h], b = m.origin[m.next[h]];
    entries[fill[a]++] = {b, -w};
    entries[fill[b]++] = {a, -w};
    diagonal[a] += w;
    diagonal[b] += w;
  }
  for (int v = 0; v < nv; ++v)
    entries[fill[v]++] = {v, diagonal[v]};
  Eigen::SparseMatrix<double> L(nv, nv);
  std::vector<int> outer(static_cast<size_t>(nv) + 1, 0);
  std::vector<int> inner;
  std::vector<double> value;
  inner.reserve(entries.size());
  value.reserve(entries.size());
  for (int v = 0; v < nv; ++v) {
    auto first = entries.begin() + count[v], last = entries.begin() + count[v + 1];
    std::sort(first, last, [](const auto& x, const auto& y) { return x.first < y.first; });
    for (auto it = first; it != last; ++it)
      if (!inner.empty() && static_cast<int>(inner.size()) > outer[v] && inner.back() == it->first)
        value.back() += it->second;
      else {
        inner.push_back(it->first);
        value.push_back(it->second);
      }
    outer[v + 1] = static_cast<int>(inner.size());
  }
  L = Eigen::Map<const Eigen::SparseMatrix<double>>(nv, nv, static_cast<Eigen::Index>(inner.size()), outer.data(),
                                                    inner.data(), value.data());
  if (stats)
    *stats = st;
  return L;
}

Eigen::SparseMatrix<double> cut_mesh_laplacian(const CutMesh& mesh, LaplacianKind kind, LaplacianStats* stats) {
  const int nv = mesh.num_vertices();
  if (kind == LaplacianKind::Uniform) {
    std::vector<Eigen::Triplet<double>> trip;
    for (int e = 0; e < mesh.num_edges(); ++e) {
      const int a = mesh.from(Halfedge(2 * e)).idx, b = mesh.to(Halfedge(2 * e)).idx;
      trip.emplace_back(a, b, -1.0);
      trip.emplace_back(b, a, -1.0);
      trip.emplace_back(a, a, 1.0);
      trip.emplace_back(b, b, 1.0);
    }
    Eigen::SparseMatrix<double> L(nv, nv);
    L.setFromTriplets(trip.begin(), trip.end());
    if (stats)
      *stats = {};
    return L;
  }
  std::vector<Eigen::Vector3d> pos(nv);
  for (int v = 0; v < nv; ++v)
    pos[v] = mesh.position(Vertex(v));
  std::vector<std::array<int, 3>> tris;
  tris.reserve(static_cast<size_t>(mesh.num_faces()) * 2);
  std::vector<Eigen::Vector3d> corners;
  std::vector<int> ids;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    ids.clear();
    corners.clear();
    const Halfedge start = mesh.halfedge(Face(f));
    Halfedge h = start;
    do {
      ids.push_back(mesh.from(h).idx);
      h = mesh.next(h);
    } while (h != start && static_cast<int>(ids.size()) <= mesh.num_halfedges());
    if (ids.size() == 3 && ids[0] != ids[1] && ids[1] != ids[2] && ids[0] != ids[2]) {
      tris.push_back({ids[0], ids[1], ids[2]});
      continue;
    }
    for (int v : ids)
      corners.push_back(mesh.position(Vertex(v)));
    for (const auto& t : triangulate_polygon(corners))
      if (ids[t[0]] != ids[t[1]] && ids[t[1]] != ids[t[2]] && ids[t[0]] != ids[t[2]]) // a crack repeats a vertex
        tris.push_back({ids[t[0]], ids[t[1]], ids[t[2]]});
  }
  return intrinsic_delaunay_laplacian(nv, pos, tris, stats);
}

} // namespace curvenet::detail
