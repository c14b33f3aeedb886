#pragma once
// What an Embedding holds: the cut mesh, its CutChains and its regions. The
// later stages (bind, transfer) read these.

#include "curvenet/embed.hpp"
#include "cut/cutter.hpp"
#include "regions/regions.hpp"

#include <optional>

namespace curvenet {

struct Embedding::Impl {
  EmbedReport report;
  detail::CutMesh cut;
  detail::CutInput input;   ///< ids, node placements and traced paths
  detail::CutResult result; ///< chains and node vertices
  detail::RegionResult regions;
  std::vector<std::vector<double>> sample_t;         ///< per profile: normalised arc length of each sample
  std::vector<std::vector<Eigen::Vector3d>> samples; ///< per profile: the samples, in mesh space

  /// The profile parameter t (normalised arc length of the curve as written,
  /// ends at the nodes) of vertex i of profile p's CutChain.
  [[nodiscard]] double chain_t(int p, size_t i) const;
};

namespace detail {
class TraceMesh;
/// embed() on the trace mesh of `mesh` already built (TraceMesh(mesh,
/// CutMesh::from_surface(mesh))): the transfer builds one of each mesh for
/// placing, and building them is a large part of an embedding's cost.
/// `uncut`, when given, is that CutMesh::from_surface(mesh), handed over
/// so that it is not built again (it is the embedding's first cut mesh).
Embedding embed_on(const SurfaceMesh& mesh, const TraceMesh& tm, const Rig& rig, const EmbedOptions& options,
                   std::optional<CutMesh> uncut = std::nullopt);
} // namespace detail

} // namespace curvenet
