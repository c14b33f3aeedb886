// Validation, welding and orientation repair of input meshes.

#include "curvenet/surface_mesh.hpp"
#include "core/predicates.hpp"
#include "core/tolerances.hpp"
#include "curvenet/errors.hpp"

#include <Eigen/Geometry>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <optional>
#include <set>
#include <sstream>
#include <tuple>
#include <utility>

namespace curvenet {

namespace {
/// One line: control characters from the input (a JSON key with a newline
/// in it) are shown escaped.
std::string one_line(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '\n')
      out += "\\n";
    else if (c == '\r')
      out += "\\r";
    else if (c == '\t')
      out += "\\t";
    else if (u < 0x20 || u == 0x7f) {
      static const char* hex = "0123456789abcdef";
      out += "\\x";
      out += hex[u >> 4];
      out += hex[u & 15];
    } else
      out += c;
  }
  return out;
}
} // namespace

InputError::InputError(std::string file, std::string element, const std::string& message)
    : Error(one_line(file + ": " + (element.empty() ? "" : element + ": ") + message)), file_(std::move(file)),
      element_(std::move(element)), reason_(message) {}

void RawMesh::add_face(std::span<const int> corners) {
  face_vertices.insert(face_vertices.end(), corners.begin(), corners.end());
  face_offsets.push_back(static_cast<int>(face_vertices.size()));
}

double SurfaceMesh::bbox_diagonal() const {
  if (positions.empty())
    return 0.0;
  Vec3 lo = positions[0], hi = positions[0];
  for (const auto& p : positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return (hi - lo).norm();
}

double SurfaceMesh::mean_edge_length() const {
  double sum = 0;
  long count = 0;
  for (int f = 0; f < num_faces(); ++f) {
    auto c = face(f);
    for (size_t i = 0; i < c.size(); ++i) {
      sum += (positions[c[i]] - positions[c[(i + 1) % c.size()]]).norm();
      ++count;
    }
  }
  return count ? sum / static_cast<double>(count) : 0.0;
}

std::vector<Vec3> SurfaceMesh::welded(const std::vector<Vec3>& per_input) const {
  std::vector<Vec3> p = positions;
  for (size_t i = 0; i < per_input.size() && i < input_to_welded.size(); ++i)
    p[input_to_welded[i]] = per_input[i];
  return p;
}

double SurfaceMesh::enclosed_volume(const std::vector<Vec3>& welded_positions) const {
  double v = 0;
  for (int f = 0; f < num_faces(); ++f) {
    const auto c = face(f);
    for (size_t k = 1; k + 1 < c.size(); ++k)
      v += welded_positions[c[0]].dot(welded_positions[c[k]].cross(welded_positions[c[k + 1]])) / 6;
  }
  return v;
}

double SurfaceMesh::winding_number(const Vec3& p) const {
  // Over blocks of faces, summed in a fixed order whatever the threads.
  auto part = [&](const tbb::blocked_range<int>& r, double sum) {
    for (int f = r.begin(); f < r.end(); ++f) {
      const auto c = face(f);
      for (size_t k = 1; k + 1 < c.size(); ++k) {
        const Vec3 a = positions[c[0]] - p, b = positions[c[k]] - p, d = positions[c[k + 1]] - p;
        const double la = a.norm(), lb = b.norm(), ld = d.norm();
        const double num = a.dot(b.cross(d));
        const double den = la * lb * ld + a.dot(b) * ld + b.dot(d) * la + d.dot(a) * lb;
        sum += 2 * std::atan2(num, den); // the solid angle of the triangle (Van Oosterom and Strackee)
      }
    }
    return sum;
  };
  const double sum =
      tbb::parallel_deterministic_reduce(tbb::blocked_range<int>(0, num_faces(), 4096), 0.0, part, std::plus<>());
  return sum / (4 * std::numbers::pi);
}

namespace {

/// The undirected edges of a polygon soup, with the faces that use them: a
/// flat table sorted by edge (no node-based map). Edge e's uses are
/// use_face(i) for i in [start[e], start[e + 1]), in face order.
struct EdgeTable {
  /// One use of an edge: a face side, as its larger vertex and the corner it starts at.
  struct Use {
    int hi;
    int corner; ///< an index into the face vertices
  };
  std::vector<std::uint64_t> key; ///< per edge: (smaller vertex << 32) | larger
  std::vector<int> start;         ///< per edge + 1
  std::vector<Use> use;           ///< per use, by edge
  std::vector<char> use_forward;  ///< the face runs smaller -> larger
  int uniform = 0;                ///< corners per face where every face has as many, else 0
  std::vector<int> corner_face;   ///< the face of each corner, where not uniform
  [[nodiscard]] int num_edges() const { return static_cast<int>(key.size()); }
  [[nodiscard]] int uses(int e) const { return start[e + 1] - start[e]; }
  [[nodiscard]] int lo(int e) const { return static_cast<int>(key[e] >> 32); }
  [[nodiscard]] int hi(int e) const { return static_cast<int>(key[e] & 0xffffffffu); }
  [[nodiscard]] int use_corner(int i) const { return use[i].corner; }
  /// By division where every face has as many corners (a triangle or quad mesh), else from a table.
  [[nodiscard]] int use_face(int i) const { return uniform ? use[i].corner / uniform : corner_face[use[i].corner]; }
};

std::uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<std::uint64_t>(static_cast<std::uint32_t>(std::min(a, b)));
  const auto hi = static_cast<std::uint64_t>(static_cast<std::uint32_t>(std::max(a, b)));
  return (lo << 32) | hi;
}

EdgeTable edge_table(const std::vector<int>& offsets, const std::vector<int>& verts) {
  // Every face side bucketed by its smaller vertex (a counting sort: linear,
  // no comparisons), then each small bucket ordered by the larger vertex;
  // sides enter their bucket in corner order and the insertion sort is
  // stable, so each edge's uses stay in face order. A side is its larger
  // vertex and its corner (8 bytes: the scatter into buckets is what costs,
  // with the first touch of each new array, so the uses stay where they
  // were scattered and a use's face is worked out when asked).
  using Use = EdgeTable::Use;
  EdgeTable t;
  int nv = 0;
  for (int v : verts)
    nv = std::max(nv, v + 1);
  const size_t nf = offsets.empty() ? 0 : offsets.size() - 1;
  t.uniform = nf > 0 ? offsets[1] : 0;
  for (size_t f = 1; f < nf && t.uniform; ++f)
    if (offsets[f + 1] - offsets[f] != t.uniform)
      t.uniform = 0;
  if (!t.uniform) {
    t.corner_face.resize(verts.size());
    for (size_t f = 0; f < nf; ++f)
      std::fill(t.corner_face.begin() + offsets[f], t.corner_face.begin() + offsets[f + 1], static_cast<int>(f));
  }
  std::vector<int> bucket(static_cast<size_t>(nv) + 1, 0);
  for (size_t f = 0; f < nf; ++f)
    for (int k = offsets[f]; k < offsets[f + 1]; ++k)
      ++bucket[std::min(verts[k], verts[k + 1 < offsets[f + 1] ? k + 1 : offsets[f]]) + 1];
  for (int v = 0; v < nv; ++v)
    bucket[v + 1] += bucket[v];
  std::vector<Use>& all = t.use;
  all.resize(verts.size());
  {
    std::vector<int> fill(bucket.begin(), bucket.end() - 1);
    for (size_t f = 0; f < nf; ++f)
      for (int k = offsets[f]; k < offsets[f + 1]; ++k) {
        const int a = verts[k], b = verts[k + 1 < offsets[f + 1] ? k + 1 : offsets[f]];
        all[fill[std::min(a, b)]++] = {std::max(a, b), k};
      }
  }
  // Each bucket ordered and its edges counted, then written at its offset:
  // both in parallel over the buckets (each bucket is a vertex's own).
  std::vector<int> edges_before(static_cast<size_t>(nv) + 1, 0);
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, 8192), [&](const tbb::blocked_range<int>& r) {
    for (int v = r.begin(); v < r.end(); ++v) {
      const int b = bucket[v], e = bucket[v + 1];
      for (int i = b + 1; i < e; ++i) // insertion sort by the larger vertex (stable)
        for (int j = i; j > b && all[j - 1].hi > all[j].hi; --j)
          std::swap(all[j - 1], all[j]);
      int count = 0;
      for (int i = b; i < e; ++i)
        count += i == b || all[i].hi != all[i - 1].hi;
      edges_before[v + 1] = count;
    }
  });
  for (int v = 0; v < nv; ++v)
    edges_before[v + 1] += edges_before[v];
  t.key.resize(static_cast<size_t>(edges_before[nv]));
  t.start.resize(static_cast<size_t>(edges_before[nv]) + 1);
  t.use_forward.resize(all.size());
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, 8192), [&](const tbb::blocked_range<int>& r) {
    for (int v = r.begin(); v < r.end(); ++v) {
      int edge = edges_before[v];
      for (int i = bucket[v]; i < bucket[v + 1]; ++i) {
        if (i == bucket[v] || all[i].hi != all[i - 1].hi) {
          t.key[edge] = edge_key(v, all[i].hi);
          t.start[edge++] = i;
        }
        t.use_forward[i] = static_cast<char>(verts[all[i].corner] == v); // the side runs from its smaller vertex
      }
    }
  });
  t.start.back() = static_cast<int>(all.size());
  return t;
}

