#pragma once
// Procedural test and demo data: a capped tube at any tessellation, and the
// thesis's tube net (14 nodes, 28 profiles, 16 regions on a closed tube).

#include "curvenet/rig.hpp"
#include "curvenet/surface_mesh.hpp"

namespace curvenet {

struct TubeSpec {
  double radius = 1.0;
  double length = 4.0;      ///< along +y, from y = 0
  int around = 16;          ///< vertices per ring
  int along = 16;           ///< side rows
  int cap_rings = 4;        ///< rings on each cap, the centre included
  bool triangulate = false; ///< split every quad (alternating diagonals)
};

/// A closed capped tube: quads (or triangles) on the side and the caps,
/// a triangle fan around each cap's centre vertex. Outward orientation.
RawMesh make_capped_tube(const TubeSpec& spec);

struct TubeNetSpec {
  double radius = 1.0;
  double length = 4.0;
  std::vector<double> ring_heights{0.6, 2.1, 3.4}; ///< at least 1, increasing
  int nodes_per_ring = 4;
  double first_angle_deg = 30.0;                        ///< angle of node 0 on each ring
  Eigen::Vector3d cap_offset = Eigen::Vector3d::Zero(); ///< moves both cap nodes off the axis
  int points_per_profile = 24;
};

/// The thesis's full-coverage tube net: three rings of four nodes, four
/// profiles along the side between consecutive rings, and four spokes on
/// each cap from a centre node to the nearest ring. V = 14, E = 28, so
/// F = 2 - V + E = 16 regions. Profiles are polylines on the exact cylinder.
/// Includes a three-joint skeleton along the axis. With R rings of N nodes
/// (spec), V = R N + 2 and E = R N + (R - 1) N + 2 N.
Rig make_tube_net(const TubeNetSpec& spec = {});

/// A chain of joints along the tube's axis, at the given heights (bind:
/// translations only), named j0, j1, ...
std::vector<Joint> make_tube_skeleton(const std::vector<double>& heights);

} // namespace curvenet
