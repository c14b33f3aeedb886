#include "curvenet/compare.hpp"

#include "compare/surface_distance.hpp"
#include "cut/cut_mesh.hpp"
#include "trace/trace_mesh.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace curvenet {

namespace {

OneWayDistance one_way(const SurfaceMesh& from, const detail::TraceMesh& to, int n) {
  // Points on a regular grid of n x n sub-triangles of every triangle of `from`,
  // each standing for an equal share of that triangle's area.
  struct Sample {
    Vec3 p;
    double w;
  };
  std::vector<Sample> samples;
  if (n <= 1) { // the corners: each vertex once, with a third of the area of the triangles around it
    samples.resize(from.num_vertices());
    for (int v = 0; v < from.num_vertices(); ++v)
      samples[v] = {from.positions[v], 0};
    for (int f = 0; f < from.num_faces(); ++f) {
      const auto c = from.face(f);
      for (size_t k = 1; k + 1 < c.size(); ++k) {
        const Vec3 &a = from.positions[c[0]], &b = from.positions[c[k]], &d = from.positions[c[k + 1]];
        const double third = (b - a).cross(d - a).norm() / 6;
        for (const int v : {c[0], c[k], c[k + 1]})
          samples[v].w += third;
      }
    }
  }
  for (int f = 0; f < from.num_faces() && n > 1; ++f) {
    const auto c = from.face(f);
    for (size_t k = 1; k + 1 < c.size(); ++k) {
      const Vec3 &a = from.positions[c[0]], &b = from.positions[c[k]], &d = from.positions[c[k + 1]];
      const double area = 0.5 * (b - a).cross(d - a).norm();
      const int count = (n + 1) * (n + 2) / 2;
      for (int i = 0; i <= n; ++i)
        for (int j = 0; i + j <= n; ++j) {
          const double u = static_cast<double>(i) / n, v = static_cast<double>(j) / n;
          samples.push_back({a + u * (b - a) + v * (d - a), area / count});
        }
    }
  }
  std::vector<double> dist(samples.size());
  tbb::parallel_for(size_t{0}, samples.size(),
                    [&](size_t i) { dist[i] = to.nearest(samples[i].p).distance(samples[i].p); });
  OneWayDistance out;
  double total = 0;
  for (size_t i = 0; i < samples.size(); ++i) {
    out.mean += samples[i].w * dist[i];
    out.rms += samples[i].w * dist[i] * dist[i];
    out.max = std::max(out.max, dist[i]);
    total += samples[i].w;
  }
  if (total > 0) {
    out.mean /= total;
    out.rms = std::sqrt(out.rms / total);
  }
  return out;
}

} // namespace

SurfaceDistance surface_distance(const SurfaceMesh& a, const SurfaceMesh& b, int samples_per_edge) {
  const detail::CutMesh ca = detail::CutMesh::from_surface(a), cb = detail::CutMesh::from_surface(b);
  const detail::TraceMesh ta(a, ca), tb(b, cb);
  return detail::surface_distance(a, ta, b, tb, samples_per_edge);
}

namespace detail {

SurfaceDistance surface_distance(const SurfaceMesh& a, const TraceMesh& ta, const SurfaceMesh& b, const TraceMesh& tb,
                                 int samples_per_edge) {
  SurfaceDistance d;
  d.a_to_b = one_way(a, tb, samples_per_edge);
  d.b_to_a = one_way(b, ta, samples_per_edge);
  d.mean = std::max(d.a_to_b.mean, d.b_to_a.mean);
  d.rms = std::max(d.a_to_b.rms, d.b_to_a.rms);
  d.max = std::max(d.a_to_b.max, d.b_to_a.max);
  d.diagonal = a.bbox_diagonal();
  return d;
}

} // namespace detail

} // namespace curvenet
