// Validation, welding and orientation repair of input meshes.

#include "curvenet/surface_mesh.hpp"
#include "core/predicates.hpp"
#include "curvenet/errors.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <queue>
#include <sstream>
#include <unordered_map>

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
      element_(std::move(element)) {}

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

namespace {

struct EdgeUse {
  int face;
  bool forward; // the face runs a -> b with a < b
};

using EdgeKey = std::pair<int, int>;
EdgeKey edge_key(int a, int b) {
  return a < b ? EdgeKey{a, b} : EdgeKey{b, a};
}

/// Undirected edges of a polygon soup, with the faces that use them.
std::map<EdgeKey, std::vector<EdgeUse>> edge_uses(const std::vector<int>& offsets, const std::vector<int>& verts) {
  std::map<EdgeKey, std::vector<EdgeUse>> uses;
  for (size_t f = 0; f + 1 < offsets.size(); ++f) {
    const int n = offsets[f + 1] - offsets[f];
    for (int i = 0; i < n; ++i) {
      const int a = verts[offsets[f] + i];
      const int b = verts[offsets[f] + (i + 1) % n];
      uses[edge_key(a, b)].push_back({static_cast<int>(f), a < b});
    }
  }
  return uses;
}

/// Vertices whose incident faces form more than one fan (non-manifold
/// vertices), given manifold edges.
std::vector<int> non_manifold_vertices(int nv, const std::vector<int>& offsets, const std::vector<int>& verts,
                                       const std::map<EdgeKey, std::vector<EdgeUse>>& uses) {
  // For each vertex, union-find over its incident face corners, joined when
  // two faces share an edge at that vertex.
  std::vector<std::vector<int>> vfaces(nv);
  for (size_t f = 0; f + 1 < offsets.size(); ++f)
    for (int k = offsets[f]; k < offsets[f + 1]; ++k)
      vfaces[verts[k]].push_back(static_cast<int>(f));
  std::vector<int> bad;
  for (int v = 0; v < nv; ++v) {
    auto& fs = vfaces[v];
    if (fs.size() <= 1)
      continue;
    std::sort(fs.begin(), fs.end());
    fs.erase(std::unique(fs.begin(), fs.end()), fs.end());
    std::vector<int> parent(fs.size());
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int x) {
      while (parent[x] != x)
        x = parent[x] = parent[parent[x]];
      return x;
    };
    auto index_of = [&](int f) { return static_cast<int>(std::lower_bound(fs.begin(), fs.end(), f) - fs.begin()); };
    for (int f : fs) {
      const int n = offsets[f + 1] - offsets[f];
      for (int i = 0; i < n; ++i) {
        if (verts[offsets[f] + i] != v)
          continue;
        for (int nb : {verts[offsets[f] + (i + 1) % n], verts[offsets[f] + (i + n - 1) % n]}) {
          auto it = uses.find(edge_key(v, nb));
          if (it == uses.end())
            continue;
          for (const auto& u : it->second)
            parent[find(index_of(u.face))] = find(index_of(f));
        }
      }
    }
    int roots = 0;
    for (size_t i = 0; i < fs.size(); ++i)
      roots += find(static_cast<int>(i)) == static_cast<int>(i);
    if (roots > 1)
      bad.push_back(v);
  }
  return bad;
}

std::string vec_str(const Vec3& p) {
  std::ostringstream s;
  s.precision(9);
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

struct VecHash {
  size_t operator()(const Vec3& p) const {
    size_t h = 0;
    for (int i = 0; i < 3; ++i) {
      double d = p[i] == 0.0 ? 0.0 : p[i]; // -0 and +0 weld
      h ^= std::hash<double>{}(d) + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    }
    return h;
  }
};

} // namespace

