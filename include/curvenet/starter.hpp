#pragma once
/// \file starter.hpp
/// A starter Curvenet from a skeleton: a ring around the limb at every joint
/// (a plane section local to the joint's bones, moved along the bone past a
/// fork), profiles along each chain between its rings, and joins on both
/// sides where chains branch. The result is a rig file a rigger then edits.

#include "curvenet/rig.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/surface_mesh.hpp"
#include "curvenet/weights.hpp"

#include <functional>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace curvenet {

struct StarterOptions {
  int nodes_per_ring = 4;
  /// Rings per bone: one at the bone's end joint, and rings_per_bone - 1
  /// more spread along the bone.
  int rings_per_bone = 1;
  /// With the mesh's skin (`skin`): a node at the middle of each profile
  /// along a bone and of each arc of a ring (docs/starter.md, step 8),
  /// which takes the skin's weights where it lies. The weights of a
  /// profile's curve are interpolated between its end nodes, so without it
  /// the middle of a bone moves with the joints at both ends where the skin
  /// moves it with one. Without a skin there is nothing to sample there,
  /// and none is made.
  bool middle_nodes = true;
  /// The net's coverage: Auto is full on a closed mesh and local on an open
  /// one (with a message saying so); the rig written says which.
  Coverage coverage = Coverage::Auto;
  /// Angle of node 0 from its ring's reference direction (carried from the
  /// parent ring; a ring with none starts from its chain root's local X
  /// axis), about the bone, in degrees.
  double first_angle_deg = 0;
  AutoWeightOptions weights;
  /// Rings closer than this fraction of the smaller one's radius are too
  /// close: the larger is moved along its bone, or dropped when it cannot
  /// move clear. Profiles that share no node keep half of it (at most
  /// 0.75 % of the bounding-box diagonal, on thick bodies).
  double ring_gap = 0.25;
  std::function<void(const std::string&)> message; ///< what was moved, dropped or not joined
  /// The joints that carry skin weight (by name), when the skeleton comes
  /// with a skin; empty: every joint may. Only joints that carry weight and
  /// lie inside the mesh, or have descendants that do, are rigged: IK pole
  /// targets, helper bones and a root on the floor are left out, and a
  /// second root (an IK chain of its own) is attached to the joint it
  /// lies nearest to.
  std::set<std::string> deforming;
  /// The mesh's own skin, when it has one (not owned; per vertex of the
  /// file the mesh was read from, read_raw_mesh's order). Each node then
  /// takes the skin's weights where it lies on the surface, interpolated
  /// over the face it lies in, so the net poses its curves as the skin
  /// poses the surface there; `weights` gives the rest (a node where the
  /// skin weights no joint of the skeleton). Weights under 1 % are dropped.
  const SkinnedMesh* skin = nullptr;
};

struct StarterResult {
  Rig rig;
  std::vector<std::string> messages;
  int rings = 0;
  int joins = 0;          ///< branch joins made
  int unjoined = 0;       ///< chains that could not be joined to their parent
  int net_components = 0; ///< connected components of the net
  /// Joints with no ring of their own, each with the reason (joints left
  /// out of the net among them: "carries no skin weight", "lies outside the mesh").
  std::vector<std::pair<std::string, std::string>> ringless;
};

/// Builds a starter net on `mesh` for the skeleton `joints` (bind matrices in
/// the mesh's object space). The net embeds on `mesh` with ok, which is
/// checked before the result is returned.
/// \throw InputError when the skeleton lies outside the mesh (no plane
///   through a joint cuts a loop around it).
/// \throw EmbedError when no net could be made to embed.
/// \throw InputError when `options.skin` has another vertex count than the mesh's file.
StarterResult make_starter(const SurfaceMesh& mesh, const std::vector<Joint>& joints,
                           const StarterOptions& options = {});

} // namespace curvenet
