#pragma once
// Plane sections of a surface: the closed and open polylines where a plane
// cuts the mesh. Which side of the plane a vertex lies on is decided
// exactly; a vertex on the plane counts as above it (symbolic
// perturbation), so every section passes through edge interiors and the
// polylines close on a closed surface.

#include "core/polyline_distance.hpp"
#include "curvenet/surface_mesh.hpp"

#include <array>
#include <optional>
#include <vector>

namespace curvenet::detail {

using Vec3 = Eigen::Vector3d;

/// The mesh triangulated (polygons as fans) with an edge table, for sections,
/// and a tree of boxes over the triangles, so that a section visits the
/// triangles near its plane rather than every vertex (a starter on a dense
/// mesh asks for thousands of sections).
class SectionMesh {
public:
  explicit SectionMesh(const SurfaceMesh& mesh);
  [[nodiscard]] const SurfaceMesh& mesh() const { return mesh_; }
  [[nodiscard]] int num_triangles() const { return static_cast<int>(tri_.size()); }
  [[nodiscard]] const std::array<int, 3>& tri(int t) const { return tri_[t]; }
  [[nodiscard]] const std::array<int, 3>& tri_edges(int t) const { return tri_edge_[t]; } ///< edge k: corner k -> k+1
  [[nodiscard]] const std::array<int, 2>& edge(int e) const { return edge_[e]; }
  [[nodiscard]] const std::array<int, 2>& edge_tris(int e) const { return edge_tri_[e]; }
  [[nodiscard]] int num_edges() const { return static_cast<int>(edge_.size()); }
  /// Every triangle that may hold a point on each side of the plane through
  /// `origin` with unit normal `n` (and perhaps a few more), in no order.
  /// Conservative: the boxes passed over lie off the plane by far more than
  /// rounding; the side of each vertex is left to the exact predicate.
  void triangles_near_plane(const Vec3& origin, const Vec3& n, std::vector<int>& out) const;

private:
  struct Node {
    Eigen::AlignedBox3d box;
    int begin = 0, end = 0; ///< its triangles: order_[begin, end)
    int second = -1;        ///< the second child (the first is the next node); -1 for a leaf
  };
  int build(int begin, int end, std::vector<Vec3>& centre);
  const SurfaceMesh& mesh_;
  std::vector<std::array<int, 3>> tri_, tri_edge_;
  std::vector<std::array<int, 2>> edge_, edge_tri_;
  std::vector<int> order_;
  std::vector<Node> node_;
};

struct Section {
  std::vector<Vec3> points; ///< on mesh edges, in order
  bool closed = false;
  [[nodiscard]] double length() const;
};

/// Every polyline where the plane through `origin` with normal `normal` cuts the mesh.
std::vector<Section> plane_sections(const SectionMesh& mesh, const Vec3& origin, const Vec3& normal);

/// The way along the surface from a through m to b inside the plane through
/// the three: the part of one section that holds all three points (each
/// within `tol` of it) and meets them in that order, a and b put at its
/// ends. None when the points are collinear or no section holds them.
std::optional<std::vector<Vec3>> section_path_through(const SectionMesh& mesh, const Vec3& a, const Vec3& m,
                                                      const Vec3& b, double tol);

/// An orthonormal basis (u, v) of the plane with normal n, with u x v = n / |n|.
std::array<Vec3, 2> plane_basis(const Vec3& n);

/// Winding number of a closed polygon (in the plane through `origin` with
/// normal `normal`) around point p of that plane; exact orientation tests.
int winding_number(const std::vector<Vec3>& loop, const Vec3& p, const Vec3& origin, const Vec3& normal);

/// Smallest distance between two polylines (closed when `closed_*`).
double polyline_distance(const std::vector<Vec3>& a, bool closed_a, const std::vector<Vec3>& b, bool closed_b);

/// Whether polylines a and b come closer than d: polyline_distance(...) < d,
/// without measuring the pairs of segments that cannot.
bool polylines_within(const std::vector<Vec3>& a, bool closed_a, const std::vector<Vec3>& b, bool closed_b, double d);

} // namespace curvenet::detail
