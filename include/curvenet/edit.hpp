#pragma once
/// \file edit.hpp
/// Editing a net: the net editor's operations on the logical rig (the
/// add-on's editor is a thin layer over these). Each takes a rig and returns
/// the edited copy, which passes validate_rig(). A request that names no such
/// node or profile, or whose result would break a rule of the rig format,
/// throws InputError naming `source` and the node or profile; the input rig
/// is never changed.
///
/// Curves the edit changes become polylines with their ends on their nodes:
/// a polyline keeps its points, a Bezier or NURBS curve is sampled densely.

#include "curvenet/rig.hpp"

#include <string>
#include <vector>

namespace curvenet {

/// Removes the nodes, every profile through them, and their weights.
Rig remove_nodes(const Rig& rig, const std::vector<std::string>& nodes, const std::string& source = "rig");

/// Removes the profiles. A node that was an end of one of them and is left
/// on no profile goes too, with its weights.
Rig remove_profiles(const Rig& rig, const std::vector<std::string>& profiles, const std::string& source = "rig");

/// Moves a node. The curves through it follow: each end's displacement
/// fades linearly along the curve's arc length, as the engine moves a
/// curve's ends onto its nodes, and is written into the curve.
Rig move_node(const Rig& rig, const std::string& node, const Eigen::Vector3d& position,
              const std::string& source = "rig");

struct SplitResult {
  Rig rig;
  std::string node;    ///< the new node, on the curve
  std::string profile; ///< the new profile, from the new node to the old profile's end
};

/// Inserts a node on a profile at normalised arc length t in (0, 1) of its
/// curve (ends on its nodes). The profile keeps its id and ends at the new
/// node; a new profile continues to the old end. When either end has
/// weights, the new node gets both ends' complete weights interpolated at t,
/// as the binding interpolates them along the profile, so the deformation
/// along the curve is unchanged.
SplitResult split_profile(const Rig& rig, const std::string& profile, double t, const std::string& source = "rig");

/// The normalised arc length of the point of a profile's curve (ends on its
/// nodes) nearest to `point`.
double nearest_parameter(const Rig& rig, const std::string& profile, const Eigen::Vector3d& point,
                         const std::string& source = "rig");

/// Merges node `merged` into node `kept`: profiles between the two go, the
/// other profiles of `merged` end at `kept` (their curves follow, as in
/// move_node), and `merged` and its weights go.
Rig merge_nodes(const Rig& rig, const std::string& kept, const std::string& merged,
                const std::string& source = "rig");

/// Routes a profile anew: its curve becomes the polyline from its first
/// node through `via` to its last node.
Rig reroute_profile(const Rig& rig, const std::string& profile, const std::vector<Eigen::Vector3d>& via,
                    const std::string& source = "rig");

/// Sets `joint`'s weight on each node to `weight` in [0, 1] and scales the
/// node's other joints so that its weights still sum to 1 (the thesis's
/// sparse weight editor). A node without weights starts from its automatic
/// ones (complete_weights). A weight below 1 on a node with no other joint
/// leaves the joint at 1: there is nothing to give the rest to.
Rig set_joint_weight(const Rig& rig, const std::vector<std::string>& nodes, const std::string& joint,
                     double weight, const std::string& source = "rig");

} // namespace curvenet
