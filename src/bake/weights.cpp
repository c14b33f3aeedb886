// Baked skin weights: the top-k harmonic weights, weights fitted to the full
// deformation over sample poses, linear blend skinning with them, and CSV.

#include "core/convex_least_squares.hpp"
#include "core/memory_budget.hpp"
#include "core/dual_quaternion.hpp"
#include "curvenet/bake.hpp"
#include "curvenet/errors.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <set>
#include <sstream>

namespace curvenet {
namespace {

void check_influences(int k) {
  if (k < 1 || k > 8)
    throw InputError("max influences", std::to_string(k), "must be between 1 and 8 (glTF's JOINTS_0 and JOINTS_1)");
}

SkinWeights empty_weights(const Binding& b, int k) {
  SkinWeights w;
  w.influences = k;
  for (const auto& j : b.joints())
    w.joints.push_back(j.name);
  const size_t n = static_cast<size_t>(b.num_input_vertices()) * k;
  w.joint.assign(n, -1);
  w.weight.assign(n, 0.0);
  return w;
}

/// Keeps the k largest, renormalised, largest first, into slot row `v`.
void store(std::vector<std::pair<int, double>>& inf, int k, SkinWeights& w, int v) {
  std::sort(inf.begin(), inf.end(), [](const auto& a, const auto& b) {
    return a.second != b.second ? a.second > b.second : a.first < b.first;
  });
  if (static_cast<int>(inf.size()) > k)
    inf.resize(k);
  double sum = 0;
  for (const auto& [j, x] : inf)
    sum += x;
  for (size_t i = 0; i < inf.size(); ++i) {
    w.joint[static_cast<size_t>(v) * k + i] = inf[i].first;
    w.weight[static_cast<size_t>(v) * k + i] = sum > 0 ? inf[i].second / sum : 1.0 / inf.size();
  }
}

} // namespace

SkinWeights bake_weights(const Binding& binding, int max_influences) {
  check_influences(max_influences);
  SkinWeights w = empty_weights(binding, max_influences);
  std::vector<std::pair<int, double>> inf;
  for (int v = 0; v < binding.num_input_vertices(); ++v) {
    binding.harmonic_weights(v, inf);
    store(inf, max_influences, w, v);
  }
  return w;
}

SkinWeights fit_weights(const Binding& binding, const std::vector<std::vector<Mat4>>& poses, int max_influences,
                        int helpers) {
  return fit_weights(
      binding, poses, max_influences,
      [&](std::span<const Mat4> M, std::span<Vec3> out) { binding.deform_frames(M, out); }, nullptr, helpers);
}

namespace {

/// The helper half way between two split joints (helper_matrix): their
/// rigid parts' dual-quaternion mean, scaled by the mean of their volume
/// scales. A similarity, so that a glTF node's translation, rotation and
/// uniform scale carry it exactly in any pose.
Mat4 helper_of(const detail::DualJoint& a, const detail::DualJoint& b) {
  detail::DualJoint ra = a, rb = b; // the rigid parts
  ra.stretch = rb.stretch = Eigen::Matrix3d::Identity();
  ra.rigid = rb.rigid = true;
  detail::DualBlend half;
  half.add(ra, 0.5);
  half.add(rb, 0.5);
  Mat4 m = half.matrix(); // valid: aligned to one hemisphere, the sum's norm is at least 1/sqrt(2)
  const double s =
      0.5 * (std::cbrt(std::abs(a.stretch.determinant())) + std::cbrt(std::abs(b.stretch.determinant())));
  m.topLeftCorner<3, 3>() *= s;
  return m;
}

} // namespace

Mat4 helper_matrix(const Mat4& a, const Mat4& b) {
  return helper_of(detail::split_joint(a), detail::split_joint(b));
}

std::vector<Mat4> with_helpers(const SkinWeights& w, std::span<const Mat4> skinning) {
  const size_t rig = static_cast<size_t>(w.rig_joints());
  if (skinning.size() != rig)
    throw Error("with_helpers: " + std::to_string(skinning.size()) + " matrices for " + std::to_string(rig) +
                " rig joints");
  std::vector<Mat4> out(skinning.begin(), skinning.end());
  for (const auto& [a, b] : w.helpers)
    if (a < 0 || b < 0 || static_cast<size_t>(a) >= rig || static_cast<size_t>(b) >= rig)
      throw Error("with_helpers: a helper between joints " + std::to_string(a) + " and " + std::to_string(b) + " of " +
                  std::to_string(rig));
  for (const auto& [a, b] : w.helpers)
    out.push_back(helper_matrix(skinning[static_cast<size_t>(a)], skinning[static_cast<size_t>(b)]));
  return out;
}

namespace {

/// Pairs of a vertex's joints that a helper may join: every two of its (at
/// most) eight heaviest candidates, as (smaller, larger) joint index.
std::vector<std::array<int, 2>> pairs_of(const std::vector<std::pair<int, double>>& inf) {
  std::vector<std::pair<int, double>> top = inf;
  std::sort(top.begin(), top.end(), [](const auto& a, const auto& b) {
    return a.second != b.second ? a.second > b.second : a.first < b.first;
  });
  if (top.size() > 8)
    top.resize(8);
  std::vector<std::array<int, 2>> out;
  for (size_t i = 0; i < top.size(); ++i)
    for (size_t j = i + 1; j < top.size(); ++j)
      if (top[i].first != top[j].first)
        out.push_back({std::min(top[i].first, top[j].first), std::max(top[i].first, top[j].first)});
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

} // namespace

SkinWeights fit_weights(const Binding& binding, const std::vector<std::vector<Mat4>>& poses, int max_influences,
                        const std::function<void(std::span<const Mat4>, std::span<Vec3>)>& deform_frames,
                        const std::function<void(int, std::vector<std::pair<int, double>>&)>& candidates,
                        int helpers) {
  check_influences(max_influences);
  if (helpers < 0)
    throw InputError("helpers", std::to_string(helpers), "must be 0 or more");
  const size_t nj = binding.joints().size();
  const int n = binding.num_input_vertices();
  for (size_t p = 0; p < poses.size(); ++p)
    if (poses[p].size() != nj)
      throw InputError("poses", "pose " + std::to_string(p),
                       "has " + std::to_string(poses[p].size()) + " matrices for " + std::to_string(nj) + " joints");
  // Every pose's matrices and deformed vertices are held at once: refused
  // past the memory budget (half the machine's, at least 4 GB) rather than
  // run out of memory (a skeleton of thousands of joints makes ten poses of
  // each).
  const double held = static_cast<double>(poses.size()) *
                      (static_cast<double>(nj) * sizeof(Mat4) + static_cast<double>(n) * sizeof(Vec3));
  if (held > detail::memory_budget()) {
    std::ostringstream why;
    why << std::setprecision(3) << "fitting over " << poses.size() << " poses of " << nj << " joints and " << n
        << " vertices would take " << held / 1e9
        << " GB: fit over fewer clip frames, or bake the harmonic weights (--weights harmonic)";
    throw InputError("weights", "fitted", why.str());
  }
  SkinWeights w = empty_weights(binding, max_influences);
  // The rest pose and every sample pose through the binding itself.
  std::vector<Vec3> rest(n);
  deform_frames(std::vector<Mat4>(nj, Mat4::Identity()), rest);
  std::vector<Mat4> all;
  for (const auto& p : poses)
    all.insert(all.end(), p.begin(), p.end());
  std::vector<Vec3> target(poses.size() * n);
  deform_frames(all, target);
  // A gentle pull (relative to the motion's size) towards the harmonic
  // weights keeps joints the poses do not move at their harmonic share.
  double scale = 0;
  for (const Vec3& x : rest)
    scale = std::max(scale, x.norm());
  const double pull = 1e-3 * std::max(scale, 1e-300);
  auto joints_of = [&](int v, std::vector<std::pair<int, double>>& inf) {
    binding.harmonic_weights(v, inf);
    if (candidates)
      candidates(v, inf);
  };

  // Helper pairs: those some vertex could use, and their matrices in every pose.
  const bool with_pairs = helpers > 0 && !poses.empty();
  std::vector<std::array<int, 2>> offered; // sorted
  std::vector<std::vector<Mat4>> pair_matrix; // per pose, per offered pair
  if (with_pairs) {
    std::vector<std::pair<int, double>> inf;
    for (int v = 0; v < n; ++v) {
      joints_of(v, inf);
      for (const auto& q : pairs_of(inf))
        offered.push_back(q);
    }
    std::sort(offered.begin(), offered.end());
    offered.erase(std::unique(offered.begin(), offered.end()), offered.end());
    // A matrix per pose and pair: refused past 2 GB rather than run out of memory.
    const double bytes = static_cast<double>(poses.size()) * static_cast<double>(offered.size()) * sizeof(Mat4);
    if (bytes > 2e9) {
      std::ostringstream why;
      why << std::setprecision(3) << "the " << offered.size() << " pairs of joints over " << poses.size()
          << " poses would take " << bytes / 1e9 << " GB: fit over fewer clip frames, or bake without helpers";
      throw InputError("helpers", std::to_string(helpers), why.str());
    }
    pair_matrix.resize(poses.size());
    tbb::parallel_for(size_t{0}, poses.size(), [&](size_t p) {
      std::vector<detail::DualJoint> d(nj);
      for (size_t j = 0; j < nj; ++j)
        d[j] = detail::split_joint(poses[p][j]);
      pair_matrix[p].resize(offered.size());
      for (size_t q = 0; q < offered.size(); ++q)
        pair_matrix[p][q] = helper_of(d[static_cast<size_t>(offered[q][0])], d[static_cast<size_t>(offered[q][1])]);
    });
  }
  auto offered_index = [&](const std::array<int, 2>& q) {
    return static_cast<int>(std::lower_bound(offered.begin(), offered.end(), q) - offered.begin());
  };

  // One vertex's fit over its joints `inf` and the offered pairs `cols`
  // (indices into `offered`): the weights of the joints, then of the pairs.
  // With `plain`, also the fit of the joints alone, and how much the pairs
  // lower the objective.
  struct Fit {
    Eigen::VectorXd sol;
    double gain = 0;
  };
  auto fit_vertex = [&](int v, const std::vector<std::pair<int, double>>& inf, const std::vector<int>& cols,
                        bool plain) {
    const int m = static_cast<int>(inf.size());
    const int c = m + static_cast<int>(cols.size());
    // The normal equations of the least squares over the poses, with the
    // pull towards the given weights as a ridge: 1/2 x'Gx - h'x.
    const int rows = 3 * static_cast<int>(poses.size());
    Eigen::MatrixXd A(rows, c);
    Eigen::VectorXd b(rows);
    const Eigen::Vector4d x = rest[v].homogeneous();
    for (size_t p = 0; p < poses.size(); ++p) {
      for (int i = 0; i < m; ++i)
        A.block<3, 1>(3 * static_cast<int>(p), i) = (poses[p][inf[i].first] * x).head<3>();
      for (int i = m; i < c; ++i)
        A.block<3, 1>(3 * static_cast<int>(p), i) = (pair_matrix[p][static_cast<size_t>(cols[i - m])] * x).head<3>();
      b.segment<3>(3 * static_cast<int>(p)) = target[p * n + v];
    }
    Eigen::MatrixXd G = A.transpose() * A;
    Eigen::VectorXd h = A.transpose() * b;
    Eigen::VectorXd start = Eigen::VectorXd::Zero(c);
    for (int i = 0; i < c; ++i) {
      const double given = i < m ? inf[i].second : 0.0; // a helper is pulled towards nothing
      G(i, i) += pull * pull;
      h[i] += pull * pull * given;
      start[i] = std::max(0.0, given);
    }
    // Too many joints: refit on the k largest of the fit, and on the k
    // largest given weights, and keep whichever has the smaller objective
    // (the residual over the poses, plus the small pull). A cut of the fit
    // alone can drop one side of a blend that the rig keeps (one of two legs
    // at the rump); choosing the subset with the least residual (dropping
    // joints one at a time) fitted the poses closer but played unseen clips
    // worse (docs/bake.md).
    Fit out;
    out.sol = detail::convex_least_squares_top_k(G, h, start, max_influences);
    if (plain && c > m) {
      const Eigen::VectorXd alone = detail::convex_least_squares_top_k(G.topLeftCorner(m, m), h.head(m),
                                                                       start.head(m), max_influences);
      // The gain: how much closer the vertex comes over the poses (the root
      // mean square distance, without the pull) with the pairs than without.
      const double poses_n = static_cast<double>(poses.size());
      out.gain = std::max(0.0, ((A.leftCols(m) * alone - b).norm() - (A * out.sol - b).norm()) / std::sqrt(poses_n));
    }
    return out;
  };

  // Rank the pairs by the most any vertex owes one: its weight on the pair
  // times how much closer the pairs brought it. The goal is the worst
  // vertex, so a pair that one badly served vertex needs ranks with one
  // that many vertices share a little of (a sum over the vertices ranked
  // them about as well on the mean and worse on the worst vertex; see
  // docs/bake.md).
  std::vector<int> chosen; // indices into `offered`, by rank
  if (with_pairs) {
    std::vector<std::vector<std::pair<int, double>>> credit(static_cast<size_t>(n));
    tbb::parallel_for(0, n, [&](int v) {
      std::vector<std::pair<int, double>> inf;
      joints_of(v, inf);
      if (inf.size() <= 1)
        return;
      std::vector<int> cols;
      for (const auto& q : pairs_of(inf))
        cols.push_back(offered_index(q));
      const Fit f = fit_vertex(v, inf, cols, true);
      const int m = static_cast<int>(inf.size());
      for (size_t i = 0; i < cols.size(); ++i)
        if (f.sol[m + static_cast<int>(i)] > 0)
          credit[static_cast<size_t>(v)].emplace_back(cols[i], f.sol[m + static_cast<int>(i)] * f.gain);
    });
    std::vector<double> score(offered.size(), 0.0);
    for (const auto& per : credit)
      for (const auto& [q, s] : per)
        score[static_cast<size_t>(q)] = std::max(score[static_cast<size_t>(q)], s);
    std::vector<int> order;
    for (size_t q = 0; q < offered.size(); ++q)
      if (score[q] > 0)
        order.push_back(static_cast<int>(q));
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return score[a] > score[b]; });
    if (static_cast<int>(order.size()) > helpers)
      order.resize(static_cast<size_t>(helpers));
    chosen = order;
    std::set<std::string> names(w.joints.begin(), w.joints.end());
    for (const int q : chosen) {
      const auto [a, b] = offered[static_cast<size_t>(q)];
      std::string name = w.joints[static_cast<size_t>(a)] + "~" + w.joints[static_cast<size_t>(b)];
      for (int copy = 2; names.count(name); ++copy)
        name = w.joints[static_cast<size_t>(a)] + "~" + w.joints[static_cast<size_t>(b)] + "~" + std::to_string(copy);
      names.insert(name);
      w.joints.push_back(name);
      w.helpers.push_back({a, b});
    }
  }
  std::vector<int> helper_of(offered.size(), -1); // offered pair -> helper number
  for (size_t i = 0; i < chosen.size(); ++i)
    helper_of[static_cast<size_t>(chosen[i])] = static_cast<int>(i);

