#pragma once
// Stage "project and trace": place a profile's samples on the surface and
// walk the surface between consecutive samples, so that the edge crossings
// come out ordered and connected by construction.

#include "core/tolerances.hpp"
#include "trace/trace_mesh.hpp"

#include <string>
#include <vector>

namespace curvenet::detail {

/// One point of a traced profile: a node, an input vertex the path runs
/// through, or a crossing of an input edge. Consecutive points always share
/// an input face (or an input edge).
struct PathPoint {
  SurfacePoint at;
  int node = -1;  ///< rig node index for the two end points
  int sample = 0; ///< the sample the walk was heading to (for messages)
};

struct TracedProfile {
  std::vector<PathPoint> points; ///< first and last are the profile's nodes
  int samples = 0;
};

/// Places a node on the surface: its closest point, moved onto a vertex or
/// an edge when it lies within Tolerances::node_snap() of one.
SurfacePoint place_node(const TraceMesh& mesh, const Vec3& p, const Tolerances& tol);

struct TraceInput {
  std::string profile_id;
  std::vector<Vec3> samples; ///< first and last are ignored: the nodes stand there
  SurfacePoint from, to;
  int from_node = -1, to_node = -1;
};

/// Traces one profile.
/// \throw EmbedError naming the profile, the sample and the face or edge
///   where the walk failed (it reached the mesh boundary, or wandered much
///   further than the samples are apart: the projection jumped).
TracedProfile trace_profile(const TraceMesh& mesh, const TraceInput& input, double mean_edge, const Tolerances& tol);

} // namespace curvenet::detail
