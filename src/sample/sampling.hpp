#pragma once
// Stage "sample": profile curves to arc-length polylines whose density is
// scaled to the target mesh.

#include "curvenet/rig.hpp"

#include <vector>

namespace curvenet::detail {

using Vec3 = Eigen::Vector3d;

/// A dense polyline that follows the curve: the points themselves for a
/// polyline, and uniform parameter samples (at least 200) for Bezier and
/// NURBS curves.
std::vector<Vec3> evaluate_dense(const Curve& curve);

/// A point of a NURBS curve at parameter u (de Boor, rational when weighted).
Vec3 evaluate_nurbs(const Curve& curve, double u);

struct SampledProfile {
  std::vector<Vec3> points; ///< #n samples, first == `from`, last == `to`
  std::vector<double> t;    ///< #n normalised arc-length parameters in [0, 1]
  double length = 0;        ///< length of the curve with its ends moved
};

/// Samples a profile at uniform arc length. The curve's ends are first moved
/// onto its nodes by a displacement that fades linearly in arc length, so the
/// profile starts exactly at `from` and ends exactly at `to`. The sample
/// count is n = max(2, ceil(density * length / edge_length)).
SampledProfile sample_profile(const Curve& curve, const Vec3& from, const Vec3& to, double edge_length, double density);

} // namespace curvenet::detail
