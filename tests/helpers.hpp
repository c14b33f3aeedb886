#pragma once
// Small fixtures built in code, and paths to the shared data.

#include "curvenet/io.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/surface_mesh.hpp"
#include "generate/tube.hpp"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace curvenet::test {

inline std::string data(const std::string& rel) {
  return std::string(CURVENET_DATA_DIR) + "/" + rel;
}
inline bool have_data() {
  return std::filesystem::exists(CURVENET_DATA_DIR);
}

/// The net `curvenet starter FILE` makes from a skinned file: rings on the
/// joints that carry skin weight, each node weighted by the file's skin.
inline Rig skinned_starter(const std::string& file) {
  const SkinnedMesh skin = load_skinned_mesh(file);
  StarterOptions so;
  so.skin = &skin;
  so.deforming = weighted_joints(skin);
  return make_starter(load_mesh(file), skin.joints, so).rig;
}

/// `part`'s faces added to `to` as a part of their own, its points scaled
/// by `scale` and moved by `offset`.
inline void add_part(RawMesh& to, const RawMesh& part, const Vec3& offset, double scale = 1.0) {
  const int base = static_cast<int>(to.positions.size());
  for (const Vec3& p : part.positions)
    to.positions.push_back(scale * p + offset);
  for (size_t f = 0; f + 1 < part.face_offsets.size(); ++f) {
    std::vector<int> corners;
    for (int k = part.face_offsets[f]; k < part.face_offsets[f + 1]; ++k)
      corners.push_back(base + part.face_vertices[static_cast<size_t>(k)]);
    to.add_face(corners);
  }
}

/// `r` with every face's corners in reverse order: wound the other way.
inline RawMesh reversed(RawMesh r) {
  for (size_t f = 0; f + 1 < r.face_offsets.size(); ++f)
    std::reverse(r.face_vertices.begin() + r.face_offsets[f], r.face_vertices.begin() + r.face_offsets[f + 1]);
  return r;
}

/// An n x m grid of unit quads in the plane z = 0, from (0,0) to (n,m).
inline RawMesh grid(int n, int m, bool triangles = false) {
  RawMesh r;
  for (int j = 0; j <= m; ++j)
    for (int i = 0; i <= n; ++i)
      r.positions.emplace_back(i, j, 0);
  auto id = [n](int i, int j) { return j * (n + 1) + i; };
  for (int j = 0; j < m; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      if (triangles) {
        r.add_face(std::vector<int>{a, b, c});
        r.add_face(std::vector<int>{a, c, d});
      } else {
        r.add_face(std::vector<int>{a, b, c, d});
      }
    }
  return r;
}

/// The box [0,1] x [0,1] x [0,height]: six quads facing out.
inline RawMesh box(double height = 1) {
  RawMesh r;
  for (int k = 0; k < 8; ++k)
    r.positions.emplace_back(k & 1, (k >> 1) & 1, (k >> 2) ? height : 0.0);
  for (const auto& f : std::vector<std::vector<int>>{
           {0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}})
    r.add_face(f);
  return r;
}

/// A validated capped tube (generate/tube.hpp), moved by `m` when given.
inline SurfaceMesh tube(int around, int along, int cap_rings, bool triangulate, const Mat4& m = Mat4::Identity()) {
  TubeSpec s;
  s.around = around;
  s.along = along;
  s.cap_rings = cap_rings;
  s.triangulate = triangulate;
  RawMesh raw = make_capped_tube(s);
  for (auto& p : raw.positions)
    p = (m * p.homogeneous()).head<3>();
  return make_surface_mesh(raw, "tube");
}

/// The faces of a capped tube (generate/tube.hpp) without those of its
/// top cap (every corner at y = length): an open mesh, as raw input.
inline RawMesh without_top_cap(const RawMesh& closed, const TubeSpec& spec) {
  RawMesh open;
  open.positions = closed.positions;
  for (int f = 0; f + 1 < static_cast<int>(closed.face_offsets.size()); ++f) {
    std::vector<int> corners(closed.face_vertices.begin() + closed.face_offsets[f],
                             closed.face_vertices.begin() + closed.face_offsets[f + 1]);
    if (!std::all_of(corners.begin(), corners.end(),
                     [&](int v) { return closed.positions[v].y() >= spec.length - 1e-9; }))
      open.add_face(corners);
  }
  return open;
}