/// Vertices whose incident faces form more than one fan (non-manifold
/// vertices), given manifold edges and no face that repeats a vertex. Around
/// a vertex each of its corners (one vertex of one face) has two sides, and
/// each side that two faces share links it to one corner of the other face
/// there: the corners of a vertex form paths and cycles, one per fan.
std::vector<int> non_manifold_vertices(int nv, const std::vector<int>& offsets, const std::vector<int>& verts,
                                       const EdgeTable& edges) {
  const int corners = static_cast<int>(verts.size());
  // Each corner's two links: across the side that starts at it (2k), and
  // the side that ends at it (2k + 1); -1 where that side is on a boundary.
  // Each side is one use of one edge, so each link is written once.
  std::vector<int> link(2 * static_cast<size_t>(corners), -1);
  // N: corners per face where every face has as many, or 0. A constant for
  // triangles and quads, so that a corner's next in its face is found by a
  // remainder by a constant, without reading the face offsets.
  auto write_links = [&]<int N>(std::integral_constant<int, N>) {
    const int n = N ? N : edges.uniform;
    auto next_corner = [&](int k) {
      if (n) {
        const int first = k - k % n;
        return k + 1 < first + n ? k + 1 : first;
      }
      const int f = edges.corner_face[k];
      return k + 1 < offsets[f + 1] ? k + 1 : offsets[f];
    };
    // The corner at vertex v of the side that starts at corner k.
    auto corner_at = [&](int k, int v) { return verts[k] == v ? k : next_corner(k); };
    tbb::parallel_for(tbb::blocked_range<int>(0, edges.num_edges(), 16384), [&](const tbb::blocked_range<int>& r) {
      for (int e = r.begin(); e < r.end(); ++e) {
        if (edges.uses(e) != 2)
          continue;
        const int s = edges.start[e];
        for (const int u : {s, s + 1}) {
          const int k = edges.use_corner(u), kn = next_corner(k), ko = edges.use_corner(u == s ? s + 1 : s);
          link[2 * static_cast<size_t>(k)] = corner_at(ko, verts[k]);
          link[2 * static_cast<size_t>(kn) + 1] = corner_at(ko, verts[kn]);
        }
      }
    });
  };
  if (edges.uniform == 3)
    write_links(std::integral_constant<int, 3>{});
  else if (edges.uniform == 4)
    write_links(std::integral_constant<int, 4>{});
  else
    write_links(std::integral_constant<int, 0>{});
  // Each fan walked once, from the first of its corners met, both ways.
  // Vertices are split into blocks that share nothing (a fan is one
  // vertex's), one per thread, each reading every corner and walking those
  // of its own vertices; the counts do not depend on how many blocks.
  std::vector<int> fans(static_cast<size_t>(nv), 0);
  std::vector<char> seen(static_cast<size_t>(corners), 0);
  const int blocks = std::max(1, std::min(tbb::this_task_arena::max_concurrency(), 8));
  tbb::parallel_for(0, blocks, [&](int block) {
    const int lo = static_cast<int>(static_cast<long long>(nv) * block / blocks),
              hi = static_cast<int>(static_cast<long long>(nv) * (block + 1) / blocks);
    auto unseen = [&](int k) { return k >= 0 && !seen[k]; };
    for (int k = 0; k < corners; ++k) {
      const int v = verts[k];
      if (v < lo || v >= hi || seen[k])
        continue;
      ++fans[v];
      seen[k] = 1;
      for (int side = 0; side < 2; ++side) // away from k across each of its sides, to the fan's end or back to k
        for (int at = link[2 * static_cast<size_t>(k) + side]; unseen(at);) {
          seen[at] = 1;
          const int a = link[2 * static_cast<size_t>(at)], b = link[2 * static_cast<size_t>(at) + 1];
          at = unseen(a) ? a : b;
        }
    }
  });
  std::vector<int> bad;
  for (int v = 0; v < nv; ++v)
    if (fans[v] > 1)
      bad.push_back(v);
  return bad;
}

