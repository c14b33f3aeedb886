#include "sample/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace curvenet::detail {
namespace {

Vec3 bezier(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3, double s) {
  const double r = 1 - s;
  return r * r * r * p0 + 3 * r * r * s * p1 + 3 * r * s * s * p2 + s * s * s * p3;
}

std::vector<double> cumulative_length(const std::vector<Vec3>& pts) {
  std::vector<double> acc(pts.size(), 0.0);
  for (size_t i = 1; i < pts.size(); ++i)
    acc[i] = acc[i - 1] + (pts[i] - pts[i - 1]).norm();
  return acc;
}

} // namespace

Vec3 evaluate_nurbs(const Curve& c, double u) {
  const int p = c.degree;
  const int n = static_cast<int>(c.points.size());
  const auto& U = c.knots;
  u = std::clamp(u, U[p], U[n]);
  // Knot span: the k with U[k] <= u < U[k+1], p <= k <= n-1.
  int k = static_cast<int>(std::upper_bound(U.begin(), U.end(), u) - U.begin()) - 1;
  k = std::clamp(k, p, n - 1);
  while (k > p && U[k] == U[k + 1])
    --k;
  std::vector<Eigen::Vector4d> d(p + 1);
  for (int j = 0; j <= p; ++j) {
    const double w = c.weights.empty() ? 1.0 : c.weights[k - p + j];
    d[j] << c.points[k - p + j] * w, w;
  }
  for (int r = 1; r <= p; ++r)
    for (int j = p; j >= r; --j) {
      const double den = U[j + 1 + k - r] - U[j + k - p];
      const double a = den > 0 ? (u - U[j + k - p]) / den : 0.0;
      d[j] = (1 - a) * d[j - 1] + a * d[j];
    }
  return d[p].head<3>() / d[p].w();
}

std::vector<Vec3> evaluate_dense(const Curve& c) {
  switch (c.kind) {
  case Curve::Kind::Polyline:
    return c.points;
  case Curve::Kind::Bezier: {
    const size_t segments = (c.points.size() - 1) / 3;
    const int per = std::max(8, static_cast<int>(std::ceil(200.0 / static_cast<double>(segments))));
    std::vector<Vec3> out{c.points[0]};
    for (size_t s = 0; s < segments; ++s)
      for (int i = 1; i <= per; ++i)
        out.push_back(bezier(c.points[3 * s], c.points[3 * s + 1], c.points[3 * s + 2], c.points[3 * s + 3],
                             static_cast<double>(i) / per));
    return out;
  }
  case Curve::Kind::Nurbs: {
    const int p = c.degree, n = static_cast<int>(c.points.size());
    const double a = c.knots[p], b = c.knots[n];
    const int count = std::max(200, 16 * (n - p));
    std::vector<Vec3> out;
    for (int i = 0; i <= count; ++i)
      out.push_back(evaluate_nurbs(c, a + (b - a) * i / count));
    return out;
  }
  }
  return c.points;
}

ProfileCurve::ProfileCurve(const Curve& curve, const Vec3& from, const Vec3& to) {
  points_ = evaluate_dense(curve);
  // Which dense points the rigger placed.
  std::vector<size_t> corner_index;
  switch (curve.kind) {
  case Curve::Kind::Polyline:
    for (size_t i = 0; i < points_.size(); ++i)
      corner_index.push_back(i);
    break;
  case Curve::Kind::Bezier: {
    const size_t segments = (curve.points.size() - 1) / 3;
    const size_t per = segments > 0 ? (points_.size() - 1) / segments : 1;
    for (size_t s = 0; s <= segments; ++s)
      corner_index.push_back(std::min(s * per, points_.size() - 1));
    break;
  }
  case Curve::Kind::Nurbs:
    corner_index = {0, points_.size() - 1};
    break;
  }
  {
    const auto acc = cumulative_length(points_);
    const double total = acc.back();
    const Vec3 d0 = from - points_.front(), d1 = to - points_.back();
    for (size_t i = 0; i < points_.size(); ++i) {
      const double s = total > 0 ? acc[i] / total : static_cast<double>(i) / static_cast<double>(points_.size() - 1);
      points_[i] += (1 - s) * d0 + s * d1;
    }
    points_.front() = from;
    points_.back() = to;
  }
  arc_ = cumulative_length(points_);
  const double total = length();
  for (size_t i : corner_index) {
    const double t = total > 0 ? arc_[i] / total : static_cast<double>(i) / static_cast<double>(points_.size() - 1);
    if (corners_.empty() || t > corners_.back())
      corners_.push_back(t);
  }
  if (corners_.empty() || corners_.front() != 0.0)
    corners_.insert(corners_.begin(), 0.0);
  if (corners_.back() != 1.0)
    corners_.push_back(1.0);
  closed_ = from == to;
}

Vec3 ProfileCurve::at(double t) const {
  if (points_.size() < 2)
    return points_.empty() ? Vec3::Zero() : points_.front();
  const double total = length();
  if (!(total > 0))
    return points_.front();
  if (t >= 1.0)
    return points_.back();
  const double target = std::clamp(t, 0.0, 1.0) * total;
  const size_t seg = std::min<size_t>(points_.size() - 2,
                                      static_cast<size_t>(std::max<std::ptrdiff_t>(
                                          0, std::upper_bound(arc_.begin(), arc_.end(), target) - arc_.begin() - 1)));
  const double len = arc_[seg + 1] - arc_[seg];
  const double a = len > 0 ? std::clamp((target - arc_[seg]) / len, 0.0, 1.0) : 0.0;
  return (1 - a) * points_[seg] + a * points_[seg + 1];
}

SampledProfile sample_profile(const ProfileCurve& curve, const SpacingFn& spacing, bool use_corners) {
  SampledProfile out;
  out.length = curve.length();
  const double total = out.length;
  // A closed profile with few corners would give a walk between two
  // samples on opposite sides of a limb: keep at least 8 segments.
  const double max_step = curve.closed() ? total / 8 : std::numeric_limits<double>::infinity();
  // Bounded work: no profile gets more than this many samples.
  constexpr size_t max_samples = 10'000'000;
  const std::vector<double> ends{0.0, 1.0};
  const auto& corners = use_corners ? curve.corners() : ends;
  out.points.push_back(curve.at(0.0));
  out.t.push_back(0.0);
  for (size_t c = 1; c < corners.size(); ++c) {
    double here = corners[c - 1] * total;
    const double end = corners[c] * total;
    while (out.points.size() < max_samples) {
      double step = total > 0 ? spacing(out.points.back()) : 0.0;
      step = std::min(step, max_step);
      if (!(step > 0) || !std::isfinite(step))
        break;
      const double left = end - here;
      const double n = std::ceil(left / step * (1 - 1e-12)); // no extra step for rounding
      if (!(n > 1))
        break;
      here += left / n;
      out.points.push_back(curve.at(here / total));
      out.t.push_back(here / total);
    }
    out.points.push_back(curve.at(corners[c]));
    out.t.push_back(corners[c]);
  }
  if (out.points.size() < 2) {
    out.points.push_back(curve.at(1.0));
    out.t.push_back(1.0);
  }
  out.t.back() = 1.0;
  return out;
}

} // namespace curvenet::detail