std::vector<ComponentInfo> mesh_components(const SurfaceMesh& mesh, std::vector<int>* face_component) {
  const int nf = mesh.num_faces();
  auto uses = edge_uses(mesh.face_offsets, mesh.face_vertices);
  std::vector<std::vector<int>> adj(nf);
  for (const auto& [k, u] : uses)
    if (u.size() == 2) {
      adj[u[0].face].push_back(u[1].face);
      adj[u[1].face].push_back(u[0].face);
    }
  std::vector<int> comp(nf, -1);
  std::vector<ComponentInfo> out;
  for (int s = 0; s < nf; ++s) {
    if (comp[s] >= 0)
      continue;
    const int c = static_cast<int>(out.size());
    out.emplace_back();
    std::vector<int> stack{s};
    comp[s] = c;
    while (!stack.empty()) {
      int f = stack.back();
      stack.pop_back();
      for (int g : adj[f])
        if (comp[g] < 0) {
          comp[g] = c;
          stack.push_back(g);
        }
    }
  }
  std::vector<std::vector<char>> seen_vertex(out.size());
  std::vector<int> nverts(out.size(), 0), nedges(out.size(), 0);
  std::vector<char> vseen(mesh.num_vertices(), 0);
  for (int f = 0; f < nf; ++f) {
    out[comp[f]].faces++;
    for (int v : mesh.face(f))
      if (!vseen[v]) {
        vseen[v] = 1;
        nverts[comp[f]]++;
      }
  }
  std::vector<char> open(out.size(), 0);
  for (const auto& [k, u] : uses) {
    nedges[comp[u[0].face]]++;
    if (u.size() == 1)
      open[comp[u[0].face]] = 1;
  }
  for (size_t c = 0; c < out.size(); ++c) {
    out[c].closed = !open[c];
    out[c].euler = nverts[c] - nedges[c] + out[c].faces;
  }
  if (face_component)
    *face_component = std::move(comp);
  return out;
}

