#pragma once
// How faithfully the cut follows the curves the rigger drew: the distance
// from each CutChain to its curve placed on the surface, and how close two
// placed curves come to each other where their chains meet.

#include "cut/cutter.hpp"

namespace curvenet::detail {

/// The symmetric Hausdorff distance between a CutChain and its curve as
/// placed on the surface (the trace's reference points), measured at the
/// vertices and segment midpoints of each against the other, sample by
/// sample; and the sample and place where it is largest.
struct ChainFidelity {
  double distance = 0;
  int sample = 0;
  Vec3 at = Vec3::Zero();
};
ChainFidelity chain_fidelity(const CutMesh& cut, const CutChain& chain, const TracedProfile& trace);

/// How close two placed curves come within `radius` of `at` (for one curve
/// with itself, `same`: its pieces that are not neighbours). Whether two
/// curves that come this close cross or only touch is not decided: near a
/// sharp vertex no plane shows it, so refusals say "meet or come closer".
double curve_gap(const TracedProfile& a, const TracedProfile& b, bool same, const Vec3& at, double radius);

} // namespace curvenet::detail
