#include "sample/sampling.hpp"

#include <algorithm>
#include <cmath>

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

SampledProfile sample_profile(const Curve& curve, const Vec3& from, const Vec3& to, double edge_length,
                              double density) {
  std::vector<Vec3> dense = evaluate_dense(curve);
  // Move the ends onto the nodes, fading the displacement along the curve.
  {
    const auto acc = cumulative_length(dense);
    const double total = acc.back();
    const Vec3 d0 = from - dense.front(), d1 = to - dense.back();
    for (size_t i = 0; i < dense.size(); ++i) {
      const double s = total > 0 ? acc[i] / total : static_cast<double>(i) / static_cast<double>(dense.size() - 1);
      dense[i] += (1 - s) * d0 + s * d1;
    }
    dense.front() = from;
    dense.back() = to;
  }
  const auto acc = cumulative_length(dense);
  SampledProfile out;
  out.length = acc.back();
  const double ratio = edge_length > 0 ? density * out.length / edge_length : 2.0;
  const int n = std::max(2, static_cast<int>(std::min(1e7, std::ceil(ratio))));
  out.points.reserve(n);
  out.t.reserve(n);
  size_t seg = 0;
  for (int i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / (n - 1);
    const double target = t * out.length;
    while (seg + 2 < dense.size() && acc[seg + 1] < target)
      ++seg;
    const double len = acc[seg + 1] - acc[seg];
    const double a = len > 0 ? std::clamp((target - acc[seg]) / len, 0.0, 1.0) : 0.0;
    out.points.push_back((1 - a) * dense[seg] + a * dense[seg + 1]);
    out.t.push_back(t);
  }
  out.points.front() = from;
  out.points.back() = to;
  return out;
}

} // namespace curvenet::detail