SurfaceMesh make_surface_mesh(const RawMesh& raw, const std::string& source) {
  const int nin = static_cast<int>(raw.positions.size());
  const int nf = static_cast<int>(raw.face_offsets.size()) - 1;
  if (nf <= 0)
    throw InputError(source, "", "the mesh has no faces");
  for (int v = 0; v < nin; ++v)
    if (!raw.positions[v].allFinite())
      throw InputError(source, "vertex " + std::to_string(v), "non-finite coordinate " + vec_str(raw.positions[v]));
  for (int f = 0; f < nf; ++f) {
    const int n = raw.face_offsets[f + 1] - raw.face_offsets[f];
    if (n < 3)
      throw InputError(source, "face " + std::to_string(f),
                       "has " + std::to_string(n) + " corners; at least 3 are needed");
    for (int k = raw.face_offsets[f]; k < raw.face_offsets[f + 1]; ++k)
      if (raw.face_vertices[k] < 0 || raw.face_vertices[k] >= nin)
        throw InputError(source, "face " + std::to_string(f),
                         "refers to vertex " + std::to_string(raw.face_vertices[k]) + ", which does not exist");
  }

  // Faces that are degenerate in the input itself (before any weld).
  auto check_degenerate = [&](const std::vector<Vec3>& pos, const std::vector<int>& verts, const char* what) {
    for (int f = 0; f < nf; ++f) {
      const int b = raw.face_offsets[f], n = raw.face_offsets[f + 1] - b;
      for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j)
          if (verts[b + i] == verts[b + j] || pos[verts[b + i]] == pos[verts[b + j]])
            throw InputError(source, "face " + std::to_string(f),
                             std::string("degenerate: corners ") + std::to_string(i) + " and " + std::to_string(j) +
                                 " are the same " + what);
      bool all_collinear = true;
      for (int i = 1; i + 1 < n && all_collinear; ++i)
        all_collinear = detail::collinear3d(pos[verts[b]], pos[verts[b + i]], pos[verts[b + i + 1]]);
      if (all_collinear)
        throw InputError(source, "face " + std::to_string(f), "degenerate: its corners are collinear (zero area)");
    }
  };
  check_degenerate(raw.positions, raw.face_vertices, "point");

  // Non-manifold edges in the input as given (no weld) are refused. A vertex
  // that is non-manifold as given may be mended by welding (a glTF seam can
  // split a fan); that is judged after the weld.
  {
    auto uses = edge_uses(raw.face_offsets, raw.face_vertices);
    for (const auto& [k, u] : uses)
      if (u.size() > 2)
        throw InputError(source, "edge " + std::to_string(k.first) + "-" + std::to_string(k.second),
                         "non-manifold: shared by " + std::to_string(u.size()) + " faces");
  }

  // Weld by exact position, then undo welds that break manifoldness.
  std::vector<int> group(nin);
  {
    std::unordered_map<Vec3, int, VecHash> first;
    for (int v = 0; v < nin; ++v)
      group[v] = first.emplace(raw.positions[v], v).first->second;
  }
  std::vector<int> to_welded;
  std::vector<int> fverts;
  int refused_welds = 0;
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
    fverts.resize(raw.face_vertices.size());
    for (size_t k = 0; k < fverts.size(); ++k)
      fverts[k] = to_welded[raw.face_vertices[k]];
    auto uses = edge_uses(raw.face_offsets, fverts);
    std::vector<char> unweld(next, 0);
    bool any = false;
    for (const auto& [k, u] : uses)
      if (u.size() > 2)
        unweld[k.first] = unweld[k.second] = any = true;
    for (int f = 0; f < nf; ++f) { // a weld that collapses a face
      const int b = raw.face_offsets[f], n = raw.face_offsets[f + 1] - b;
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
      for (int w : non_manifold_vertices(next, raw.face_offsets, fverts, uses)) {
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

  SurfaceMesh mesh;
  mesh.source = source;
  mesh.input_to_welded = to_welded;
  int nw = 0;
  for (int w : to_welded)
    nw = std::max(nw, w + 1);
  mesh.positions.resize(nw);
  for (int v = 0; v < nin; ++v)
    mesh.positions[to_welded[v]] = raw.positions[v];
  mesh.face_offsets = raw.face_offsets;
  mesh.face_vertices = fverts;
  if (nw < nin)
    mesh.notes.push_back("welded " + std::to_string(nin) + " input vertices into " + std::to_string(nw) +
                         " by position");
  if (refused_welds > 0)
    mesh.notes.push_back("kept " + std::to_string(refused_welds) +
                         " coincident vertices apart, where welding would break manifoldness");

  // Orientation: make every component consistent with its lowest face.
  auto uses = edge_uses(mesh.face_offsets, mesh.face_vertices);
  std::vector<std::vector<std::pair<int, bool>>> adj(nf); // neighbour, same-direction use
  for (const auto& [k, u] : uses)
    if (u.size() == 2) {
      const bool conflict = u[0].forward == u[1].forward;
      adj[u[0].face].push_back({u[1].face, conflict});
      adj[u[1].face].push_back({u[0].face, conflict});
    }
  std::vector<int> flip(nf, -1);
  int flipped = 0;
  for (int s = 0; s < nf; ++s) {
    if (flip[s] >= 0)
      continue;
    flip[s] = 0;
    std::queue<int> q;
    q.push(s);
    std::vector<int> members;
    while (!q.empty()) {
      int f = q.front();
      q.pop();
      members.push_back(f);
      for (auto [g, conflict] : adj[f]) {
        const int want = flip[f] ^ static_cast<int>(conflict);
        if (flip[g] < 0) {
          flip[g] = want;
          q.push(g);
        } else if (flip[g] != want) {
          throw InputError(source, "face " + std::to_string(g),
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
  if (flipped > 0) {
    for (int f = 0; f < nf; ++f)
      if (flip[f])
        std::reverse(mesh.face_vertices.begin() + mesh.face_offsets[f],
                     mesh.face_vertices.begin() + mesh.face_offsets[f + 1]);
    mesh.notes.push_back("repaired inconsistent orientation: reversed " + std::to_string(flipped) + " faces");
  }
  // A weld can make a face degenerate in welded terms only when positions coincide, which was checked above.
  return mesh;
}

} // namespace curvenet
