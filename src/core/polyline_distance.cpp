#include "core/polyline_distance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace curvenet::detail {

double point_segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

double segment_distance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q0,
                        const Eigen::Vector3d& q1, Eigen::Vector3d* on_q) {
  // Closest points of two segments (Ericson 5.1.9), clamped.
  const Eigen::Vector3d d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0, t = 0;
  if (a <= 0 && e <= 0) {
    if (on_q)
      *on_q = q0;
    return r.norm();
  }
  if (a <= 0) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 0) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), den = a * e - b * b;
      s = den > 0 ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  if (on_q)
    *on_q = q0 + t * d2;
  return ((p0 + s * d1) - (q0 + t * d2)).norm();
}

DirectedDistance directed_hausdorff(const std::vector<KeyedPoint>& from, const std::vector<KeyedPoint>& to,
                                    int window) {
  DirectedDistance out;
  if (from.empty() || to.empty())
    return out;
  auto distance_to = [&](const Eigen::Vector3d& p, int key_lo, int key_hi) {
    // Segments of `to` with an end whose key is within the window.
    const auto lo =
        std::lower_bound(to.begin(), to.end(), key_lo - window, [](const KeyedPoint& q, int k) { return q.key < k; });
    const auto hi =
        std::upper_bound(to.begin(), to.end(), key_hi + window, [](int k, const KeyedPoint& q) { return k < q.key; });
    size_t first = static_cast<size_t>(lo - to.begin());
    size_t last = static_cast<size_t>(hi - to.begin()); // one past
    first = first > 0 ? first - 1 : 0;
    last = std::min(last, to.size() - 1);
    if (to.size() == 1)
      return (to[0].pos - p).norm();
    if (first >= last) {
      first = std::min(first, to.size() - 2);
      last = first + 1;
    }
    double best = std::numeric_limits<double>::infinity();
    for (size_t j = first; j < last; ++j)
      best = std::min(best, point_segment_distance(p, to[j].pos, to[j + 1].pos));
    return best;
  };
  // A vertex is measured against the keys of its two segments; a
  // segment's midpoint against the keys of its two ends.
  for (size_t i = 0; i < from.size(); ++i) {
    if (from[i].skip)
      continue;
    const double d = distance_to(from[i].pos, from[i > 0 ? i - 1 : 0].key, from[std::min(i + 1, from.size() - 1)].key);
    if (d > out.distance) {
      out.distance = d;
      out.at = i;
    }
    if (i + 1 < from.size() && !from[i + 1].skip) {
      const double m = distance_to((from[i].pos + from[i + 1].pos) / 2, from[i].key, from[i + 1].key);
      if (m > out.distance) {
        out.distance = m;
        out.at = i;
      }
    }
  }
  return out;
}

std::vector<size_t> simplify_polyline(const std::vector<Eigen::Vector3d>& points, double tolerance,
                                      const std::function<double(const Eigen::Vector3d&)>& off_surface) {
  if (points.size() <= 2) {
    std::vector<size_t> all(points.size());
    for (size_t i = 0; i < all.size(); ++i)
      all[i] = i;
    return all;
  }
  std::vector<char> keep(points.size(), 0);
  keep.front() = keep.back() = 1;
  // An explicit stack: a long polyline must not recurse deeply.
  std::vector<std::pair<size_t, size_t>> todo{{0, points.size() - 1}};
  while (!todo.empty()) {
    const auto [i, j] = todo.back();
    todo.pop_back();
    double worst = -1;
    size_t at = i;
    const Eigen::Vector3d ab = points[j] - points[i];
    for (size_t k = i + 1; k < j; ++k) {
      double d = point_segment_distance(points[k], points[i], points[j]);
      if (off_surface && d <= tolerance) {
        const double t =
            ab.squaredNorm() > 0 ? std::clamp((points[k] - points[i]).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
        d = std::max(d, off_surface(points[i] + t * ab));
      }
      if (d > worst) {
        worst = d;
        at = k;
      }
    }
    if (j > i + 1 && worst > tolerance) {
      keep[at] = 1;
      todo.emplace_back(i, at);
      todo.emplace_back(at, j);
    }
  }
  std::vector<size_t> out;
  for (size_t k = 0; k < points.size(); ++k)
    if (keep[k])
      out.push_back(k);
  return out;
}

double hausdorff(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  auto directed = [](const std::vector<Eigen::Vector3d>& from, const std::vector<Eigen::Vector3d>& to) {
    double worst = 0;
    auto dist = [&](const Eigen::Vector3d& p) {
      if (to.size() == 1)
        return (to[0] - p).norm();
      double best = std::numeric_limits<double>::infinity();
      for (size_t j = 0; j + 1 < to.size(); ++j)
        best = std::min(best, point_segment_distance(p, to[j], to[j + 1]));
      return best;
    };
    for (size_t i = 0; i < from.size(); ++i) {
      worst = std::max(worst, dist(from[i]));
      if (i + 1 < from.size())
        worst = std::max(worst, dist((from[i] + from[i + 1]) / 2));
    }
    return worst;
  };
  if (a.empty() || b.empty())
    return 0;
  return std::max(directed(a, b), directed(b, a));
}

} // namespace curvenet::detail