  tbb::parallel_for(0, n, [&](int v) {
    std::vector<std::pair<int, double>> inf;
    joints_of(v, inf);
    const int m = static_cast<int>(inf.size());
    if (m <= 1 || poses.empty()) {
      store(inf, max_influences, w, v);
      return;
    }
    std::vector<int> cols;
    if (!chosen.empty())
      for (const auto& q : pairs_of(inf))
        if (helper_of[static_cast<size_t>(offered_index(q))] >= 0)
          cols.push_back(offered_index(q));
    const Fit f = fit_vertex(v, inf, cols, false);
    std::vector<std::pair<int, double>> fitted;
    for (int i = 0; i < m; ++i)
      if (f.sol[i] > 0)
        fitted.emplace_back(inf[i].first, f.sol[i]);
    for (size_t i = 0; i < cols.size(); ++i)
      if (f.sol[m + static_cast<int>(i)] > 0)
        fitted.emplace_back(static_cast<int>(nj) + helper_of[static_cast<size_t>(cols[i])],
                            f.sol[m + static_cast<int>(i)]);
    if (fitted.empty())
      fitted = inf;
    store(fitted, max_influences, w, v);
  });
  // A chosen pair can end with no weight anywhere (ranked where the fit had
  // every pair, refitted with the chosen alone, or cut past k): it would
  // cost an engine an update a frame for nothing, so it is dropped.
  if (!w.helpers.empty()) {
    std::vector<char> used(w.joints.size(), 0);
    for (const int j : w.joint)
      if (j >= 0)
        used[static_cast<size_t>(j)] = 1;
    std::vector<int> remap(w.joints.size(), -1);
    std::vector<std::string> names(w.joints.begin(), w.joints.begin() + static_cast<std::ptrdiff_t>(nj));
    std::vector<std::array<int, 2>> kept;
    for (size_t j = 0; j < w.joints.size(); ++j)
      if (j < nj) {
        remap[j] = static_cast<int>(j);
      } else if (used[j]) {
        remap[j] = static_cast<int>(names.size());
        names.push_back(w.joints[j]);
        kept.push_back(w.helpers[j - nj]);
      }
    for (int& j : w.joint)
      if (j >= 0)
        j = remap[static_cast<size_t>(j)];
    w.joints = std::move(names);
    w.helpers = std::move(kept);
  }
  return w;
}