std::string vec_str(const Vec3& p) {
  std::ostringstream s;
  s.precision(9);
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

/// For each position, the first vertex at exactly the same point (-0 and +0
/// are one point): flat hash tables with linear probing (no node per
/// entry). The positions are split by their hash's top bits into parts
/// (a stable counting sort, so each part keeps file order), and each part
/// is looked up in a table of its own, the parts in parallel: a part's
/// table stays in cache, and its slots hold the hash's low bits beside the
/// vertex, so a position is read again only where those agree.
std::vector<int> first_at_same_position(const std::vector<Vec3>& positions) {
  const int n = static_cast<int>(positions.size());
  auto hash = [](const Vec3& p) {
    std::uint64_t h = 0x9e3779b97f4a7c15ULL;
    for (int i = 0; i < 3; ++i) {
      const double d = p[i] == 0.0 ? 0.0 : p[i]; // -0 and +0 weld
      std::uint64_t bits = 0;
      std::memcpy(&bits, &d, sizeof bits);
      h = (h ^ bits) * 0xff51afd7ed558ccdULL;
      h ^= h >> 32;
    }
    return h;
  };
  constexpr int kPartBits = 6, kParts = 1 << kPartBits;
  std::vector<std::uint64_t> h(static_cast<size_t>(n));
  tbb::parallel_for(tbb::blocked_range<int>(0, n, 16384), [&](const tbb::blocked_range<int>& r) {
    for (int v = r.begin(); v < r.end(); ++v)
      h[v] = hash(positions[v]);
  });
  std::array<int, kParts + 1> part_start{};
  for (int v = 0; v < n; ++v)
    ++part_start[(h[v] >> (64 - kPartBits)) + 1];
  for (int p = 0; p < kParts; ++p)
    part_start[p + 1] += part_start[p];
  std::vector<int> order(static_cast<size_t>(n));
  {
    std::array<int, kParts> fill{};
    std::copy(part_start.begin(), part_start.end() - 1, fill.begin());
    for (int v = 0; v < n; ++v)
      order[fill[h[v] >> (64 - kPartBits)]++] = v;
  }
  std::vector<int> first(static_cast<size_t>(n));
  tbb::parallel_for(0, kParts, [&](int part) {
    const int b = part_start[part], e = part_start[part + 1];
    size_t size = 16;
    while (size < 2 * static_cast<size_t>(e - b))
      size *= 2;
    // A slot: the vertex + 1 in the low 32 bits (0: empty), the hash's low 32 above.
    std::vector<std::uint64_t> slot(size, 0);
    for (int k = b; k < e; ++k) {
      const int v = order[k];
      const std::uint64_t tag = h[v] << 32;
      size_t i = (h[v] >> 32) & (size - 1);
      for (;; i = (i + 1) & (size - 1)) {
        if (slot[i] == 0) {
          slot[i] = tag | static_cast<std::uint32_t>(v + 1);
          first[v] = v;
          break;
        }
        const int u = static_cast<int>(slot[i] & 0xffffffffu) - 1;
        if ((slot[i] & ~std::uint64_t{0xffffffffu}) == tag && positions[u] == positions[v]) {
          first[v] = u;
          break;
        }
      }
    }
  });
  return first;
}

/// The nearest of a set of points to a query point (the lowest index among
/// equally near ones): a k-d tree by median splits, over a permutation of
/// the points, searched with pruning. Each query is logarithmic for points
/// in general position; a loop over every point was quadratic in a file's
/// loose vertices (60k of them took 90 s).
class NearestPoint {
public:
  explicit NearestPoint(const std::vector<Vec3>& points) : points_(points), order_(points.size()) {
    std::iota(order_.begin(), order_.end(), 0);
    build(0, static_cast<int>(order_.size()), 0);
  }
  [[nodiscard]] int of(const Vec3& q) const {
    int best = -1;
    double best_d = std::numeric_limits<double>::infinity();
    search(0, static_cast<int>(order_.size()), 0, q, best, best_d);
    return best;
  }

private:
  void build(int lo, int hi, int axis) {
    if (hi - lo <= 1)
      return;
    const int mid = lo + (hi - lo) / 2;
    std::nth_element(order_.begin() + lo, order_.begin() + mid, order_.begin() + hi,
                     [&](int a, int b) { return points_[a][axis] < points_[b][axis]; });
    build(lo, mid, (axis + 1) % 3);
    build(mid + 1, hi, (axis + 1) % 3);
  }
  void search(int lo, int hi, int axis, const Vec3& q, int& best, double& best_d) const {
    if (lo >= hi)
      return;
    const int mid = lo + (hi - lo) / 2, i = order_[mid];
    const double d = (points_[i] - q).squaredNorm();
    if (best < 0 || d < best_d || (d == best_d && i < best)) {
      best = i;
      best_d = d;
    }
    const double along = q[axis] - points_[i][axis];
    const int next = (axis + 1) % 3;
    if (along < 0) {
      search(lo, mid, next, q, best, best_d);
      if (!(along * along > best_d))
        search(mid + 1, hi, next, q, best, best_d);
    } else {
      search(mid + 1, hi, next, q, best, best_d);
      if (!(along * along > best_d))
        search(lo, mid, next, q, best, best_d);
    }
  }
  const std::vector<Vec3>& points_;
  std::vector<int> order_;
};

/// Leaves out every face whose corners, by `id`, are the corners of an
/// earlier face (a copy of it, either way round; an exporter's doubled
/// faces, or a double-sided card's back). `extra`, when given, is a corner
/// array in step with `verts` that loses the same corners. Returns how many
/// faces were left out. Run only where a mesh has failed a check: it
/// hashes every face.
template <typename Id>
int drop_repeated_faces(std::vector<int>& offsets, std::vector<int>& verts, std::vector<int>* extra, Id&& id) {
  const int nf = static_cast<int>(offsets.size()) - 1;
  std::vector<std::vector<int>> key(static_cast<size_t>(nf));
  for (int f = 0; f < nf; ++f) {
    for (int k = offsets[f]; k < offsets[f + 1]; ++k)
      key[f].push_back(id(verts[k]));
    std::sort(key[f].begin(), key[f].end());
  }
  std::vector<int> order(static_cast<size_t>(nf));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return key[a] < key[b]; });
  std::vector<char> repeat(static_cast<size_t>(nf), 0);
  int count = 0;
  for (int i = 1; i < nf; ++i)
    if (key[order[i]] == key[order[i - 1]]) { // stable: the earlier face in file order stays
      repeat[order[i]] = 1;
      ++count;
    }
  if (count == 0)
    return 0;
  std::vector<int> new_offsets{0}, new_verts, new_extra;
  for (int f = 0; f < nf; ++f) {
    if (repeat[f])
      continue;
    new_verts.insert(new_verts.end(), verts.begin() + offsets[f], verts.begin() + offsets[f + 1]);
    if (extra)
      new_extra.insert(new_extra.end(), extra->begin() + offsets[f], extra->begin() + offsets[f + 1]);
    new_offsets.push_back(static_cast<int>(new_verts.size()));
  }
  offsets = std::move(new_offsets);
  verts = std::move(new_verts);
  if (extra)
    *extra = std::move(new_extra);
  return count;
}

