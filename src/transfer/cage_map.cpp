#include "transfer/cage_map.hpp"

#include "core/polygon.hpp"
#include "curvenet/errors.hpp"

#include <limits>

namespace curvenet::detail {

CageMap::CageMap(const SurfaceMesh& cage, int levels, long long max_faces)
    : r_(refine_cage(cage, levels, max_faces)),
      cage_tm_(std::make_unique<TraceMesh>(cage, CutMesh::from_surface(cage))),
      limit_tm_(std::make_unique<TraceMesh>(r_.limit, CutMesh::from_surface(r_.limit))),
      flat_tm_(std::make_unique<TraceMesh>(r_.flat, CutMesh::from_surface(r_.flat))) {
  cage_tris_.resize(cage.num_faces());
  for (int t = 0; t < cage_tm_->num_triangles(); ++t)
    cage_tris_[cage_tm_->tri_face(t)].push_back(t);
  flat_tris_.resize(cage.num_faces());
  for (int t = 0; t < flat_tm_->num_triangles(); ++t)
    flat_tris_[r_.base_face[flat_tm_->tri_face(t)]].push_back(t);
}

TraceMesh::Nearest CageMap::closest_among(const TraceMesh& tm, const std::vector<int>& tris, const Vec3& p) {
  TraceMesh::Nearest best;
  double d = std::numeric_limits<double>::infinity();
  for (int t : tris) {
    const auto& c = tm.tri(t);
    const TriClosest cl = closest_on_triangle(p, tm.position(c[0]), tm.position(c[1]), tm.position(c[2]));
    if ((cl.point - p).squaredNorm() < d) {
      d = (cl.point - p).squaredNorm();
      best = {t, cl.point, cl.bary};
    }
  }
  return best;
}

Vec3 CageMap::to_cage(const Vec3& on_limit) const {
  // Limit -> the bilinear point at the same corners and weights -> the
  // cage's own (triangulated) face that holds it.
  const TraceMesh::Nearest n = limit_tm_->nearest(on_limit);
  const auto& c = limit_tm_->tri(n.tri);
  const Vec3 flat =
      n.bary[0] * r_.flat.positions[c[0]] + n.bary[1] * r_.flat.positions[c[1]] + n.bary[2] * r_.flat.positions[c[2]];
  const int face = r_.base_face[limit_tm_->tri_face(n.tri)];
  return closest_among(*cage_tm_, cage_tris_[face], flat).point;
}

Vec3 CageMap::to_limit(const Vec3& on_cage) const {
  // Cage -> the bilinear refinement of the same cage face -> the limit at
  // the same corners and weights.
  const int face = cage_tm_->tri_face(cage_tm_->nearest(on_cage).tri);
  const TraceMesh::Nearest n = closest_among(*flat_tm_, flat_tris_[face], on_cage);
  const auto& c = flat_tm_->tri(n.tri);
  return n.bary[0] * r_.limit.positions[c[0]] + n.bary[1] * r_.limit.positions[c[1]] +
         n.bary[2] * r_.limit.positions[c[2]];
}

} // namespace curvenet::detail
