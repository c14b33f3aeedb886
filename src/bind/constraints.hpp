#pragma once
// The constraints of a binding: every CutChain vertex with its profile's
// node weights, interpolated along the chain by arc length. The binding
// (binding.cpp) and the layer over a skin (layer.cpp) pose the curves
// through them.

#include "curvenet/rig.hpp"
#include "embed/embedding_impl.hpp"

#include <map>
#include <string>
#include <vector>

namespace curvenet::detail {

struct ChainConstraints {
  std::vector<char> constrained;         ///< per cut-mesh vertex
  std::vector<std::map<int, double>> cw; ///< per cut-mesh vertex: joint -> weight, summing to 1; empty off the chains
  /// Per cut-mesh vertex on a chain: its two nodes and its parameter between them (0 at the first).
  std::vector<std::array<int, 2>> nodes;
  std::vector<double> t;
};

/// `rig` must have every node's weights (complete_weights), by the joint
/// names of `joint_index`.
ChainConstraints chain_constraints(const Embedding::Impl& emb, const Rig& rig,
                                   const std::map<std::string, int>& joint_index);

} // namespace curvenet::detail
