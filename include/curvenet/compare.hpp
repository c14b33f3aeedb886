#pragma once
/// \file compare.hpp
/// The symmetric surface distance between two meshes, point to surface, so
/// that it works across topologies.

#include "curvenet/surface_mesh.hpp"

namespace curvenet {

struct OneWayDistance {
  double mean = 0; ///< area-weighted
  double rms = 0;
  double max = 0;
};

struct SurfaceDistance {
  OneWayDistance a_to_b, b_to_a;
  double mean = 0;     ///< the larger of the two directions' means
  double rms = 0;      ///< the larger of the two RMS
  double max = 0;      ///< Hausdorff: the larger of the two maxima
  double diagonal = 0; ///< of A's bounding box; percentages are of it
  [[nodiscard]] double percent(double d) const { return diagonal > 0 ? 100 * d / diagonal : 0; }
};

/// Distances from points spread over each surface (every vertex, and a
/// regular set of points inside every triangle, weighted by area) to the
/// exact closest point of the other surface (Embree BVH).
SurfaceDistance surface_distance(const SurfaceMesh& a, const SurfaceMesh& b, int samples_per_edge = 4);

} // namespace curvenet
