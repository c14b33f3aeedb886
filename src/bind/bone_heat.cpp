#include "bind/bone_heat.hpp"

#include "core/tolerances.hpp"
#include "curvenet/errors.hpp"
#include "trace/trace_mesh.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>

namespace curvenet::detail {

namespace {

struct Bone {
  int joint = -1;
  int child = -1; ///< -1 for a joint with no child: a point
  Eigen::Vector3d a, b;
};

/// The closest point of segment ab to p.
Eigen::Vector3d closest_on_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d d = b - a;
  const double len2 = d.squaredNorm();
  if (!(len2 > 0))
    return a;
  return a + std::clamp((p - a).dot(d) / len2, 0.0, 1.0) * d;
}

/// What a vertex sees: the distance to its nearest visible bone, and the
/// bones at that distance.
struct Source {
  double distance = std::numeric_limits<double>::infinity();
  std::vector<int> bones; ///< empty when no bone is seen
};

} // namespace

BoneHeat bone_heat(const BoneHeatInput& in) {
  const CutMesh& cut = *in.cut;
  const std::vector<Joint>& joints = *in.joints;
  const int nc = cut.num_vertices(), nj = static_cast<int>(joints.size());
  const std::vector<int> parent = joint_parents(joints);
  std::vector<Bone> bones;
  for (int j = 0; j < nj; ++j) {
    if (!in.deforming[j])
      continue;
    const Eigen::Vector3d a = joints[j].bind.block<3, 1>(0, 3);
    bool child = false;
    for (int c = 0; c < nj; ++c)
      if (parent[c] == j) {
        bones.push_back({j, c, a, joints[c].bind.block<3, 1>(0, 3)});
        child = true;
      }
    if (!child)
      bones.push_back({j, -1, a, a});
  }
  if (bones.empty())
    throw Error("bone heat: no joint takes part");

  double diagonal = 0;
  {
    Eigen::AlignedBox3d box;
    for (int v = 0; v < nc; ++v)
      box.extend(cut.position(Vertex(v)));
    diagonal = nc > 0 ? box.diagonal().norm() : 1.0;
  }
  const Tolerances tol = Tolerances::for_model(diagonal);
  const double skip = Tolerances::visibility_skip_rel * tol.diagonal;
  const double nearest_floor = Tolerances::visibility_skip_rel * tol.diagonal; // a vertex on a bone

  // What each vertex sees: bones by distance, the first few tried for a
  // clear segment (the nearest seen bone is nearly always among them).
  constexpr size_t kTries = 8;
  std::vector<Source> seen(nc), nearest(nc);
  tbb::parallel_for(tbb::blocked_range<int>(0, nc, 1024), [&](const tbb::blocked_range<int>& r) {
    std::vector<std::pair<double, int>> order(bones.size());
    std::vector<Eigen::Vector3d> foot(bones.size());
    for (int v = r.begin(); v < r.end(); ++v) {
      const Eigen::Vector3d& p = cut.position(Vertex(v));
      for (size_t b = 0; b < bones.size(); ++b) {
        foot[b] = closest_on_segment(p, bones[b].a, bones[b].b);
        order[b] = {(foot[b] - p).norm(), static_cast<int>(b)};
      }
      std::sort(order.begin(), order.end());
      nearest[v].distance = order[0].first;
      for (const auto& [d, b] : order)
        if (d <= order[0].first)
          nearest[v].bones.push_back(b);
      const size_t tries = std::min(kTries, order.size());
      for (size_t k = 0; k < tries; ++k) {
        const auto [d, b] = order[k];
        if (d > seen[v].distance)
          break; // past the nearest seen bone (ties at its distance are kept)
        if (!in.surface->segment_blocked(p, foot[b], skip)) {
          seen[v].distance = d;
          seen[v].bones.push_back(b);
        }
      }
    }
  });

  // Parts of the surface that see no bone at all take their nearest bones.
  BoneHeat out;
  const Eigen::SparseMatrix<double>& L = *in.laplacian;
  std::vector<int> comp(nc, -1);
  for (int s0 = 0; s0 < nc; ++s0) {
    if (comp[s0] >= 0)
      continue;
    std::vector<int> members{s0}, stack{s0};
    comp[s0] = s0;
    bool sees = false;
    while (!stack.empty()) {
      const int v = stack.back();
      stack.pop_back();
      sees = sees || !seen[v].bones.empty();
      for (Eigen::SparseMatrix<double>::InnerIterator it(L, v); it; ++it) {
        const int u = static_cast<int>(it.row());
        if (u != v && it.value() != 0 && comp[u] < 0) {
          comp[u] = s0;
          stack.push_back(u);
          members.push_back(u);
        }
      }
    }
    if (!sees)
      for (int v : members) {
        seen[v] = nearest[v];
        ++out.blind;
      }
  }

  // Lumped vertex areas.
  Eigen::VectorXd area = Eigen::VectorXd::Zero(nc);
  for (int f = 0; f < cut.num_faces(); ++f) {
    const auto loop = cut.face_loop(Face(f));
    const double a = cut.face_area(Face(f)) / static_cast<double>(loop.size());
    for (const Halfedge h : loop)
      area[cut.from(h).idx] += a;
  }

  // Per vertex: its screening h = M H, and its sources p_j (the rule's
  // weights on the bones it sees, shared between bones at one distance).
  std::vector<double> h(nc, 0.0);
  std::vector<std::vector<std::pair<int, double>>> p(nc);
  std::vector<std::pair<int, double>> rule;
  for (int v = 0; v < nc; ++v) {
    const Source& src = seen[v];
    if (src.bones.empty())
      continue; // heat reaches it through the surface
    const double d = std::max(src.distance, nearest_floor);
    h[v] = area[v] / (d * d);
    const double share = 1.0 / static_cast<double>(src.bones.size());
    std::map<int, double> pv;
    for (int b : src.bones) {
      // The rule's weights on this bone, over the joints that take part.
      const Bone& bone = bones[b];
      double sum = 0;
      rule.clear();
      if (bone.child >= 0)
        for (const auto& [j, x] : auto_weights(joints, parent, cut.position(Vertex(v)), in.rule, {bone.child}))
          if (in.deforming[j]) {
            rule.emplace_back(j, x);
            sum += x;
          }
      if (!(sum > 0)) {
        pv[bone.joint] += share;
        continue;
      }
      for (const auto& [j, x] : rule)
        pv[j] += share * x / sum;
    }
    p[v].assign(pv.begin(), pv.end());
  }

  // (L + M H) w_j = M H p_j, factored once.
  std::vector<Eigen::Triplet<double>> entries;
  for (int v = 0; v < nc; ++v)
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, v); it; ++it)
      entries.emplace_back(static_cast<int>(it.row()), v, it.value() + (it.row() == v ? h[v] : 0.0));
  Eigen::SparseMatrix<double> A(nc, nc);
  A.setFromTriplets(entries.begin(), entries.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
  if (solver.info() != Eigen::Success)
    throw EmbedError("bone heat: the system could not be factored");
  out.weight.assign(nj, Eigen::VectorXd());
  Eigen::VectorXd rhs(nc);
  for (int j = 0; j < nj; ++j) {
    if (!in.deforming[j])
      continue;
    rhs.setZero();
    for (int v = 0; v < nc; ++v)
      for (const auto& [k, x] : p[v])
        if (k == j)
          rhs[v] = h[v] * x;
    out.weight[j] = solver.solve(rhs);
    if (solver.info() != Eigen::Success || !out.weight[j].allFinite())
      throw EmbedError("bone heat: the solve failed for joint '" + joints[j].name + "'");
  }

  // Per vertex: drop the small weights, renormalise the rest.
  for (int v = 0; v < nc; ++v) {
    double sum = 0, largest = -1;
    int best = -1;
    for (int j = 0; j < nj; ++j) {
      if (out.weight[j].size() == 0)
        continue;
      const double x = out.weight[j][v];
      if (x >= in.floor)
        sum += x;
      if (x > largest) {
        largest = x;
        best = j;
      }
    }
    for (int j = 0; j < nj; ++j) {
      if (out.weight[j].size() == 0)
        continue;
      double& x = out.weight[j][v];
      x = sum > 0 ? (x >= in.floor ? x / sum : 0.0) : (j == best ? 1.0 : 0.0); // all under the floor: the largest alone
    }
  }
  return out;
}

} // namespace curvenet::detail
