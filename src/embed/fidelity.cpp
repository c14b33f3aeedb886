#include "embed/fidelity.hpp"

#include "core/polyline_distance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace curvenet::detail {

ChainFidelity chain_fidelity(const CutMesh& cut, const CutChain& chain, const TracedProfile& trace) {
  // Keyed by the walk that placed each point, so each is measured against
  // the curve near it; a walk across a jump of the placed curve is skipped.
  std::vector<KeyedPoint> c, r;
  auto jump = [&](int piece) { return std::find(trace.jumps.begin(), trace.jumps.end(), piece) != trace.jumps.end(); };
  c.reserve(chain.vertices.size());
  for (size_t i = 0; i < chain.vertices.size(); ++i) {
    const PathPoint& pp = trace.points[chain.point[i]];
    c.push_back({cut.position(chain.vertices[i]), pp.piece, jump(pp.piece) || pp.unmeasured});
  }
  r.reserve(trace.reference.size());
  for (const ReferencePoint& q : trace.reference)
    r.push_back({q.pos, q.piece, jump(q.piece) || q.skip});
  const DirectedDistance to_curve = directed_hausdorff(c, r, 1);
  const DirectedDistance to_chain = directed_hausdorff(r, c, 1);
  ChainFidelity out;
  if (to_curve.distance >= to_chain.distance) {
    out.distance = to_curve.distance;
    out.sample = c.empty() ? 0 : trace.points[chain.point[to_curve.at]].sample;
    out.at = c.empty() ? Vec3::Zero() : c[to_curve.at].pos;
  } else {
    out.distance = to_chain.distance;
    out.sample = trace.reference[to_chain.at].sample;
    out.at = r[to_chain.at].pos;
  }
  return out;
}

namespace {

struct Piece {
  Vec3 a, b;
  size_t index; // along the curve
};

std::vector<Piece> pieces_near(const TracedProfile& t, const Vec3& at, double radius) {
  std::vector<Piece> all, near;
  for (size_t i = 0; i + 1 < t.reference.size(); ++i)
    all.push_back({t.reference[i].pos, t.reference[i + 1].pos, i});
  for (const Piece& p : all)
    if (point_segment_distance(at, p.a, p.b) <= radius)
      near.push_back(p);
  if (near.empty() && !all.empty()) {
    // Nothing that close: the three pieces nearest to the place.
    std::sort(all.begin(), all.end(), [&](const Piece& x, const Piece& y) {
      return point_segment_distance(at, x.a, x.b) < point_segment_distance(at, y.a, y.b);
    });
    all.resize(std::min<size_t>(3, all.size()));
    near = all;
  }
  return near;
}

} // namespace

double curve_gap(const TracedProfile& a, const TracedProfile& b, bool same, const Vec3& at, double radius) {
  const std::vector<Piece> pa = pieces_near(a, at, radius), pb = same ? pa : pieces_near(b, at, radius);
  double gap = std::numeric_limits<double>::infinity();
  for (const Piece& x : pa)
    for (const Piece& y : pb) {
      if (same && (x.index > y.index ? x.index - y.index : y.index - x.index) <= 1)
        continue; // neighbours along the curve share an end
      gap = std::min(gap, segment_distance(x.a, x.b, y.a, y.b));
    }
  return std::isfinite(gap) ? gap : radius;
}

} // namespace curvenet::detail
