// The weights-only step of smooth skinning decomposition (weights_anchor.hpp).

#include "weights_anchor.hpp"

#include "core/convex_least_squares.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <Eigen/SparseLU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <tuple>

namespace curvenet::bench {

std::vector<std::vector<std::pair<int, double>>> anchor_weights(std::span<const Vec3> rest,
                                                               const std::vector<std::vector<int>>& faces,
                                                               const std::vector<std::vector<Mat4>>& transforms,
                                                               const std::vector<std::vector<Vec3>>& frames,
                                                               const AnchorOptions& options) {
  const int nv = static_cast<int>(rest.size());
  const int nf = static_cast<int>(frames.size());
  const int nb = nf > 0 ? static_cast<int>(transforms[0].size()) : 0;
  std::vector<std::vector<std::pair<int, double>>> out(nv);
  if (nv == 0 || nb == 0 || nf == 0)
    return out;

  // Each vertex moved rigidly by each joint, against where the frames put it.
  Eigen::MatrixXd error(nv, nb);
  tbb::parallel_for(0, nv, [&](int i) {
    const Eigen::Vector4d u = rest[i].homogeneous();
    for (int j = 0; j < nb; ++j) {
      double e = 0;
      for (int f = 0; f < nf; ++f)
        e += ((transforms[f][j] * u).head<3>() - frames[f][i]).squaredNorm();
      error(i, j) = e;
    }
  });

  // Edges, and the Laplacian that smooths weights: an edge counts the more
  // the less its length changes over the frames.
  std::vector<std::pair<int, int>> edges;
  double length_sum = 0;
  for (const auto& f : faces)
    for (size_t k = 0; k < f.size(); ++k) {
      const int a = f[k], b = f[(k + 1) % f.size()];
      length_sum += (rest[a] - rest[b]).norm();
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  const double eps = std::max(length_sum * 1e-15, std::numeric_limits<double>::min());
  std::vector<std::vector<int>> neighbours(nv);
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::VectorXd degree = Eigen::VectorXd::Zero(nv);
  std::vector<double> edge_weight(edges.size());
  tbb::parallel_for(size_t{0}, edges.size(), [&](size_t e) {
    const auto [a, b] = edges[e];
    const double l0 = (rest[a] - rest[b]).norm();
    double s = 0;
    for (int f = 0; f < nf; ++f) {
      const double d = (frames[f][a] - frames[f][b]).norm() - l0;
      s += d * d;
    }
    edge_weight[e] = 1 / (std::sqrt(s / nf) + eps);
  });
  for (size_t e = 0; e < edges.size(); ++e) {
    const auto [a, b] = edges[e];
    neighbours[a].push_back(b);
    neighbours[b].push_back(a);
    degree[a] += edge_weight[e];
    degree[b] += edge_weight[e];
  }
  for (size_t e = 0; e < edges.size(); ++e) {
    const auto [a, b] = edges[e];
    trip.emplace_back(a, b, -options.smooth_step * edge_weight[e] / degree[a]);
    trip.emplace_back(b, a, -options.smooth_step * edge_weight[e] / degree[b]);
  }
  for (int i = 0; i < nv; ++i)
    trip.emplace_back(i, i, 1 + (degree[i] > 0 ? options.smooth_step : 0));
  Eigen::SparseMatrix<double> S(nv, nv);
  S.setFromTriplets(trip.begin(), trip.end());
  Eigen::SparseLU<Eigen::SparseMatrix<double>> smoother;
  smoother.compute(S);

  // 1. Rigid labels: each vertex's best joint, then grown across the mesh
  //    from each joint's best vertex, cheapest first.
  std::vector<int> label(nv);
  for (int i = 0; i < nv; ++i)
    error.row(i).minCoeff(&label[i]);
  if (options.grow_labels) {
    std::vector<int> seed(nb, -1);
    for (int i = 0; i < nv; ++i) {
      const int j = label[i];
      if (seed[j] < 0 || error(i, j) < error(seed[j], j))
        seed[j] = i;
    }
    using Item = std::tuple<double, int, int>; // error, vertex, joint
    std::priority_queue<Item, std::vector<Item>, std::greater<>> heap;
    for (int j = 0; j < nb; ++j)
      if (seed[j] >= 0)
        heap.emplace(error(seed[j], j), seed[j], j);
    std::vector<bool> done(nv, false);
    while (!heap.empty()) {
      const auto [e, i, j] = heap.top();
      heap.pop();
      if (done[i])
        continue;
      done[i] = true;
      label[i] = j;
      for (int n : neighbours[i])
        if (!done[n])
          heap.emplace(error(n, j), n, j);
    }
  }
  Eigen::MatrixXd W = Eigen::MatrixXd::Zero(nv, nb);
  for (int i = 0; i < nv; ++i)
    W(i, label[i]) = 1;

  // 2. Updates.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Vec3& p : rest)
    centroid += p;
  centroid /= nv;
  double spread = 0;
  for (const Vec3& p : rest)
    spread += (p - centroid).squaredNorm();
  // The model's size squared, times the frames (not zero for a mesh of one point).
  const double reg = std::max(spread / nv * nf, std::numeric_limits<double>::min());
  for (int it = 0; it < options.iterations; ++it) {
    Eigen::MatrixXd Ws(nv, nb);
    for (int j = 0; j < nb; ++j)
      Ws.col(j) = smoother.solve(W.col(j));
    for (int i = 0; i < nv; ++i) {
      Ws.row(i) = Ws.row(i).cwiseMax(0.0);
      const double s = Ws.row(i).sum();
      if (s < 0.1)
        Ws.row(i).setConstant(1.0 / nb);
      else
        Ws.row(i) /= s;
    }
    Eigen::MatrixXd next = Eigen::MatrixXd::Zero(nv, nb);
    tbb::parallel_for(0, nv, [&](int i) {
      std::vector<int> order(nb);
      std::iota(order.begin(), order.end(), 0);
      std::sort(order.begin(), order.end(), [&](int a, int b) { return Ws(i, a) > Ws(i, b); });
      int k = std::min(options.nnz, nb);
      while (k > 1 && Ws(i, order[k - 1]) < 1e-15)
        --k;
      order.resize(k);
      const Eigen::Vector4d u = rest[i].homogeneous();
      Eigen::MatrixXd moved(3 * nf, k);
      Eigen::VectorXd target(3 * nf);
      for (int f = 0; f < nf; ++f) {
        for (int a = 0; a < k; ++a)
          moved.block<3, 1>(3 * f, a) = (transforms[f][order[a]] * u).head<3>();
        target.segment<3>(3 * f) = frames[f][i];
      }
      Eigen::MatrixXd Q = moved.transpose() * moved / reg;
      Eigen::VectorXd c = moved.transpose() * target / reg;
      Eigen::VectorXd x(k);
      for (int a = 0; a < k; ++a) {
        Q(a, a) += options.smooth;
        c[a] += options.smooth * Ws(i, order[a]);
        x[a] = std::max(0.0, W(i, order[a]));
      }
      if (x.sum() > 0.1)
        x /= x.sum();
      else
        x.setConstant(1.0 / k);
      x = detail::convex_least_squares(Q, c, x);
      for (int a = 0; a < k; ++a)
        next(i, order[a]) = x[a];
    });
    W = std::move(next);
  }
  for (int i = 0; i < nv; ++i)
    for (int j = 0; j < nb; ++j)
      if (W(i, j) > 0)
        out[i].emplace_back(j, W(i, j));
  return out;
}

} // namespace curvenet::bench