std::vector<Vec3> skin_positions(const SkinWeights& w, std::span<const Vec3> rest, std::span<const Mat4> skinning,
                                 Skinning method) {
  if (!w.helpers.empty() && skinning.size() == static_cast<size_t>(w.rig_joints())) {
    const std::vector<Mat4> full = with_helpers(w, skinning);
    return skin_positions(w, rest, full, method);
  }
  if (static_cast<int>(rest.size()) != w.num_vertices() || skinning.size() != w.joints.size())
    throw Error("skin_positions: " + std::to_string(rest.size()) + " positions and " + std::to_string(skinning.size()) +
                " matrices for weights of " + std::to_string(w.num_vertices()) + " vertices and " +
                std::to_string(w.joints.size()) + " joints");
  std::vector<Vec3> out(rest.size());
  std::vector<detail::DualJoint> dual;
  if (method == Skinning::DualQuaternion)
    for (const Mat4& m : skinning)
      dual.push_back(detail::split_joint(m));
  detail::DualBlend blend;
  const int k = w.influences;
  for (size_t v = 0; v < rest.size(); ++v) {
    Eigen::Vector4d x = Eigen::Vector4d::Zero();
    blend.clear();
    for (int i = 0; i < k; ++i) {
      const int j = w.joint[v * k + i];
      if (j < 0)
        continue;
      if (method == Skinning::DualQuaternion)
        blend.add(dual[j], w.weight[v * k + i]);
      else
        x += w.weight[v * k + i] * (skinning[j] * rest[v].homogeneous());
    }
    if (method == Skinning::Linear)
      out[v] = x.head<3>();
    else
      out[v] = blend.valid() ? blend.apply(rest[v]) : rest[v];
  }
  return out;
}

std::string weights_csv(const SkinWeights& w) {
  std::ostringstream out;
  out << std::setprecision(17) << "vertex";
  for (int i = 0; i < w.influences; ++i)
    out << ",joint_" << i << ",weight_" << i;
  out << '\n';
  auto quoted = [](const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos)
      return s;
    std::string q = "\"";
    for (char c : s)
      q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  for (int v = 0; v < w.num_vertices(); ++v) {
    out << v;
    for (int i = 0; i < w.influences; ++i) {
      const int j = w.joint[static_cast<size_t>(v) * w.influences + i];
      out << ',' << (j >= 0 ? quoted(w.joints[j]) : "") << ',';
      if (j >= 0)
        out << w.weight[static_cast<size_t>(v) * w.influences + i];
    }
    out << '\n';
  }
  return out.str();
}

} // namespace curvenet
