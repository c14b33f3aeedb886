// Baked skin weights: the top-k harmonic weights, weights fitted to the full
// deformation over sample poses, linear blend skinning with them, and CSV.

#include "core/dual_quaternion.hpp"
#include "curvenet/bake.hpp"
#include "curvenet/errors.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <numeric>
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

/// Non-negative least squares, min |A x - b|, x >= 0 (Lawson and Hanson's
/// active set method). Small dense problems: one per vertex.
Eigen::VectorXd nnls(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  const int n = static_cast<int>(A.cols());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  std::vector<bool> passive(n, false);
  const double tol = 1e-12 * std::max(1.0, A.norm() * b.norm());
  for (int outer = 0; outer < 3 * n + 3; ++outer) {
    const Eigen::VectorXd w = A.transpose() * (b - A * x);
    int best = -1;
    for (int j = 0; j < n; ++j)
      if (!passive[j] && w[j] > tol && (best < 0 || w[j] > w[best]))
        best = j;
    if (best < 0)
      break;
    passive[best] = true;
    for (int inner = 0; inner < 3 * n + 3; ++inner) {
      std::vector<int> P;
      for (int j = 0; j < n; ++j)
        if (passive[j])
          P.push_back(j);
      Eigen::MatrixXd Ap(A.rows(), static_cast<int>(P.size()));
      for (size_t i = 0; i < P.size(); ++i)
        Ap.col(static_cast<int>(i)) = A.col(P[i]);
      const Eigen::VectorXd z = Ap.colPivHouseholderQr().solve(b);
      bool feasible = true;
      for (int i = 0; i < z.size(); ++i)
        feasible = feasible && z[i] > 0;
      if (feasible) {
        x.setZero();
        for (size_t i = 0; i < P.size(); ++i)
          x[P[i]] = z[static_cast<int>(i)];
        break;
      }
      // Step back to the boundary of the feasible set, and drop what reaches it.
      double alpha = 1;
      for (size_t i = 0; i < P.size(); ++i)
        if (z[static_cast<int>(i)] <= 0)
          alpha = std::min(alpha, x[P[i]] / (x[P[i]] - z[static_cast<int>(i)]));
      for (size_t i = 0; i < P.size(); ++i) {
        x[P[i]] += alpha * (z[static_cast<int>(i)] - x[P[i]]);
        if (x[P[i]] <= 1e-15)
          passive[P[i]] = false, x[P[i]] = 0;
      }
    }
  }
  return x;
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
    auto solve = [&](const std::vector<std::pair<int, double>>& cand) {
      const int c = static_cast<int>(cand.size());
      const int rows = 3 * static_cast<int>(poses.size()) + c + 1;
      Eigen::MatrixXd A = Eigen::MatrixXd::Zero(rows, c);
      Eigen::VectorXd b = Eigen::VectorXd::Zero(rows);
      const Eigen::Vector4d x = rest[v].homogeneous();
      for (size_t p = 0; p < poses.size(); ++p) {
        for (int i = 0; i < c; ++i)
          A.block<3, 1>(3 * static_cast<int>(p), i) = (poses[p][cand[i].first] * x).head<3>();
        b.segment<3>(3 * static_cast<int>(p)) = target[p * n + v];
      }
      for (int i = 0; i < c; ++i) {
        A(3 * static_cast<int>(poses.size()) + i, i) = pull;
        b[3 * static_cast<int>(poses.size()) + i] = pull * cand[i].second;
      }
      // Sum to one, strongly.
      const double big = 1e3 * std::max(scale, 1e-300);
      A.row(rows - 1).setConstant(big);
      b[rows - 1] = big;
      const Eigen::VectorXd sol = nnls(A, b);
      std::vector<std::pair<int, double>> out;
      for (int i = 0; i < c; ++i)
        if (sol[i] > 0)
          out.emplace_back(cand[i].first, sol[i]);
      return out;
    };
    auto fitted = solve(inf);
    if (static_cast<int>(fitted.size()) > max_influences) {
      // Keep the k largest, and fit those alone.
      std::sort(fitted.begin(), fitted.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
      fitted.resize(max_influences);
      std::vector<std::pair<int, double>> cand;
      for (const auto& [j, x] : fitted) {
        const auto it = std::find_if(inf.begin(), inf.end(), [j = j](const auto& q) { return q.first == j; });
        cand.emplace_back(j, it->second);
      }
      fitted = solve(cand);
    }
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
