#pragma once
// Small fixtures built in code, and paths to the shared data.

#include "curvenet/io.hpp"
#include "curvenet/surface_mesh.hpp"
#include "generate/tube.hpp"

#include <filesystem>
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

/// A fresh temporary folder for one test.
inline std::filesystem::path temp_dir(const std::string& name) {
  auto p = std::filesystem::temp_directory_path() / ("curvenet_test_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

} // namespace curvenet::test
