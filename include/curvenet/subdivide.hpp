#pragma once
/// \file subdivide.hpp
/// Catmull-Clark refinement of a control cage, and midpoint refinement of
/// any mesh (OpenSubdiv). A cage is not
/// the surface it stands for: its limit surface is. Refine a cage before
/// comparing it with a mesh of that surface; to transfer a rig to or from
/// the cage itself, see TransferOptions::target_cage_levels.

#include "curvenet/surface_mesh.hpp"

namespace curvenet {

/// The cage refined `levels` times (all quads after the first level).
/// Boundaries keep their edges (OpenSubdiv's "edge only" rule). The result's
/// `source` names the cage and the level.
/// \throw InputError when levels is not between 1 and 6, or when the result
///   would have more than 4 million faces (checked before it is made).
SurfaceMesh catmull_clark(const SurfaceMesh& cage, int levels, long long max_faces = 4'000'000);

/// The mesh refined `levels` times by midpoint subdivision (OpenSubdiv's
/// bilinear scheme): every n-gon split into n quads through its centroid
/// and its edges' midpoints, nothing moved. A triangle mesh keeps its
/// surface exactly, only finer: a rig bound to it and posed shows the
/// deformation between the original's vertices (a bent joint on a coarse
/// mesh is a chord across it). The result's `source` names the mesh and the level.
/// \throw InputError as catmull_clark() does.
SurfaceMesh midpoint_subdivide(const SurfaceMesh& mesh, int levels, long long max_faces = 4'000'000);

} // namespace curvenet