/// Makes every component's faces run one way, the way most of them run.
/// Returns how many faces were reversed. Where every edge two faces share
/// is run in opposite directions, as in most files, nothing is searched.
/// \throw InputError for a component that cannot be oriented.
int orient_consistently(SurfaceMesh& mesh, const EdgeTable& edges) {
  const int nf = mesh.num_faces();
  bool consistent = true;
  for (int e = 0; e < edges.num_edges() && consistent; ++e)
    consistent = edges.uses(e) != 2 || edges.use_forward[edges.start[e]] != edges.use_forward[edges.start[e] + 1];
  if (consistent)
    return 0;
  // Each face's neighbours across its manifold edges, with whether the two
  // run the edge the same way (compressed rows).
  std::vector<int> adj_start(static_cast<size_t>(nf) + 1, 0);
  for (int e = 0; e < edges.num_edges(); ++e)
    if (edges.uses(e) == 2) {
      ++adj_start[edges.use_face(edges.start[e]) + 1];
      ++adj_start[edges.use_face(edges.start[e] + 1) + 1];
    }
  for (int f = 0; f < nf; ++f)
    adj_start[f + 1] += adj_start[f];
  std::vector<std::pair<int, bool>> adj(static_cast<size_t>(adj_start[nf])); // neighbour, same-direction use
  {
    std::vector<int> fill(adj_start.begin(), adj_start.end() - 1);
    for (int e = 0; e < edges.num_edges(); ++e)
      if (edges.uses(e) == 2) {
        const int k = edges.start[e], f = edges.use_face(k), g = edges.use_face(k + 1);
        const bool conflict = edges.use_forward[k] == edges.use_forward[k + 1];
        adj[fill[f]++] = {g, conflict};
        adj[fill[g]++] = {f, conflict};
      }
  }
  std::vector<int> flip(nf, -1);
  int flipped = 0;
  std::vector<int> members; // of one component, in the order reached
  for (int s = 0; s < nf; ++s) {
    if (flip[s] >= 0)
      continue;
    flip[s] = 0;
    members.assign(1, s);
    for (size_t next = 0; next < members.size(); ++next) {
      const int f = members[next];
      for (int a = adj_start[f]; a < adj_start[f + 1]; ++a) {
        const auto [g, conflict] = adj[a];
        const int want = flip[f] ^ static_cast<int>(conflict);
        if (flip[g] < 0) {
          flip[g] = want;
          members.push_back(g);
        } else if (flip[g] != want) {
          throw InputError(mesh.source, "face " + std::to_string(g),
                           "the surface is not orientable (a Moebius-like component)");
        }
      }
    }
    int count = 0;
    for (int f : members)
      count += flip[f];
    // Keep the majority orientation of the component.
    if (2 * count > static_cast<int>(members.size()))
      for (int f : members)
        flip[f] ^= 1;
    for (int f : members)
      flipped += flip[f];
  }
  for (int f = 0; f < nf; ++f)
    if (flip[f])
      std::reverse(mesh.face_vertices.begin() + mesh.face_offsets[f],
                   mesh.face_vertices.begin() + mesh.face_offsets[f + 1]);
  return flipped;
}

/// Turns outward every closed component wound inside out (its enclosed
/// volume negative: a mirrored export, normals flipped in a modeller), so
/// that a closed surface's winding number is 1 inside it and the sides of
/// its curves are those of the same surface wound outward. Looked for only
/// where the whole mesh encloses a negative volume: one pass over the faces
/// otherwise. Returns the components and the faces turned.
std::pair<int, int> turn_closed_parts_outward(SurfaceMesh& mesh) {
  const int nf = mesh.num_faces();
  if (nf == 0)
    return {0, 0};
  // Six times each face's signed volume from a corner of the mesh (near
  // it, so that large coordinates do not swamp it).
  const Vec3 o = mesh.positions[mesh.face(0)[0]];
  auto volume = [&](int f) {
    const auto c = mesh.face(f);
    double v = 0;
    for (size_t k = 1; k + 1 < c.size(); ++k)
      v += (mesh.positions[c[0]] - o).dot((mesh.positions[c[k]] - o).cross(mesh.positions[c[k + 1]] - o));
    return v;
  };
  const double total = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<int>(0, nf, 4096), 0.0,
      [&](const tbb::blocked_range<int>& r, double sum) {
        for (int f = r.begin(); f < r.end(); ++f)
          sum += volume(f);
        return sum;
      },
      std::plus<>());
  if (!(total < 0))
    return {0, 0};
  std::vector<int> comp;
  const std::vector<ComponentInfo> parts = mesh_components(mesh, &comp);
  std::vector<double> part_vol(parts.size(), 0);
  for (int f = 0; f < nf; ++f)
    part_vol[comp[f]] += volume(f);
  int turned = 0, faces = 0;
  for (size_t c = 0; c < parts.size(); ++c)
    if (parts[c].closed && part_vol[c] < 0) {
      ++turned;
      faces += parts[c].faces;
    }
  if (turned == 0)
    return {0, 0};
  for (int f = 0; f < nf; ++f)
    if (parts[comp[f]].closed && part_vol[comp[f]] < 0)
      std::reverse(mesh.face_vertices.begin() + mesh.face_offsets[f],
                   mesh.face_vertices.begin() + mesh.face_offsets[f + 1]);
  return {turned, faces};
}

} // namespace

std::vector<ComponentInfo> mesh_components(const SurfaceMesh& mesh, std::vector<int>* face_component) {
  const int nf = mesh.num_faces();
  const EdgeTable edges = edge_table(mesh.face_offsets, mesh.face_vertices);
  // Faces joined across shared edges: union-find.
  std::vector<int> parent(nf);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int x) {
    while (parent[x] != x)
      x = parent[x] = parent[parent[x]];
    return x;
  };
  for (int e = 0; e < edges.num_edges(); ++e)
    if (edges.uses(e) == 2) {
      const int a = find(edges.use_face(edges.start[e])), b = find(edges.use_face(edges.start[e] + 1));
      if (a != b)
        parent[std::max(a, b)] = std::min(a, b);
    }
  // Components in order of their lowest face.
  std::vector<int> comp(nf, -1), id_of_root(nf, -1);
  std::vector<ComponentInfo> out;
  for (int f = 0; f < nf; ++f) {
    const int r = find(f);
    if (id_of_root[r] < 0) {
      id_of_root[r] = static_cast<int>(out.size());
      out.emplace_back();
    }
    comp[f] = id_of_root[r];
  }
  std::vector<int> nverts(out.size(), 0), nedges(out.size(), 0);
  std::vector<char> vseen(mesh.num_vertices(), 0), open(out.size(), 0);
  for (int f = 0; f < nf; ++f) {
    out[comp[f]].faces++;
    for (int v : mesh.face(f))
      if (!vseen[v]) {
        vseen[v] = 1;
        nverts[comp[f]]++;
      }
  }
  for (int e = 0; e < edges.num_edges(); ++e) {
    const int c = comp[edges.use_face(edges.start[e])];
    nedges[c]++;
    if (edges.uses(e) == 1)
      open[c] = 1;
  }
  for (size_t c = 0; c < out.size(); ++c) {
    out[c].closed = !open[c];
    out[c].euler = nverts[c] - nedges[c] + out[c].faces;
  }
  if (face_component)
    *face_component = std::move(comp);
  return out;
}

std::string open_parts_words(const SurfaceMesh& mesh) {
  const std::vector<ComponentInfo> parts = mesh_components(mesh);
  const auto open = std::count_if(parts.begin(), parts.end(), [](const ComponentInfo& p) { return !p.closed; });
  if (open == 0)
    return {};
  // Where loading kept coincident vertices apart (welding them would give an
  // edge of three or more faces, as Blender's Remesh leaves a few), that is
  // where the boundary is: said, as the file itself has no hole there.
  std::string kept;
  for (const std::string& n : mesh.notes)
    if (n.rfind("kept ", 0) == 0)
      kept = "; loading " + n.substr(0, n.find(',')) +
             ", as welding them would give edges of more than two faces, which leaves a boundary there: dissolve or "
             "split those edges in the modeller";
  if (parts.size() == 1)
    return "it has a boundary" + kept;
  return std::to_string(open) + " of its " + std::to_string(parts.size()) + " parts " + (open == 1 ? "has" : "have") +
         " a boundary" + kept;
}

