#pragma once
// Stage "cut": insert the nodes, split the crossed edges in order along each
// edge, then split every crossed face along its profile segments. Builds one
// CutChain per profile.

#include "curvenet/errors.hpp"
#include "cut/cut_mesh.hpp"
#include "trace/tracer.hpp"

#include <functional>
#include <string>
#include <vector>

namespace curvenet::detail {

/// The physical representation of one profile: its ordered cut vertices and
/// the half-edges between them, all running in the profile's direction.
struct CutChain {
  std::vector<Vertex> vertices;    ///< #halfedges + 1
  std::vector<Halfedge> halfedges; ///< to(h[i]) == from(h[i+1])
  std::vector<int> point;          ///< per vertex: the index of its path point in the trace
};

struct CutInput {
  std::vector<std::string> node_ids;
  std::vector<SurfacePoint> node_points;
  std::vector<std::string> profile_ids;
  std::vector<int> profile_from, profile_to; ///< node indices
  std::vector<TracedProfile> traces;
};

/// Two profiles (or one profile with itself) that cross or touch in the cut,
/// away from a node: the embedding may trace them more closely and cut again.
class ProfilesMeet : public EmbedError {
public:
  ProfilesMeet(const std::string& what, int first, int second, const Eigen::Vector3d& at, std::string place,
               int face = -1)
      : EmbedError(what), first(first), second(second), face(face), at(at), place(std::move(place)) {}
  int first, second;  ///< profile indices (equal for a profile that meets itself)
  int face;           ///< the input face where two chords cross, or -1 (at a vertex or along an edge)
  Eigen::Vector3d at; ///< where, in mesh space
  std::string place;  ///< "input face 12", "input vertex 7", "input edge 3-4"
};

struct CutResult {
  std::vector<CutChain> chains;    ///< one per profile
  std::vector<Vertex> node_vertex; ///< per node; invalid for a node no profile uses
  int crossings = 0;
};

/// Cuts `mesh` (fresh from CutMesh::from_surface) along the traced profiles.
/// `after_mutation`, when set, is called after every topological edit (tests
/// use it to run the validator).
/// Path points inside a face (samples) become vertices of the cut, so a
/// chain follows its curve through the face.
/// \throw ProfilesMeet when two profiles cross or touch away from a node, or
///   run along the same edge, naming both profiles and the face or edge.
/// \throw EmbedError for other faults of a path (a node passed through).
CutResult cut_mesh(CutMesh& mesh, const TraceMesh& trace, const CutInput& input,
                   const std::function<void()>& after_mutation = {});

/// Checks every CutChain against the mesh: continuity, endpoints at the
/// node vertices, tags that name the chain's profile. Returns the first
/// fault, or nothing.
std::optional<std::string> validate_chains(const CutMesh& mesh, const CutInput& input, const CutResult& cut);

} // namespace curvenet::detail
