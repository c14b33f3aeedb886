#pragma once
// The cut mesh: our own compact, index-based half-edge structure. It holds
// general polygons and cracks (an edge whose two half-edges border the same
// face), and carries curve data on its half-edges. Half-edges come in pairs:
// the twin of h is h ^ 1. Boundary half-edges have no face and are linked in
// boundary loops, so every half-edge has a twin, a next and a prev.

#include "curvenet/surface_mesh.hpp"

#include <Eigen/Core>

#include <array>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

namespace curvenet::detail {

/// A typed index: one int, an invalid sentinel, and nothing else.
template <class Tag> struct Handle {
  int idx = -1;
  constexpr Handle() = default;
  constexpr explicit Handle(int i) : idx(i) {}
  [[nodiscard]] constexpr bool is_valid() const { return idx >= 0; }
  constexpr bool operator==(const Handle&) const = default;
  constexpr auto operator<=>(const Handle&) const = default;
};
using Vertex = Handle<struct VertexTag>;
using Halfedge = Handle<struct HalfedgeTag>;
using Face = Handle<struct FaceTag>;

/// Which profile a half-edge lies on, and whether it runs in the profile's
/// direction. The twin of a tagged half-edge carries the same profile with
/// the opposite direction.
struct CurveTag {
  int profile = -1;
  bool forward = true;
  [[nodiscard]] bool is_curve() const { return profile >= 0; }
};

/// Where a cut-mesh vertex came from.
struct VertexOrigin {
  enum class Kind { Input, OnEdge, InFace } kind = Kind::Input;
  int index = -1; ///< input vertex (Input), input edge (OnEdge), input face (InFace)
  double t = 0;   ///< OnEdge: parameter along the input edge's first half-edge
};

/// A segment to insert across a face by subdivide_face.
struct Chord {
  Vertex a, b;
  CurveTag tag; ///< the tag of the half-edge a -> b
};

class CutMesh {
public:
  /// The half-edge structure of a validated surface mesh. Input vertex v is
  /// cut vertex v, input face f is cut face f, and input edge e (in the order
  /// edges are first met, face by face) is the half-edge pair (2e, 2e+1).
  static CutMesh from_surface(const SurfaceMesh& mesh);

  [[nodiscard]] int num_vertices() const { return static_cast<int>(position_.size()); }
  [[nodiscard]] int num_halfedges() const { return static_cast<int>(to_.size()); }
  [[nodiscard]] int num_edges() const { return num_halfedges() / 2; }
  [[nodiscard]] int num_faces() const { return static_cast<int>(face_halfedge_.size()); }

  [[nodiscard]] static Halfedge twin(Halfedge h) { return Halfedge(h.idx ^ 1); }
  [[nodiscard]] Halfedge next(Halfedge h) const { return next_[h.idx]; }
  [[nodiscard]] Halfedge prev(Halfedge h) const { return prev_[h.idx]; }
  [[nodiscard]] Vertex to(Halfedge h) const { return to_[h.idx]; }
  [[nodiscard]] Vertex from(Halfedge h) const { return to_[h.idx ^ 1]; }
  [[nodiscard]] Face face(Halfedge h) const { return face_[h.idx]; }
  [[nodiscard]] bool is_boundary(Halfedge h) const { return !face_[h.idx].is_valid(); }
  [[nodiscard]] Halfedge halfedge(Vertex v) const { return vertex_halfedge_[v.idx]; }
  [[nodiscard]] Halfedge halfedge(Face f) const { return face_halfedge_[f.idx]; }
  [[nodiscard]] const Eigen::Vector3d& position(Vertex v) const { return position_[v.idx]; }
  [[nodiscard]] const VertexOrigin& origin(Vertex v) const { return vertex_origin_[v.idx]; }
  [[nodiscard]] int face_origin(Face f) const { return face_origin_[f.idx]; }
  /// The input edge a half-edge lies on, or -1 for a half-edge cut across a face.
  [[nodiscard]] int edge_origin(Halfedge h) const { return edge_origin_[h.idx / 2]; }
  [[nodiscard]] const CurveTag& tag(Halfedge h) const { return tag_[h.idx]; }
  /// Tags h and its twin (the twin gets the opposite direction).
  void set_tag(Halfedge h, CurveTag t);

  /// The half-edges of a face's loop, starting at halfedge(f).
  [[nodiscard]] std::vector<Halfedge> face_loop(Face f) const;
  /// The same, into `loop` (cleared first), for loops over many faces.
  void face_loop(Face f, std::vector<Halfedge>& loop) const;
  /// Outgoing half-edges of a vertex, by rotation (twin, next).
  [[nodiscard]] std::vector<Halfedge> outgoing(Vertex v) const;
  [[nodiscard]] double face_area(Face f) const;
  [[nodiscard]] Eigen::Vector3d face_normal(Face f) const; ///< Newell normal, not normalised

