#pragma once
// A control cage and its limit surface, point for point. The cage refined
// by Catmull-Clark (its limit, near enough) and by the bilinear rule (on
// the cage's own faces) share their vertices and faces, so a point of one
// refinement has its place on the other at the same corners and weights,
// inside the same cage face.

#include "cut/cut_mesh.hpp"
#include "generate/refine.hpp"
#include "trace/trace_mesh.hpp"

#include <memory>
#include <vector>

namespace curvenet::detail {

class CageMap {
public:
  /// \throw InputError when the cage cannot be refined.
  CageMap(const SurfaceMesh& cage, int levels, long long max_faces = 4'000'000);
  CageMap(const CageMap&) = delete; // the trace meshes refer to the meshes held here
  CageMap& operator=(const CageMap&) = delete;

  /// The cage's limit surface: the cage refined by Catmull-Clark.
  [[nodiscard]] const SurfaceMesh& limit() const { return r_.limit; }
  [[nodiscard]] const TraceMesh& limit_trace() const { return *limit_tm_; }
  [[nodiscard]] const TraceMesh& cage_trace() const { return *cage_tm_; }
  /// The point of the cage that a point of the limit stands for: on the
  /// same cage face, at the same parameters.
  [[nodiscard]] Vec3 to_cage(const Vec3& on_limit) const;
  /// The point of the limit that a point of the cage stands for.
  [[nodiscard]] Vec3 to_limit(const Vec3& on_cage) const;

private:
  /// The closest point of `tm` to p among the given triangles.
  static TraceMesh::Nearest closest_among(const TraceMesh& tm, const std::vector<int>& tris, const Vec3& p);

  CageRefinement r_;
  std::unique_ptr<TraceMesh> cage_tm_, limit_tm_, flat_tm_;
  std::vector<std::vector<int>> cage_tris_; // per cage face: its triangles in cage_tm_
  std::vector<std::vector<int>> flat_tris_; // per cage face: the triangles of its refined faces in flat_tm_
};

} // namespace curvenet::detail
