#pragma once
// Stage "project and trace": place a profile's samples on the surface and
// walk the surface between consecutive samples, so that the edge crossings
// come out ordered and connected by construction.

#include "core/tolerances.hpp"
#include "sample/sampling.hpp"
#include "trace/trace_mesh.hpp"

#include <string>
#include <vector>

namespace curvenet::detail {

/// One point of a traced profile: a node, an input vertex the path runs
/// through, or a crossing of an input edge. Consecutive points always share
/// an input face (or an input edge).
struct PathPoint {
  SurfacePoint at;
  int node = -1;         ///< rig node index for the two end points
  int sample = 0;        ///< the sample the walk was heading to (for messages)
  int piece = 0;         ///< the walk that placed it: increases along the path
  bool on_curve = false; ///< a sample or midpoint of the curve, not a crossing
  /// The path reaches this point straight across a face where the placed
  /// curve folds (TraceInput::unfold_faces): the segment that ends here is
  /// not measured against the curve.
  bool unmeasured = false;
};

/// A point of the drawn curve placed on the surface (its closest point),
/// for measuring how far the traced path strays from the curve.
struct ReferencePoint {
  Vec3 pos;
  int sample = 0;    ///< the sample it is, or the one after it for a point between samples
  int piece = 0;     ///< the walk that ends at it, or whose midpoint it is
  bool skip = false; ///< in a face where the placed curve folds: not measured
};

struct TracedProfile {
  std::vector<PathPoint> points; ///< first and last are the profile's nodes
  int samples = 0;
  /// The curve as placed on the surface: every sample, and the curve's
  /// midpoint between each two, in order along the profile.
  std::vector<ReferencePoint> reference;
  int refinements = 0; ///< midpoints inserted because a walk strayed or failed
  /// Walks across a jump of the placed curve: where the closest-point
  /// placement of a curve that lies off the surface jumps (across a concave
  /// crease), however finely it is sampled. The walk bridges the jump along
  /// the surface, and the bridge is not measured against the curve.
  std::vector<int> jumps;
};

/// Places a node on the surface: its closest point, moved onto a vertex or
/// an edge when it lies within Tolerances::node_snap() of one.
SurfacePoint place_node(const TraceMesh& mesh, const Vec3& p, const Tolerances& tol);

/// A ball inside which a profile must follow its curve more closely than
/// its tolerance (set where two profiles come close together).
struct Tightening {
  Vec3 centre = Vec3::Zero();
  double radius = 0;
  double tolerance = 0;
};

struct TraceInput {
  std::string profile_id;
  const ProfileCurve* curve = nullptr; ///< the drawn curve, for refinement
  std::vector<Vec3> samples;           ///< first and last are ignored: the nodes stand there
  std::vector<double> t;               ///< each sample's normalised arc length on `curve`
  SurfacePoint from, to;
  int from_node = -1, to_node = -1;
  /// How far a traced piece may stray from the curve placed on the surface.
  double tolerance = 0;
  std::vector<Tightening> tighter;
  /// Input faces where the placed curve folds onto itself (the profile's
  /// chain crossed itself there): the path keeps no samples inside them and
  /// runs straight across, and the curve there is not measured.
  std::vector<int> unfold_faces;
  /// False on a control cage: no samples are kept inside any face, and a
  /// walk that strays is not redone (only one that fails).
  bool inside_faces = true;
};

/// Traces one profile. Between each two consecutive samples the walk's
/// piece is compared with the curve placed on the surface there (the two
/// samples and the curve's own midpoint between them); a piece that strays
/// further than the tolerance, or a walk that fails, is redone through the
/// midpoint, as two walks (docs/embedding.md).
/// \throw EmbedError naming the profile, the sample and the face or edge
///   where the walk failed (it reached the mesh boundary, or wandered much
///   further than the samples are apart: the projection jumped).
TracedProfile trace_profile(const TraceMesh& mesh, const TraceInput& input, double mean_edge, const Tolerances& tol);

} // namespace curvenet::detail
