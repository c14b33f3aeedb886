#pragma once
// Stage "sample": profile curves to polylines whose spacing follows the
// target mesh's local edge length.

#include "curvenet/rig.hpp"

#include <functional>
#include <vector>

namespace curvenet::detail {

using Vec3 = Eigen::Vector3d;

/// A dense polyline that follows the curve: the points themselves for a
/// polyline, and uniform parameter samples (at least 200) for Bezier and
/// NURBS curves.
std::vector<Vec3> evaluate_dense(const Curve& curve);

/// A point of a NURBS curve at parameter u (de Boor, rational when weighted).
Vec3 evaluate_nurbs(const Curve& curve, double u);

/// A profile's curve as drawn, with its ends moved onto its nodes: a dense
/// polyline with arc length, evaluated anywhere along it. The ends are moved
/// by a displacement that fades linearly in arc length, so the curve starts
/// exactly at `from` and ends exactly at `to`.
class ProfileCurve {
public:
  ProfileCurve() = default;
  ProfileCurve(const Curve& curve, const Vec3& from, const Vec3& to);

  [[nodiscard]] double length() const { return arc_.empty() ? 0.0 : arc_.back(); }
  /// How many points the dense polyline has.
  [[nodiscard]] size_t size() const { return points_.size(); }
  /// The dense polyline, its ends on the nodes.
  [[nodiscard]] const std::vector<Vec3>& points() const { return points_; }
  /// Its cumulative arc length, point by point.
  [[nodiscard]] const std::vector<double>& arc() const { return arc_; }
  /// The point at normalised arc length t in [0, 1].
  [[nodiscard]] Vec3 at(double t) const;
  /// Normalised arc lengths of the points the rigger placed (a polyline's
  /// points, a Bezier's segment ends; a NURBS's two ends): always samples.
  [[nodiscard]] const std::vector<double>& corners() const { return corners_; }
  [[nodiscard]] bool closed() const { return closed_; }

private:
  std::vector<Vec3> points_;
  std::vector<double> arc_;
  std::vector<double> corners_;
  bool closed_ = false;
};

struct SampledProfile {
  std::vector<Vec3> points; ///< #n samples, first == `from`, last == `to`
  std::vector<double> t;    ///< #n normalised arc-length parameters in [0, 1]
  double length = 0;        ///< length of the curve with its ends moved
};

/// The sample spacing wanted near a point: the local edge length of the
/// target mesh divided by the density.
using SpacingFn = std::function<double(const Vec3&)>;

/// Samples a profile. Every corner of the curve is a sample; between two
/// corners the samples march along the curve in equal steps no longer than
/// `spacing` where each step starts. A closed profile (its two ends on one
/// node) gets at least 8 segments.
/// With `corners` false, only the two ends are fixed and the samples are
/// uniform in arc length at the spacing found at the start.
SampledProfile sample_profile(const ProfileCurve& curve, const SpacingFn& spacing, bool corners = true);

} // namespace curvenet::detail
