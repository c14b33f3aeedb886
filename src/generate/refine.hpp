#pragma once
// Both refinements of a control cage, from one topology: Catmull-Clark
// (its limit surface, near enough) and bilinear (on the cage's own faces).
// They share their vertices and faces, so vertex i of one and vertex i of
// the other are the same point of the cage's parameter space.

#include "curvenet/surface_mesh.hpp"

#include <vector>

namespace curvenet::detail {

struct CageRefinement {
  SurfaceMesh limit, flat;
  std::vector<int> base_face; ///< per refined face: the cage face it lies in
};

/// \throw InputError when levels is not between 1 and 6, or the cage cannot be refined.
CageRefinement refine_cage(const SurfaceMesh& cage, int levels, long long max_faces);

} // namespace curvenet::detail