namespace {
/// make_surface_mesh, moving `raw`'s arrays out of `steal` (which is `raw`)
/// where they are kept as they are.
SurfaceMesh surface_mesh_of(const RawMesh& raw, RawMesh* steal, const std::string& source);
} // namespace

SurfaceMesh make_surface_mesh(const RawMesh& raw, const std::string& source) {
  return surface_mesh_of(raw, nullptr, source);
}

SurfaceMesh make_surface_mesh(RawMesh&& raw, const std::string& source) {
  return surface_mesh_of(raw, &raw, source);
}

namespace {
SurfaceMesh surface_mesh_of(const RawMesh& raw, RawMesh* steal, const std::string& source) {
  const int nin = static_cast<int>(raw.positions.size());
  const int nraw = static_cast<int>(raw.face_offsets.size()) - 1;
  if (nraw <= 0)
    throw InputError(source, "", "the mesh has no faces");
  // The first bad vertex and the first bad face, found in parallel.
  auto first_where = [](int count, auto&& bad) {
    return tbb::parallel_reduce(
        tbb::blocked_range<int>(0, count, 16384), count,
        [&](const tbb::blocked_range<int>& r, int first) {
          for (int i = r.begin(); i < r.end() && i < first; ++i)
            if (bad(i))
              return i;
          return first;
        },
        [](int a, int b) { return std::min(a, b); });
  };
  if (const int v = first_where(nin, [&](int i) { return !raw.positions[i].allFinite(); }); v < nin)
    throw InputError(source, "vertex " + std::to_string(v), "non-finite coordinate " + vec_str(raw.positions[v]));
  const int bad_face = first_where(nraw, [&](int f) {
    if (raw.face_offsets[f + 1] - raw.face_offsets[f] < 3)
      return true;
    for (int k = raw.face_offsets[f]; k < raw.face_offsets[f + 1]; ++k)
      if (raw.face_vertices[k] < 0 || raw.face_vertices[k] >= nin)
        return true;
    return false;
  });
  for (int f = bad_face; f < nraw; ++f) { // the first bad face's message
    const int n = raw.face_offsets[f + 1] - raw.face_offsets[f];
    if (n < 3)
      throw InputError(source, "face " + std::to_string(f),
                       "has " + std::to_string(n) + " corners; at least 3 are needed");
    for (int k = raw.face_offsets[f]; k < raw.face_offsets[f + 1]; ++k)
      if (raw.face_vertices[k] < 0 || raw.face_vertices[k] >= nin)
        throw InputError(source, "face " + std::to_string(f),
                         "refers to vertex " + std::to_string(raw.face_vertices[k]) + ", which does not exist");
  }

  // Degenerate faces (two corners at one point, or no area), which game
  // meshes have, are left out of the surface the engine works on; the
  // output keeps them (it is written on the file's own topology).
  // Each face classified on its own (in parallel), then the survivors kept
  // in file order.
  // A triangle whose corner opposite its longest edge lies within
  // Tolerances::node_snap_rel of the diagonal of that edge, and between its
  // ends, has no area either: a vertex put at an edge's midpoint and stored
  // in single precision lands that close to the edge, not on it, and so
  // thin a triangle leaves the cut no room.
  Eigen::AlignedBox3d box;
  for (int v = 0; v < nin; ++v)
    box.extend(raw.positions[v]);
  // (Measured in units of the diagonal: a mesh at 1e-200 or 1e200 would
  // underflow or overflow a cross product of its own coordinates.)
  const double inv_diag = 1 / box.diagonal().stableNorm();
  const bool measure_thin = std::isfinite(inv_diag) && inv_diag > 0;
  enum : char { kKept = 0, kSamePoint = 1, kNoArea = 2 };
  std::vector<char> kind(static_cast<size_t>(nraw), kKept);
  tbb::parallel_for(tbb::blocked_range<int>(0, nraw, 4096), [&](const tbb::blocked_range<int>& range) {
    std::vector<Vec3> corners;
    for (int f = range.begin(); f < range.end(); ++f) {
      const int b = raw.face_offsets[f], n = raw.face_offsets[f + 1] - b;
      auto at = [&](int i) -> const Vec3& { return raw.positions[raw.face_vertices[b + i]]; };
      bool degenerate = false;
      if (n <= 16) {
        for (int i = 0; i < n && !degenerate; ++i)
          for (int j = i + 1; j < n && !degenerate; ++j)
            degenerate = at(i) == at(j);
      } else { // a large polygon: its corners' points sorted, not compared pairwise
        corners.clear();
        for (int i = 0; i < n; ++i)
          corners.push_back(at(i));
        auto less = [](const Vec3& x, const Vec3& y) {
          return std::lexicographical_compare(x.data(), x.data() + 3, y.data(), y.data() + 3);
        };
        std::sort(corners.begin(), corners.end(), less);
        degenerate = std::adjacent_find(corners.begin(), corners.end()) != corners.end();
      }
      bool all_collinear = !degenerate;
      for (int i = 1; i + 1 < n && all_collinear; ++i)
        all_collinear = detail::collinear3d(at(0), at(i), at(i + 1));
      // A triangle's least height is over its longest edge (where the corner
      // opposite lies between the edge's ends): one whose height there is
      // over twice the bound (a margin for rounding) needs no test per edge.
      auto surely_thick = [&] {
        const Vec3 ab = (at(1) - at(0)) * inv_diag, ac = (at(2) - at(0)) * inv_diag, bc = ac - ab;
        const double longest = std::max({ab.squaredNorm(), ac.squaredNorm(), bc.squaredNorm()});
        const double bound = 2 * detail::Tolerances::node_snap_rel;
        return ab.cross(ac).squaredNorm() > bound * bound * longest;
      };
      if (n == 3 && !degenerate && !all_collinear && measure_thin && !surely_thick())
        for (int m = 0; m < 3 && !all_collinear; ++m) {
          const Vec3 &a = at((m + 1) % 3), &c = at((m + 2) % 3), &x = at(m);
          const Vec3 ac = (c - a) * inv_diag, ax = (x - a) * inv_diag;
          const double t = ax.dot(ac) / ac.squaredNorm();
          all_collinear = t > 0 && t < 1 && ax.cross(ac).norm() / ac.norm() <= detail::Tolerances::node_snap_rel;
        }
      kind[f] = degenerate ? kSamePoint : all_collinear ? kNoArea : kKept;
    }
  });
  std::vector<int> offsets, verts;
  int dropped = 0;
  std::string first_reason; // of the first degenerate face, for a mesh with no other
  if (raw.face_offsets.front() == 0 && std::all_of(kind.begin(), kind.end(), [](char k) { return k == kKept; })) {
    if (steal) { // every face kept: the arrays as they are (the rest of raw.face_* is not read again)
      offsets = std::move(steal->face_offsets);
      verts = std::move(steal->face_vertices);
      verts.resize(static_cast<size_t>(offsets.back()));
    } else { // one copy
      offsets = raw.face_offsets;
      verts.assign(raw.face_vertices.begin(), raw.face_vertices.begin() + raw.face_offsets.back());
    }
  } else {
    offsets.reserve(static_cast<size_t>(nraw) + 1);
    offsets.push_back(0);
    verts.reserve(raw.face_vertices.size());
    for (int f = 0; f < nraw; ++f) {
      const int b = raw.face_offsets[f], n = raw.face_offsets[f + 1] - b;
      if (kind[f] != kKept) {
        if (dropped++ == 0)
          first_reason = "face " + std::to_string(f) +
                         (kind[f] == kSamePoint ? ": degenerate: two of its corners are one point"
                                                : ": degenerate: its corners are collinear (no area)");
        continue;
      }
      verts.insert(verts.end(), raw.face_vertices.begin() + b, raw.face_vertices.begin() + b + n);
      offsets.push_back(static_cast<int>(verts.size()));
    }
  }
  // Vertices at one position (the weld below starts from these groups).
  std::vector<int> group = first_at_same_position(raw.positions);
  // Corners of a left-out face that lie a few units in the last place apart
  // are one point written twice: they join one group, and their face is
  // then one with two corners at one point.
  int near_welds = 0;
  if (dropped > 0 && measure_thin) {
    std::vector<int> joined; // union-find over group representatives, built on the first join
    auto find = [&](int r) {
      while (joined[r] != r)
        r = joined[r] = joined[joined[r]];
      return r;
    };
    for (int f = 0; f < nraw; ++f) {
      if (kind[f] != kNoArea)
        continue;
      const int b = raw.face_offsets[f], n = raw.face_offsets[f + 1] - b;
      for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j) {
          const int u = raw.face_vertices[b + i], v = raw.face_vertices[b + j];
          if ((raw.positions[u] - raw.positions[v]).norm() * inv_diag > detail::Tolerances::degenerate_weld_rel)
            continue;
          if (joined.empty()) {
            joined.resize(static_cast<size_t>(nin));
            std::iota(joined.begin(), joined.end(), 0);
          }
          const int ru = find(group[u]), rv = find(group[v]);
          if (ru != rv) {
            joined[std::max(ru, rv)] = std::min(ru, rv);
            ++near_welds;
          }
          kind[f] = kSamePoint;
        }
    }
    if (near_welds > 0)
      for (int v = 0; v < nin; ++v)
        group[v] = find(group[v]);
  }
  // A triangle with no area whose corners are three points of one line (b
  // between a and c) leaves a slit when it is left out. The triangle across
  // its long edge a-c is split at b into two, so that the faces across a-b
  // and b-c meet them and the surface stays closed. Slivers come in runs (a
  // planar decimation's n-gons triangulated into fans of them): the points
  // of a run's slivers, one line, are put into every kept triangle's edge
  // that is a sliver's edge, wherever they lie strictly inside it (within
  // Tolerances::node_snap_rel of the diagonal from it). (Not a polygon
  // across: a corner added to it would be a straight angle, which no layout
  // orders.) A triangle that has such a point already, or a run whose edges
  // no kept triangle has, is left as it is; and the splits are kept only
  // where every edge then has two faces at most.
  int closed_slits = 0;
  if (dropped > 0 && measure_thin) {
    std::vector<std::array<int, 3>> slivers; // input vertices
    for (int f = 0; f < nraw; ++f) {
      const int b = raw.face_offsets[f];
      if (kind[f] != kNoArea || raw.face_offsets[f + 1] - b != 3)
        continue;
      const std::array<int, 3> w{raw.face_vertices[b], raw.face_vertices[b + 1], raw.face_vertices[b + 2]};
      if (group[w[0]] != group[w[1]] && group[w[1]] != group[w[2]] && group[w[0]] != group[w[2]])
        slivers.push_back(w);
    }
    // Runs: slivers joined where they share a point (union-find over groups).
    std::map<int, int> run_of; // group -> its run's root group
    auto root = [&](int g) {
      int r = g;
      while (run_of.at(r) != r)
        r = run_of.at(r);
      for (int x = g; run_of.at(x) != r;)
        x = std::exchange(run_of.at(x), r);
      return r;
    };
    std::set<std::pair<int, int>> sliver_edges; // by group, smaller first
    for (const auto& w : slivers)
      for (int i = 0; i < 3; ++i) {
        run_of.emplace(group[w[i]], group[w[i]]);
        const int g = group[w[i]], h = group[w[(i + 1) % 3]];
        sliver_edges.insert({std::min(g, h), std::max(g, h)});
      }
    for (const auto& w : slivers)
      for (int i = 1; i < 3; ++i) {
        const int r0 = root(group[w[0]]), ri = root(group[w[i]]);
        if (r0 != ri)
          run_of[std::max(r0, ri)] = std::min(r0, ri);
      }
    std::map<int, std::vector<int>> run_points; // root group -> one input vertex per group of the run
    {
      std::set<int> seen;
      for (const auto& w : slivers)
        for (const int v : w)
          if (seen.insert(group[v]).second)
            run_points[root(group[v])].push_back(v);
    }
    if (!slivers.empty()) {
      std::vector<int> new_offsets{0}, new_verts;
      new_verts.reserve(verts.size() + 6 * slivers.size());
      int split = 0;
      std::vector<std::pair<double, int>> list;
      for (int f = 0; f + 1 < static_cast<int>(offsets.size()); ++f) {
        const int b = offsets[f], n = offsets[f + 1] - b;
        bool done = false;
        for (int k = 0; k < n && n == 3 && !done; ++k) {
          const int x = verts[b + k], y = verts[b + (k + 1) % 3], z = verts[b + (k + 2) % 3];
          if (!sliver_edges.count({std::min(group[x], group[y]), std::max(group[x], group[y])}))
            continue;
          // The run's points strictly inside x-y, nearest x first.
          const Vec3 &px = raw.positions[x], &py = raw.positions[y];
          const Vec3 along = (py - px) * inv_diag;
          list.clear();
          bool has_one = false;
          const std::vector<int>& run = run_points.at(root(group[x]));
          if (run.size() > 4096) // each edge of a run scans its points: a run this long is left open
            continue;
          for (const int v : run) {
            if (group[v] == group[x] || group[v] == group[y])
              continue;
            const Vec3 off = (raw.positions[v] - px) * inv_diag;
            const double t = off.dot(along) / along.squaredNorm();
            if (!(t > 0 && t < 1) || (off - t * along).norm() > detail::Tolerances::node_snap_rel)
              continue;
            if (group[v] == group[z])
              has_one = true;
            list.emplace_back(t, v);
          }
          if (list.empty() || has_one)
            continue;
          std::sort(list.begin(), list.end());
          int from = x;
          for (const auto& [t, v] : list) {
            new_verts.insert(new_verts.end(), {from, v, z});
            new_offsets.push_back(static_cast<int>(new_verts.size()));
            from = v;
            ++split;
          }
          new_verts.insert(new_verts.end(), {from, y, z});
          new_offsets.push_back(static_cast<int>(new_verts.size()));
          done = true;
        }
        if (done)
          continue;
        new_verts.insert(new_verts.end(), verts.begin() + b, verts.begin() + b + n);
        new_offsets.push_back(static_cast<int>(new_verts.size()));
      }
      const EdgeTable closed = edge_table(new_offsets, new_verts);
      bool manifold = true;
      for (int e = 0; e < closed.num_edges() && manifold; ++e)
        manifold = closed.uses(e) <= 2;
      if (manifold && split > 0) {
        offsets = std::move(new_offsets);
        verts = std::move(new_verts);
        closed_slits = split;
      }
    }
  }

