#pragma once
/// \file surface_mesh.hpp
/// A validated polygon mesh, welded by position, with the map back to the
/// vertices of the file it was read from.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <span>
#include <string>
#include <vector>

namespace curvenet {

using Vec3 = Eigen::Vector3d;

/// A polygon mesh as read from a file, before any validation: #V positions
/// and #F polygons given as lists of indices into `positions`.
struct RawMesh {
  std::vector<Vec3> positions;
  std::vector<int> face_offsets{0}; ///< #F+1 offsets into face_vertices
  std::vector<int> face_vertices;
  void add_face(std::span<const int> corners);
};

/// A closed or open 2-manifold polygon mesh, consistently oriented, with no
/// degenerate face and no non-finite coordinate.
///
/// Vertices are welded by exact position (glTF splits vertices at UV seams),
/// but only where the weld keeps the mesh manifold. `input_to_welded` maps
/// each vertex of the file to its welded vertex, so results come back on the
/// file's own vertex order. Faces keep the file's order.
struct SurfaceMesh {
  std::string source;               ///< the file it came from (for messages)
  std::vector<Vec3> positions;      ///< #V welded positions
  std::vector<int> face_offsets;    ///< #F+1
  std::vector<int> face_vertices;   ///< welded vertex ids, counter-clockwise
  std::vector<int> input_to_welded; ///< #input vertices
  std::vector<std::string> notes;   ///< repairs made on load, one line each

  [[nodiscard]] int num_vertices() const { return static_cast<int>(positions.size()); }
  [[nodiscard]] int num_faces() const { return static_cast<int>(face_offsets.size()) - 1; }
  [[nodiscard]] std::span<const int> face(int f) const {
    return {face_vertices.data() + face_offsets[f], static_cast<size_t>(face_offsets[f + 1] - face_offsets[f])};
  }
  [[nodiscard]] double bbox_diagonal() const;
  [[nodiscard]] double mean_edge_length() const;
  /// Positions per welded vertex from positions per input vertex (what a
  /// deformation returns, in the file's order).
  [[nodiscard]] std::vector<Vec3> welded(const std::vector<Vec3>& per_input) const;
  /// The volume the faces enclose with the given welded positions (the
  /// divergence theorem over each face's fan; positive when the faces point
  /// outward).
  [[nodiscard]] double enclosed_volume(const std::vector<Vec3>& welded_positions) const;
  /// The winding number of the surface about p (1 inside a closed mesh, 0
  /// outside, near 1/2 on it): the solid angles of its faces' fans over 4 pi.
  [[nodiscard]] double winding_number(const Vec3& p) const;
};

/// Per connected component: whether it is closed, and its Euler characteristic.
struct ComponentInfo {
  int faces = 0;
  bool closed = false;
  int euler = 0; ///< V - E + F of the component
  [[nodiscard]] int genus() const { return closed ? (2 - euler) / 2 : -1; }
};

/// The connected components of `mesh` (by shared edges), in order of their
/// lowest face. `face_component` receives the component of each face if given.
std::vector<ComponentInfo> mesh_components(const SurfaceMesh& mesh, std::vector<int>* face_component = nullptr);

/// Which of the mesh's parts are open, in words for a message ("it has a
/// boundary", "2 of its 5 parts have a boundary"); empty when all are closed.
std::string open_parts_words(const SurfaceMesh& mesh);

/// Validates and welds a raw mesh.
/// \throw InputError naming `source` and the element: a non-finite
///   coordinate, a face with fewer than 3 corners or a bad index, a
///   degenerate face, a non-manifold edge or vertex, or a non-orientable
///   component. An orientation that is merely inconsistent is repaired, and
///   the repair is recorded in `notes`; so are the welds: by exact
///   position, and on an open mesh, boundary vertices within
///   Tolerances::seam_weld_rel of the diagonal where that closes a seam.
SurfaceMesh make_surface_mesh(const RawMesh& raw, const std::string& source);
/// The same, taking over `raw`'s arrays where they become the mesh's as
/// they are (no copy of a large mesh that needs no repair).
SurfaceMesh make_surface_mesh(RawMesh&& raw, const std::string& source);

} // namespace curvenet
