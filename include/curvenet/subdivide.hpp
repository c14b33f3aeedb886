#pragma once
/// \file subdivide.hpp
/// Catmull-Clark refinement of a control cage (OpenSubdiv). A cage is not
/// the surface it stands for: its limit surface is. Refine a cage before
/// comparing it with a mesh of that surface; to transfer a rig to or from
/// the cage itself, see TransferOptions::target_cage_levels.

#include "curvenet/surface_mesh.hpp"

namespace curvenet {

/// The cage refined `levels` times (all quads after the first level).
/// Boundaries keep their edges (OpenSubdiv's "edge only" rule). The result's
/// `source` names the cage and the level.
/// \throw InputError when levels is not between 1 and 6, or when the result
///   would have more than 20 million faces (checked before it is made).
SurfaceMesh catmull_clark(const SurfaceMesh& cage, int levels, long long max_faces = 20'000'000);

} // namespace curvenet