  int nf = static_cast<int>(offsets.size()) - 1;
  if (nf == 0) {
    const auto colon = first_reason.find(": ");
    throw InputError(source, first_reason.substr(0, colon), first_reason.substr(colon + 2) + ", as is every face");
  }

  // Non-manifold edges in the input as given (no weld) are refused. A vertex
  // that is non-manifold as given may be mended by welding (a glTF seam can
  // split a fan); that is judged after the weld.
  EdgeTable edges = edge_table(offsets, verts); // as given; then as welded
  int repeated = 0; // faces left out as copies of another (looked for only where a check fails)
  auto over_two = [&] {
    for (int e = 0; e < edges.num_edges(); ++e)
      if (edges.uses(e) > 2)
        return true;
    return false;
  };
  if (over_two()) { // copies of faces on the same vertices, or at the same points, are left out
    repeated = drop_repeated_faces(offsets, verts, nullptr, [&](int v) { return group[v]; });
    if (repeated > 0) {
      nf = static_cast<int>(offsets.size()) - 1;
      edges = edge_table(offsets, verts);
    }
  }
  for (int e = 0; e < edges.num_edges(); ++e)
    if (edges.uses(e) > 2)
      throw InputError(source, "edge " + std::to_string(edges.lo(e)) + "-" + std::to_string(edges.hi(e)),
                       "non-manifold: shared by " + std::to_string(edges.uses(e)) + " faces");

