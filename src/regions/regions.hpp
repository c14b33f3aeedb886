#pragma once
// Stage "regions": flood fill of the cut mesh that never crosses a CutChain
// edge, the outside of a local net, region identities and preview colours.

#include "curvenet/embed.hpp"
#include "cut/cut_mesh.hpp"

#include <string>
#include <vector>

namespace curvenet::detail {

struct RegionResult {
  std::vector<int> face_region; ///< per cut face: region index, or -1 outside a local net
  std::vector<RegionInfo> regions;
  int outside_faces = 0;
};

/// Partitions the cut faces. With local coverage the outside is not a
/// region: on an open mesh component, every piece that reaches the mesh
/// boundary; on a closed one, the piece of largest area.
/// `face_component` gives the mesh component of each input face.
RegionResult find_regions(const CutMesh& mesh, const std::vector<std::string>& profile_ids, Coverage coverage,
                          const std::vector<int>& face_component);

/// Greedy graph colouring (largest degree first): adjacent entries get
/// different colours. Returns a colour index per node of the graph.
std::vector<int> colour_graph(const std::vector<std::vector<int>>& adjacency);

/// An RGB colour for a colour index: a fixed palette, then golden-ratio hues.
std::array<int, 3> palette_colour(int index);

} // namespace curvenet::detail
