// Baked skin weights: the top-k harmonic weights, weights fitted to the full
// deformation over sample poses, linear blend skinning with them, and CSV.

#include "core/convex_least_squares.hpp"
#include "core/dual_quaternion.hpp"
#include "curvenet/bake.hpp"
#include "curvenet/errors.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <iomanip>
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

SkinWeights fit_weights(const Binding& binding, const std::vector<std::vector<Mat4>>& poses, int max_influences) {
  return fit_weights(
      binding, poses, max_influences,
      [&](std::span<const Mat4> M, std::span<Vec3> out) { binding.deform_frames(M, out); }, nullptr);
}

SkinWeights fit_weights(const Binding& binding, const std::vector<std::vector<Mat4>>& poses, int max_influences,
                        const std::function<void(std::span<const Mat4>, std::span<Vec3>)>& deform_frames,
                        const std::function<void(int, std::vector<std::pair<int, double>>&)>& candidates) {
  check_influences(max_influences);
  const size_t nj = binding.joints().size();
  const int n = binding.num_input_vertices();
  for (size_t p = 0; p < poses.size(); ++p)
    if (poses[p].size() != nj)
      throw InputError("poses", "pose " + std::to_string(p),
                       "has " + std::to_string(poses[p].size()) + " matrices for " + std::to_string(nj) + " joints");
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
  tbb::parallel_for(0, n, [&](int v) {
    std::vector<std::pair<int, double>> inf;
    binding.harmonic_weights(v, inf);
    if (candidates)
      candidates(v, inf);
    const int m = static_cast<int>(inf.size());
    if (m <= 1 || poses.empty()) {
      store(inf, max_influences, w, v);
      return;
    }
    // The normal equations of the least squares over the poses, with the
    // pull towards the given weights as a ridge: 1/2 x'Gx - h'x.
    const int c = m; // the candidate joints
    const int rows = 3 * static_cast<int>(poses.size());
    Eigen::MatrixXd A(rows, c);
    Eigen::VectorXd b(rows);
    const Eigen::Vector4d x = rest[v].homogeneous();
    for (size_t p = 0; p < poses.size(); ++p) {
      for (int i = 0; i < c; ++i)
        A.block<3, 1>(3 * static_cast<int>(p), i) = (poses[p][inf[i].first] * x).head<3>();
      b.segment<3>(3 * static_cast<int>(p)) = target[p * n + v];
    }
    Eigen::MatrixXd G = A.transpose() * A;
    Eigen::VectorXd h = A.transpose() * b;
    Eigen::VectorXd start(c);
    for (int i = 0; i < c; ++i) {
      G(i, i) += pull * pull;
      h[i] += pull * pull * inf[i].second;
      start[i] = std::max(0.0, inf[i].second);
    }
    // Too many joints: refit on the k largest of the fit, and on the k
    // largest given weights, and keep whichever has the smaller objective
    // (the residual over the poses, plus the small pull). A cut of the fit
    // alone can drop one side of a blend that the rig keeps (one of two legs
    // at the rump); choosing the subset with the least residual (dropping
    // joints one at a time) fitted the poses closer but played unseen clips
    // worse (docs/bake.md).
    const Eigen::VectorXd sol = detail::convex_least_squares_top_k(G, h, start, max_influences);
    std::vector<std::pair<int, double>> fitted;
    for (int i = 0; i < c; ++i)
      if (sol[i] > 0)
        fitted.emplace_back(inf[i].first, sol[i]);
    if (fitted.empty())
      fitted = inf;
    store(fitted, max_influences, w, v);
  });
  return w;
}

std::vector<Vec3> skin_positions(const SkinWeights& w, std::span<const Vec3> rest, std::span<const Mat4> skinning,
                                 Skinning method) {
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