/// A file's bytes, as they are on disk.
inline std::string file_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// A fresh temporary folder for one test, removed with what it holds when
/// the test's variable goes out of scope (set CURVENET_KEEP_TEST_FILES to
/// keep it for a look). It is a path; a copy of it as a plain path does not
/// own the folder.
class TempDir : public std::filesystem::path {
public:
  explicit TempDir(std::filesystem::path p) : std::filesystem::path(std::move(p)) {
    std::filesystem::remove_all(*this);
    std::filesystem::create_directories(*this);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  ~TempDir() {
    if (std::getenv("CURVENET_KEEP_TEST_FILES") != nullptr)
      return;
    std::error_code ignored;
    std::filesystem::remove_all(*this, ignored);
  }
};

inline TempDir temp_dir(const std::string& name) {
  return TempDir(std::filesystem::temp_directory_path() / ("curvenet_test_" + name + "_" + std::to_string(::getpid())));
}

} // namespace curvenet::test

namespace curvenet::test {

/// A closed surface where `f` changes sign (inside where f < 0), by marching
/// tetrahedra on an n x m x k grid over `box` (each cube in six tetrahedra
/// around its diagonal): the same edge gives the same vertex, so the mesh
/// is closed and manifold; faces point outwards.
inline RawMesh implicit_surface(const std::function<double(const Vec3&)>& f, const Eigen::AlignedBox3d& box, int n,
                                int m, int k) {
  RawMesh out;
  const Vec3 step = box.diagonal().cwiseQuotient(Vec3(n, m, k));
  auto at = [&](int i, int j, int l) { return Vec3(box.min() + step.cwiseProduct(Vec3(i, j, l))); };
  std::vector<double> value(static_cast<size_t>(n + 1) * (m + 1) * (k + 1));
  auto id = [&](int i, int j, int l) { return (static_cast<size_t>(l) * (m + 1) + j) * (n + 1) + i; };
  for (int l = 0; l <= k; ++l)
    for (int j = 0; j <= m; ++j)
      for (int i = 0; i <= n; ++i) {
        const double v = f(at(i, j, l));
        value[id(i, j, l)] = v == 0 ? 1e-12 : v; // never exactly on the surface
      }
  std::map<std::pair<size_t, size_t>, int> edge_vertex;
  auto vertex_on = [&](size_t a, size_t b, const Vec3& pa, const Vec3& pb) {
    const auto key = std::minmax(a, b);
    auto it = edge_vertex.find(key);
    if (it != edge_vertex.end())
      return it->second;
    const double t = value[a] / (value[a] - value[b]);
    out.positions.push_back(pa + t * (pb - pa));
    return edge_vertex[key] = static_cast<int>(out.positions.size()) - 1;
  };
  // Cube corner c (bits x, y, z); the six tetrahedra share the diagonal 0-7.
  static const int tets[6][4] = {{0, 1, 3, 7}, {0, 3, 2, 7}, {0, 2, 6, 7}, {0, 6, 4, 7}, {0, 4, 5, 7}, {0, 5, 1, 7}};
  for (int l = 0; l < k; ++l)
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < n; ++i)
        for (const auto& tet : tets) {
          size_t g[4];
          Vec3 p[4];
          for (int q = 0; q < 4; ++q) {
            const int c = tet[q], di = c & 1, dj = (c >> 1) & 1, dl = (c >> 2) & 1;
            g[q] = id(i + di, j + dj, l + dl);
            p[q] = at(i + di, j + dj, l + dl);
          }
          std::vector<int> in, outside;
          for (int q = 0; q < 4; ++q)
            (value[g[q]] < 0 ? in : outside).push_back(q);
          if (in.empty() || outside.empty())
            continue;
          // Triangles between the inside corners and the outside ones, then
          // turned to face away from the inside.
          std::vector<std::array<int, 3>> tris;
          auto v = [&](int a, int b) { return vertex_on(g[a], g[b], p[a], p[b]); };
          if (in.size() == 1)
            tris.push_back({v(in[0], outside[0]), v(in[0], outside[1]), v(in[0], outside[2])});
          else if (in.size() == 3)
            tris.push_back({v(outside[0], in[0]), v(outside[0], in[1]), v(outside[0], in[2])});
          else {
            const int a = v(in[0], outside[0]), b = v(in[0], outside[1]), c = v(in[1], outside[1]),
                      d = v(in[1], outside[0]);
            tris.push_back({a, b, c});
            tris.push_back({a, c, d});
          }
          Vec3 inside_point = Vec3::Zero();
          for (int q : in)
            inside_point += p[q] / static_cast<double>(in.size());
          for (auto& t : tris) {
            const Vec3 nrm =
                (out.positions[t[1]] - out.positions[t[0]]).cross(out.positions[t[2]] - out.positions[t[0]]);
            if (nrm.dot(out.positions[t[0]] - inside_point) < 0)
              std::swap(t[1], t[2]);
            out.add_face(std::vector<int>{t[0], t[1], t[2]});
          }
        }
  return out;
}

/// The signed distance to the capsule from a to b of radius r.
inline double capsule(const Vec3& p, const Vec3& a, const Vec3& b, double r) {
  const Vec3 d = b - a;
  const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return (p - a - t * d).norm() - r;
}

} // namespace curvenet::test