  // Weld by exact position, then undo welds that break manifoldness.
  std::vector<int> to_welded;
  std::vector<int> fverts;
  int refused_welds = 0;
  auto weld = [&] {
    for (int round = 0;; ++round) {
      // Welded ids in order of first occurrence.
      std::vector<int> id_of_rep(nin, -1);
      to_welded.assign(nin, -1);
      int next = 0;
      for (int v = 0; v < nin; ++v) {
        int r = group[v];
        if (id_of_rep[r] < 0)
          id_of_rep[r] = next++;
        to_welded[v] = id_of_rep[r];
      }
      const bool same = next == nin; // nothing welded: ids in order of first occurrence are the input's
      if (same) {                    // and so the last round: it ends, or refuses the mesh
        fverts = std::move(verts);
      } else {
        fverts.resize(verts.size());
        for (size_t k = 0; k < fverts.size(); ++k)
          fverts[k] = to_welded[verts[k]];
      }
      if (!same || round > 0)
        edges = edge_table(offsets, fverts);
      if (round == 0 && !same) {
        // Copies of faces with vertices of their own at the same points (an
        // exporter's doubled faces) weld onto their original: left out
        // before any weld is undone for them. Looked for only where the weld
        // broke manifoldness.
        bool broken = over_two();
        if (!broken)
          for (int f = 0; f < nf && !broken; ++f)
            for (int i = offsets[f]; i < offsets[f + 1] && !broken; ++i)
              for (int j = i + 1; j < offsets[f + 1] && !broken; ++j)
                broken = fverts[i] == fverts[j];
        if (!broken)
          broken = !non_manifold_vertices(next, offsets, fverts, edges).empty();
        if (broken) {
          const int more = drop_repeated_faces(offsets, fverts, &verts, [](int w) { return w; });
          if (more > 0) {
            repeated += more;
            nf = static_cast<int>(offsets.size()) - 1;
            edges = edge_table(offsets, fverts);
          }
        }
      }
      std::vector<char> unweld(next, 0);
      bool any = false;
      for (int e = 0; e < edges.num_edges(); ++e)
        if (edges.uses(e) > 2)
          unweld[edges.lo(e)] = unweld[edges.hi(e)] = any = true;
      for (int f = 0; f < nf && !same; ++f) { // a weld that collapses a face (none without a weld)
        const int b = offsets[f], n = offsets[f + 1] - b;
        for (int i = 0; i < n; ++i)
          for (int j = i + 1; j < n; ++j)
            if (fverts[b + i] == fverts[b + j])
              unweld[fverts[b + i]] = any = true;
      }
      if (!any) {
        // Non-manifold vertices: undo their weld; one that was never welded is refused.
        std::vector<int> members(next, 0);
        for (int v = 0; v < nin; ++v)
          members[to_welded[v]]++;
        for (int w : non_manifold_vertices(next, offsets, fverts, edges)) {
          if (members[w] > 1) {
            unweld[w] = any = true;
            continue;
          }
          int input = 0;
          while (to_welded[input] != w)
            ++input;
          throw InputError(source, "vertex " + std::to_string(input), "non-manifold: its faces form more than one fan");
        }
      }
      if (!any)
        break;
      if (round > 64)
        throw InputError(source, "", "could not weld the mesh into a manifold");
      for (int v = 0; v < nin; ++v)
        if (unweld[to_welded[v]] && group[v] != v) {
          group[v] = v;
          ++refused_welds;
        }
    }
  };
  weld();

