#include "curvenet/weights.hpp"

#include <algorithm>
#include <limits>
#include <map>

namespace curvenet {

const char* to_string(WeightRule rule) {
  return rule == WeightRule::Segment ? "segment" : "blend-zone";
}

std::vector<std::pair<int, double>> auto_weights(const std::vector<Joint>& joints, const Eigen::Vector3d& p,
                                                 const AutoWeightOptions& opt) {
  return auto_weights(joints, p, opt, {});
}

std::vector<int> joint_parents(const std::vector<Joint>& joints) {
  const int n = static_cast<int>(joints.size());
  std::map<std::string, int> index;
  for (int j = 0; j < n; ++j)
    index[joints[j].name] = j;
  std::vector<int> parent(n, -1);
  for (int j = 0; j < n; ++j)
    if (joints[j].parent)
      parent[j] = index.at(*joints[j].parent);
  return parent;
}

std::vector<std::pair<int, double>> auto_weights(const std::vector<Joint>& joints, const Eigen::Vector3d& p,
                                                 const AutoWeightOptions& opt, const std::vector<int>& bones) {
  return auto_weights(joints, joint_parents(joints), p, opt, bones);
}

std::vector<std::pair<int, double>> auto_weights(const std::vector<Joint>& joints, const std::vector<int>& parent,
                                                 const Eigen::Vector3d& p, const AutoWeightOptions& opt,
                                                 const std::vector<int>& bones) {
  const int n = static_cast<int>(joints.size());
  auto origin = [&](int j) -> Eigen::Vector3d { return joints[j].bind.block<3, 1>(0, 3); };
  // The nearest bone (parent[c] -> c), or the nearest lone joint.
  int best_c = -1;
  double best_d = std::numeric_limits<double>::infinity(), best_t = 0, best_raw = 0;
  std::vector<char> allowed(n, bones.empty() ? 1 : 0);
  for (int c : bones)
    if (c >= 0 && c < n)
      allowed[c] = 1;
  for (int c = 0; c < n; ++c) {
    if (parent[c] < 0 || !allowed[c])
      continue;
    const Eigen::Vector3d a = origin(parent[c]), b = origin(c);
    const double len2 = (b - a).squaredNorm();
    const double raw = len2 > 0 ? (p - a).dot(b - a) / len2 : 0.0;
    const double t = std::clamp(raw, 0.0, 1.0);
    const double d = (a + t * (b - a) - p).norm();
    if (d < best_d) {
      best_d = d;
      best_c = c;
      best_t = t;
      best_raw = raw;
    }
  }
  std::map<int, double> w;
  if (best_c < 0) {
    int nearest = 0;
    for (int j = 1; j < n; ++j)
      if ((origin(j) - p).norm() < (origin(nearest) - p).norm())
        nearest = j;
    w[nearest] = 1;
  } else if (opt.rule == WeightRule::Segment) {
    w[parent[best_c]] += 1 - best_t;
    w[best_c] += best_t;
  } else {
    const int pj = parent[best_c];
    const double len = (origin(best_c) - origin(pj)).norm();
    const double zone = std::max(opt.blend * len, 1e-300);
    auto ramp = [](double x) { // smoothstep from 0 at x = 0 to 1 at x = 1
      x = std::clamp(x, 0.0, 1.0);
      return x * x * (3 - 2 * x);
    };
    // Signed distance to the child joint along the bone: negative past it,
    // where a joint with no child bone drives what lies beyond it.
    const double to_end = (1 - best_raw) * len, from_start = best_t * len;
    double w_child = 0, w_grand = 0;
    if (to_end < zone)
      w_child = to_end >= 0 ? 0.5 * ramp(1 - to_end / zone) : 0.5 + 0.5 * ramp(-to_end / zone);
    if (parent[pj] >= 0 && from_start < zone)
      w_grand = 0.5 * ramp(1 - from_start / zone); // the previous bone's joint
    if (w_child + w_grand > 1)
      w_grand = 1 - w_child;
    w[pj] += 1 - w_child - w_grand;
    if (w_child > 0)
      w[best_c] += w_child;
    if (w_grand > 0)
      w[parent[pj]] += w_grand;
  }
  std::vector<std::pair<int, double>> out;
  for (const auto& [j, v] : w)
    if (v > 0)
      out.emplace_back(j, v);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
  return out;
}

SkinComparison compare_with_skin(const SkinnedMesh& skin, const std::vector<Eigen::Vector3d>& positions,
                                 const std::vector<std::vector<Mat4>>& poses, const AutoWeightOptions& options) {
  std::vector<std::vector<std::pair<int, double>>> w;
  w.reserve(positions.size());
  for (const auto& p : positions)
    w.push_back(auto_weights(skin.joints, p, options));
  SkinComparison out;
  long count = 0;
  for (const auto& m : poses) {
    const auto reference = skin_positions(skin, positions, m);
    for (size_t v = 0; v < positions.size(); ++v) {
      Eigen::Vector3d q = Eigen::Vector3d::Zero();
      for (const auto& [j, wj] : w[v])
        q += wj * (m[j] * positions[v].homogeneous()).head<3>();
      const double d = (q - reference[v]).norm();
      out.mean += d;
      out.max = std::max(out.max, d);
      ++count;
    }
  }
  if (count > 0)
    out.mean /= static_cast<double>(count);
  return out;
}

} // namespace curvenet