  /// Splits the edge of h at a new vertex placed at `pos`. Afterwards h ends
  /// at the new vertex and next(h) starts at it; the twin side is split the
  /// same way. Curve tags carry over to both halves.
  Vertex split_edge(Halfedge h, const Eigen::Vector3d& pos, const VertexOrigin& origin);

  /// Adds a vertex with no edges yet: a point inside a face that a later
  /// subdivide_face connects.
  Vertex add_isolated_vertex(const Eigen::Vector3d& pos, const VertexOrigin& origin);

  /// Splits face f along non-crossing chords between vertices of its loop
  /// and isolated vertices inside it. The faces are rebuilt by sorting the
  /// half-edges around each vertex by angle in the face's plane (exact
  /// predicates). A chord that ends at an isolated vertex of degree one
  /// becomes a crack. f keeps one of the pieces; the others are new faces.
  /// Returns the half-edge a -> b of each chord.
  /// \throw EmbedError when a piece does not close into a simple face (a
  ///   chord leaves the face, or a group of chords touches no other).
  std::vector<Halfedge> subdivide_face(Face f, std::span<const Chord> chords);

  /// 2D coordinates of a vertex of face f, or of a vertex inside it, in the
  /// face's layout (for exact predicates). The layout is the input face's
  /// triangulation (the tracer's) unfolded into the plane, edge lengths
  /// kept, so a face that is far from flat keeps its shape; a flat face
  /// lays out as itself. Fixed when first asked for, and inherited by the
  /// pieces the face is split into.
  [[nodiscard]] Eigen::Vector2d to_face_plane(Face f, Vertex v) const;
  /// The same for a point of the surface inside face f that is not a vertex.
  [[nodiscard]] Eigen::Vector2d to_face_plane(Face f, const Eigen::Vector3d& inside) const;
  /// For a chord from a to b (vertices of face f, or inside it) that would
  /// leave the face in its layout (a polygon whose layout is not convex: a
  /// bent quad unfolds with a reflex corner), the points it should pass
  /// through instead, in order: one on each diagonal of the layout's
  /// triangulation between a's triangle and b's, where the straight chord's
  /// line meets that diagonal, kept inside it. Empty when a and b lie in one
  /// triangle of the layout.
  [[nodiscard]] std::vector<Eigen::Vector3d> detour(Face f, Vertex a, Vertex b) const;
  /// A vertex as an affine combination of input vertices, on the input
  /// surface: itself; the two ends of its input edge; or, inside an input
  /// face, the corners of the face's triangle nearest to it (barycentric).
  [[nodiscard]] std::vector<std::pair<int, double>> input_weights(Vertex v) const;

  /// The first broken invariant, or nothing when the mesh is valid: twin
  /// symmetry, next/prev inverse, closed loops with one face, vertex
  /// half-edges that start at their vertex, consistent tags.
  [[nodiscard]] std::optional<std::string> validate() const;

private:
  Halfedge new_edge(Vertex a, Vertex b, int edge_origin); // returns a -> b

  std::vector<Eigen::Vector3d> position_;
  std::vector<VertexOrigin> vertex_origin_;
  std::vector<Halfedge> vertex_halfedge_;
  std::vector<Vertex> to_;
  std::vector<Halfedge> next_, prev_;
  std::vector<Face> face_;
  std::vector<CurveTag> tag_;
  std::vector<int> edge_origin_;
  std::vector<Halfedge> face_halfedge_;
  std::vector<int> face_origin_;
  std::vector<std::array<int, 2>> input_edge_ends_; // input edge -> its two input vertices, along half-edge 2e
  std::vector<int> input_first_corner_;             // input face -> its first corner in the input (the tracer's order)
  // The unfolded layout of an input face: its corners (input vertices) in
  // the plane and its triangles, built on demand (see to_face_plane).
  struct Layout {
    std::vector<int> corners;
    std::vector<Eigen::Vector2d> uv;
    std::vector<std::array<int, 3>> tris; // indices into corners
  };
  const Layout& layout(Face f) const;
  /// The layout's triangle nearest to p, and p's closest point on it (barycentric).
  std::pair<std::array<int, 3>, std::array<double, 3>> nearest_triangle(const Layout& l,
                                                                        const Eigen::Vector3d& p) const;
  mutable std::unordered_map<int, Layout> layouts_; // input face -> layout
};

/// The connected components of a cut mesh fresh from from_surface (so its
/// elements are the input's): the same as mesh_components() on the input,
/// numbered by their first face, from the half-edges in linear time.
std::vector<ComponentInfo> input_components(const CutMesh& mesh, std::vector<int>& face_component);

} // namespace curvenet::detail
