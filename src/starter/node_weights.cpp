// Stage 8 of the starter: each node's weights from the bones of the limb
// it lies on.

#include "curvenet/weights.hpp"
#include "starter/stages.hpp"

namespace curvenet::detail {

void node_weights(const StarterContext& c, const std::vector<Ring>& rings, const std::vector<int>& active,
                  NetResult& net) {
  const std::vector<Joint>& joints = c.joints;
  const int nj = static_cast<int>(joints.size());
  std::map<int, bool> end_of; // weighted joint ending its chain -> whether its end ring is in the net
  for (int j = 0; j < nj; ++j)
    if (c.sk.kids[j].empty() && c.sk.parent[j] >= 0 && c.options.deforming.count(joints[j].name))
      end_of[j] = false;
  for (int i : active)
    if (rings[i].frac > 1)
      end_of[rings[i].joint] = true;
  for (size_t k = 0; k < net.rig.nodes.size(); ++k) {
    const Node& n = net.rig.nodes[k];
    const Ring& r = rings[net.node_ring[k]];
    std::map<std::string, double>& w = net.rig.weights[n.id];
    w.clear();
    if (r.frac > 1 || (r.frac == 1 && end_of.count(r.joint) && !end_of.at(r.joint))) {
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
    for (const auto& [j, v] : auto_weights(joints, n.position, c.options.weights, bones))
      w[joints[j].name] = v;
  }
}

} // namespace curvenet::detail
