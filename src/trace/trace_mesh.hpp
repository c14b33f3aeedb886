#pragma once
// The surface as the tracer sees it: the input polygons triangulated, with
// triangle adjacency, the input edge under each triangle side (or -1 for a
// diagonal inside a polygon), and a closest-point query (Embree BVH).

#include "cut/cut_mesh.hpp"

#include <array>
#include <memory>
#include <optional>
#include <span>
#include <utility>
#include <vector>

namespace curvenet::detail {

using Vec3 = Eigen::Vector3d;

/// A point of the surface. Vertex and Edge points are exact: they lie on an
/// input vertex or on an input edge (parameter t along its half-edge 2e).
/// A Face point lies inside triangle `tri` (or on one of its diagonals).
struct SurfacePoint {
  enum class Kind { Vertex, Edge, Face } kind = Kind::Face;
  int vertex = -1;
  int edge = -1;
  double t = 0;
  int tri = -1;
  Vec3 pos = Vec3::Zero();
};

/// Lists of ints for each of n keys, in one flat array (compressed rows).
class Adjacency {
public:
  /// Builds the lists from (key, value) pairs; each list keeps the pairs' order.
  static Adjacency build(int keys, const std::vector<std::pair<int, int>>& pairs);
  [[nodiscard]] std::span<const int> operator[](int key) const {
    return {items_.data() + offset_[key], static_cast<size_t>(offset_[key + 1] - offset_[key])};
  }

private:
  std::vector<int> offset_, items_;
};

class TraceMesh {
public:
  /// \pre `cut` is CutMesh::from_surface(mesh), not yet cut. The trace mesh
  /// copies what it needs: `cut` may be cut afterwards.
  TraceMesh(const SurfaceMesh& mesh, const CutMesh& cut);
  ~TraceMesh();
  TraceMesh(const TraceMesh&) = delete;
  TraceMesh& operator=(const TraceMesh&) = delete;

  [[nodiscard]] int num_triangles() const { return static_cast<int>(tri_.size()); }
  [[nodiscard]] const std::array<int, 3>& tri(int t) const { return tri_[t]; }
  [[nodiscard]] int tri_face(int t) const { return tri_face_[t]; }
  /// Input edge under side k (corner k to corner k+1) of triangle t, or -1.
  [[nodiscard]] int side_edge(int t, int k) const { return side_edge_[t][k]; }
  /// Triangle across side k of t, or -1 on the boundary.
  [[nodiscard]] int neighbour(int t, int k) const { return nbr_[t][k]; }
  [[nodiscard]] std::span<const int> vertex_triangles(int v) const { return vertex_tris_[v]; }
  [[nodiscard]] std::span<const int> edge_triangles(int e) const { return edge_tris_[e]; }
  [[nodiscard]] const Vec3& position(int v) const { return mesh_.positions[v]; }
  [[nodiscard]] Vec3 tri_normal(int t) const;
  /// The mean length of the input edges under triangle t's sides (all
  /// three sides for a triangle inside a polygon with no input edge).
  [[nodiscard]] double edge_length(int t) const;
  [[nodiscard]] const SurfaceMesh& mesh() const { return mesh_; }
  /// mesh().mean_edge_length(), computed once.
  [[nodiscard]] double mean_edge_length() const { return mean_edge_length_; }
  /// The two ends of input edge e, in the direction of its half-edge 2e.
  [[nodiscard]] const std::array<int, 2>& edge_ends(int e) const { return edge_ends_[e]; }
  /// Input edges around input vertex v.
  [[nodiscard]] std::span<const int> vertex_edges(int v) const { return vertex_edges_[v]; }

  /// The surface point at input vertex v.
  [[nodiscard]] SurfacePoint vertex_point(int v) const {
    SurfacePoint p;
    p.kind = SurfacePoint::Kind::Vertex;
    p.vertex = v;
    p.tri = vertex_tris_[v].empty() ? -1 : vertex_tris_[v].front();
    p.pos = position(v);
    return p;
  }
  /// Triangles that contain p (one for a face point, two for an edge, the
  /// fan for a vertex; a face point on a diagonal also gets its neighbour).
  [[nodiscard]] std::vector<int> triangles_of(const SurfacePoint& p) const;
  /// Input faces that contain p.
  [[nodiscard]] std::vector<int> faces_of(const SurfacePoint& p) const;

  /// The closest point of the surface to q, classified exactly by the
  /// closest-point region (a vertex, an edge, or the inside of a triangle).
  [[nodiscard]] SurfacePoint closest_point(const Vec3& q) const;

  /// The exact closest point of the surface to q, without any snapping.
  struct Nearest {
    int tri = -1;
    Vec3 point = Vec3::Zero();
    std::array<double, 3> bary{};
    [[nodiscard]] double distance(const Vec3& q) const { return (point - q).norm(); }
  };
  [[nodiscard]] Nearest nearest(const Vec3& q) const;

  /// The first point where the ray origin + t * dir (0 <= t <= t_max, dir a
  /// unit vector) meets a triangle whose normal points along `facing`
  /// (positive dot product); triangles facing the other way are passed
  /// through. The point is recomputed in double precision on the triangle.
  [[nodiscard]] std::optional<Nearest> ray_hit(const Vec3& origin, const Vec3& dir, double t_max,
                                               const Vec3& facing) const;

  /// Whether the segment from `a` to `b` meets a triangle anywhere past the
  /// first `skip` of its length (a segment that starts on the surface leaves
  /// its own triangles out that way). A segment Embree cannot take (not
  /// finite, or past single precision) counts as blocked.
  [[nodiscard]] bool segment_blocked(const Vec3& a, const Vec3& b, double skip) const;

private:
  const SurfaceMesh& mesh_;
  double mean_edge_length_;
  std::vector<std::array<int, 2>> edge_ends_;
  Adjacency vertex_edges_;
  std::vector<std::array<int, 3>> tri_;
  std::vector<int> tri_face_;
  std::vector<std::array<int, 3>> side_edge_;
  std::vector<std::array<int, 3>> nbr_;
  Adjacency vertex_tris_;
  Adjacency edge_tris_;
  struct Bvh;
  std::unique_ptr<Bvh> bvh_;
};

/// Angle-weighted vertex normals of a trace mesh (the same whichever way
/// the polygons around a vertex are split into triangles), interpolated
/// inside its triangles.
class SmoothNormals {
public:
  explicit SmoothNormals(const TraceMesh& mesh);
  /// The normal at the point of triangle t with barycentric coordinates `bary`.
  [[nodiscard]] Vec3 at(int t, const std::array<double, 3>& bary) const;

private:
  const TraceMesh& mesh_;
  std::vector<Vec3> vertex_;
};

} // namespace curvenet::detail
