// Stage 8 of the starter: each node's weights from the bones of the limb
// it lies on.

#include "curvenet/weights.hpp"
#include "embed/embedding_impl.hpp"
#include "starter/stages.hpp"

#include <optional>
#include <set>

#include <algorithm>
#include <limits>

namespace curvenet::detail {

namespace {

/// Of `bones` (each named by its child joint), the one whose segment passes nearest to p.
int nearest_bone(const StarterContext& c, const Vec3& p, const std::vector<int>& bones) {
  int best = bones.front();
  double best_d = std::numeric_limits<double>::infinity();
  for (int b : bones) {
    const Vec3 a = c.sk.origin[c.sk.parent[b]], e = c.sk.origin[b];
    const double len2 = (e - a).squaredNorm();
    const double t = len2 > 0 ? std::clamp((p - a).dot(e - a) / len2, 0.0, 1.0) : 0.0;
    const double d = (a + t * (e - a) - p).norm();
    if (d < best_d) {
      best_d = d;
      best = b;
    }
  }
  return best;
}

/// The skin's weights at each welded vertex of the mesh, by joint name,
/// the mean over the file's vertices welded into it.
class SkinSampler {
public:
  SkinSampler(const SurfaceMesh& mesh, const SkinnedMesh& skin, const std::vector<Joint>& rig_joints) : skin_(skin) {
    for (const Joint& j : rig_joints)
      names_.insert(j.name);
    files_of_.resize(mesh.num_vertices());
    for (size_t i = 0; i < mesh.input_to_welded.size(); ++i)
      files_of_[mesh.input_to_welded[i]].push_back(static_cast<int>(i));
  }
  /// At a point of the surface given as input (welded) vertices with
  /// barycentric weights; empty where the skin weights no joint the rig has.
  [[nodiscard]] std::map<std::string, double> at(const std::vector<std::pair<int, double>>& point) const {
    std::map<std::string, double> w;
    for (const auto& [v, b] : point) {
      const auto& files = files_of_[v];
      for (int i : files)
        for (int k = 0; k < 4; ++k) {
          const int j = skin_.vertex_joint[i][k];
          if (j >= 0 && skin_.vertex_weight[i][k] > 0 && names_.count(skin_.joints[j].name))
            w[skin_.joints[j].name] += b * skin_.vertex_weight[i][k] / static_cast<double>(files.size());
        }
    }
    double sum = 0;
    for (const auto& [j, x] : w)
      sum += x;
    std::map<std::string, double> out;
    for (const auto& [j, x] : w)
      if (sum > 0 && x / sum >= kSkinFloor)
        out[j] = x;
    sum = 0;
    for (const auto& [j, x] : out)
      sum += x;
    for (auto& [j, x] : out)
      x /= sum;
    return out;
  }

private:
  /// Skin weights under this share of a node's are dropped.
  static constexpr double kSkinFloor = 0.01;
  const SkinnedMesh& skin_;
  std::set<std::string> names_;
  std::vector<std::vector<int>> files_of_;
};

} // namespace

void node_weights(const StarterContext& c, const NodeWeightOptions& wo, const std::vector<Ring>& rings,
                  const std::vector<int>& active, const Embedding& embedding, const std::vector<Joint>& rig_joints,
                  NetResult& net) {
  const std::vector<Joint>& joints = c.joints;
  const int nj = static_cast<int>(joints.size());
  std::optional<SkinSampler> skin;
  if (wo.skin)
    skin.emplace(c.mesh, *wo.skin, rig_joints);
  std::map<int, bool> end_of; // weighted joint ending its chain -> whether its end ring is in the net
  for (int j = 0; j < nj; ++j)
    if (c.sk.kids[j].empty() && c.sk.parent[j] >= 0 && wo.deforming.count(joints[j].name))
      end_of[j] = false;
  for (int i : active)
    if (rings[i].frac > 1)
      end_of[rings[i].joint] = true;
  for (size_t k = 0; k < net.rig.nodes.size(); ++k) {
    const Node& n = net.rig.nodes[k];
    const Ring& r = rings[net.node_ring[k]];
    std::map<std::string, double>& w = net.rig.weights[n.id];
    w.clear();
    if (skin) {
      const detail::Vertex v = embedding.impl().result.node_vertex[k];
      if (v.is_valid())
        w = skin->at(embedding.impl().cut.input_weights(v));
      if (!w.empty())
        continue;
    }
    const bool middle = net.node_middle[k] != 0; // of a profile that ends on ring r
    if (r.frac > 1 || (!middle && r.frac == 1 && end_of.count(r.joint) && !end_of.at(r.joint))) {
      w[joints[r.joint].name] = 1;
      continue;
    }
    std::set<int> near;
    for (int j : r.own) {
      near.insert(j);
      if (c.sk.parent[j] >= 0)
        near.insert(c.sk.parent[j]);
      near.insert(c.sk.kids[j].begin(), c.sk.kids[j].end());
    }
    std::vector<int> bones;
    for (int b = 0; b < nj; ++b)
      if (c.sk.parent[b] >= 0 && (near.count(b) || near.count(c.sk.parent[b])))
        bones.push_back(b);
    // A ring is a section across one bone: the bone its centre lies nearest
    // to weights all its nodes. Node by node, a limb that curls back (a
    // tail, a trunk) would hand a node to a bone further down the chain that
    // happens to pass nearer to it.
    // A middle node lies along a bone into the ring, whichever is nearest.
    if (!middle && r.own.size() == 1 && bones.size() > 1)
      bones = {nearest_bone(c, r.centre, bones)};
    for (const auto& [j, v] : auto_weights(joints, n.position, wo.rule, bones))
      w[joints[j].name] = v;
  }
}

} // namespace curvenet::detail