  // Open seams: vertices on the boundary that lie within
  // Tolerances::seam_weld_rel of another boundary vertex are one point
  // written twice, each copy rounded its own way (a file whose primitives
  // were quantized or compressed one by one: Draco's 14 bits over each
  // primitive's box). They are welded where that leaves fewer boundary
  // edges and a manifold; otherwise the exact weld stands. A closed mesh
  // never comes here.
  int seam_welds = 0;
  auto boundary_edges = [&] {
    int count = 0;
    for (int e = 0; e < edges.num_edges(); ++e)
      count += edges.uses(e) == 1;
    return count;
  };
  if (const int open = boundary_edges(); open > 0 && measure_thin) {
    const double tol = detail::Tolerances::seam_weld_rel / inv_diag;
    std::vector<char> on_boundary(static_cast<size_t>(*std::max_element(to_welded.begin(), to_welded.end())) + 1, 0);
    for (int e = 0; e < edges.num_edges(); ++e)
      if (edges.uses(e) == 1)
        on_boundary[edges.lo(e)] = on_boundary[edges.hi(e)] = 1;
    std::map<std::array<long long, 3>, std::vector<int>> cells; // boundary input vertices by cell of side tol
    // Cells counted from the box's corner, in units of the diagonal, so
    // that a mesh far from the origin stays within a cell index's range.
    auto cell = [&](const Vec3& p) {
      const Vec3 q = (p - box.min()) * inv_diag / detail::Tolerances::seam_weld_rel;
      return std::array<long long, 3>{static_cast<long long>(std::floor(q.x())),
                                      static_cast<long long>(std::floor(q.y())),
                                      static_cast<long long>(std::floor(q.z()))};
    };
    for (int v = 0; v < nin; ++v)
      if (to_welded[v] >= 0 && on_boundary[to_welded[v]])
        cells[cell(raw.positions[v])].push_back(v);
    // Each boundary vertex's shortest edge: two points less than half of it
    // apart are one point written twice, not two corners of the surface (a
    // model with edges shorter than the tolerance keeps them).
    std::vector<double> shortest(on_boundary.size(), std::numeric_limits<double>::infinity());
    std::vector<int> position_of(on_boundary.size(), -1); // an input vertex of each welded one
    for (int v = 0; v < nin; ++v)
      if (to_welded[v] >= 0)
        position_of[to_welded[v]] = v;
    for (int f = 0; f < nf; ++f)
      for (int i = offsets[f], n = offsets[f + 1] - offsets[f]; i < offsets[f + 1]; ++i) {
        const int a = fverts[i], b = fverts[offsets[f] + (i - offsets[f] + 1) % n];
        if (!on_boundary[a] && !on_boundary[b])
          continue;
        const double length = (raw.positions[position_of[a]] - raw.positions[position_of[b]]).norm();
        shortest[a] = std::min(shortest[a], length);
        shortest[b] = std::min(shortest[b], length);
      }
    std::vector<int> joined(static_cast<size_t>(nin));
    std::iota(joined.begin(), joined.end(), 0);
    auto find = [&](int r) {
      while (joined[r] != r)
        r = joined[r] = joined[joined[r]];
      return r;
    };
    int merges = 0;
    for (const auto& [c, members] : cells)
      for (const int v : members)
        for (long long dx = -1; dx <= 1; ++dx)
          for (long long dy = -1; dy <= 1; ++dy)
            for (long long dz = -1; dz <= 1; ++dz) {
              const auto it = cells.find({c[0] + dx, c[1] + dy, c[2] + dz});
              if (it == cells.end())
                continue;
              for (const int u : it->second) {
                const double apart = (raw.positions[u] - raw.positions[v]).norm();
                if (apart > tol || apart >= 0.5 * std::min(shortest[to_welded[u]], shortest[to_welded[v]]))
                  continue;
                const int ru = find(group[u]), rv = find(group[v]);
                if (ru != rv) {
                  joined[std::max(ru, rv)] = std::min(ru, rv);
                  ++merges;
                }
              }
            }
    if (merges > 0) {
      // The exact weld kept, to go back to.
      auto kept = std::make_tuple(group, to_welded, fverts, verts, offsets, nf, repeated, refused_welds);
      const EdgeTable kept_edges = edges;
      if (verts.empty()) // moved into fverts when nothing welded: the input's ids
        verts = fverts;
      for (int v = 0; v < nin; ++v)
        group[v] = find(group[v]);
      const int refused_before = refused_welds;
      bool better = false;
      try {
        weld();
        better = boundary_edges() < open;
      } catch (const InputError&) {
      }
      if (better) {
        seam_welds = merges - (refused_welds - refused_before);
        refused_welds = refused_before;
      } else {
        std::tie(group, to_welded, fverts, verts, offsets, nf, repeated, refused_welds) = std::move(kept);
        edges = kept_edges;
      }
    }
  }

  // Welded vertices that no face uses (a degenerate face's corners away
  // from every other face) follow their nearest neighbour that one does,
  // so that the welded vertices are exactly the surface's.
  std::vector<char> used(static_cast<size_t>(*std::max_element(to_welded.begin(), to_welded.end())) + 1, 0);
  for (int w : fverts)
    used[w] = 1;
  std::vector<int> compact(used.size(), -1);
  int nw = 0;
  for (size_t w = 0; w < used.size(); ++w)
    if (used[w])
      compact[w] = nw++;
  std::vector<Vec3> welded_pos;
  int followers = 0;
  bool renumbered = false;
  if (nw == nin) { // nothing welded and every vertex used: the ids as given (raw.positions is not read again)
    welded_pos = steal ? std::move(steal->positions) : raw.positions;
  } else {
    welded_pos.resize(nw);
    for (int v = 0; v < nin; ++v)
      if (compact[to_welded[v]] >= 0)
        welded_pos[compact[to_welded[v]]] = raw.positions[v];
    std::optional<NearestPoint> nearest; // built for the first follower
    for (int v = 0; v < nin; ++v) {
      if (compact[to_welded[v]] >= 0)
        continue;
      if (!nearest)
        nearest.emplace(welded_pos);
      to_welded[v] = -2 - nearest->of(raw.positions[v]); // resolved below
      ++followers;
    }
    for (int v = 0; v < nin; ++v)
      to_welded[v] = to_welded[v] <= -2 ? -2 - to_welded[v] : compact[to_welded[v]];
    for (auto& w : fverts) {
      renumbered |= compact[w] != w;
      w = compact[w];
    }
  }

  SurfaceMesh mesh;
  mesh.source = source;
  mesh.input_to_welded = std::move(to_welded);
  mesh.positions = std::move(welded_pos);
  mesh.face_offsets = std::move(offsets);
  mesh.face_vertices = std::move(fverts);
  if (dropped > 0)
    mesh.notes.push_back(
        "left out " + std::to_string(dropped) +
        " degenerate faces (two corners at one point, or no area) of the surface it works on" +
        (followers > 0 ? "; " + std::to_string(followers) + " of their vertices follow their nearest neighbour" : "") +
        (closed_slits > 0 ? "; the slits " + std::to_string(closed_slits) +
                                " of them left are closed by splitting the triangle across"
                          : "") +
        (near_welds > 0 ? "; " + std::to_string(near_welds) +
                              " of their corners, a few units in the last place from another, are welded to it"
                        : ""));
  if (repeated > 0)
    mesh.notes.push_back("left out " + std::to_string(repeated) +
                         " faces that repeat another face's corners (doubled faces) of the surface it works on");
  if (seam_welds > 0) {
    std::ostringstream note;
    note << "closed open seams: welded " << seam_welds << " boundary vertices to another within "
         << detail::Tolerances::seam_weld_rel << " of the diagonal (a file whose parts were rounded apart)";
    mesh.notes.push_back(note.str());
  }
  if (nw < nin)
    mesh.notes.push_back("welded " + std::to_string(nin) + " input vertices into " + std::to_string(nw) +
                         " by position");
  if (refused_welds > 0)
    mesh.notes.push_back("kept " + std::to_string(refused_welds) +
                         " coincident vertices apart, where welding would break manifoldness");

  // Orientation: make every component consistent with its lowest face.
  if (renumbered)
    edges = edge_table(mesh.face_offsets, mesh.face_vertices);
  const int flipped = orient_consistently(mesh, edges);
  if (flipped > 0)
    mesh.notes.push_back("repaired inconsistent orientation: reversed " + std::to_string(flipped) + " faces");
  if (const auto [parts, faces] = turn_closed_parts_outward(mesh); parts > 0)
    mesh.notes.push_back("turned " + std::to_string(parts) + (parts == 1 ? " closed part" : " closed parts") +
                         " outward (" + std::to_string(faces) + " faces): " + (parts == 1 ? "it was" : "they were") +
                         " wound inside out, normals pointing in (a mirrored export, or flipped normals)");
  return mesh;
}
} // namespace

} // namespace curvenet
