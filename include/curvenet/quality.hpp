#pragma once
/// \file quality.hpp
/// How well a deformation keeps a character's shape, measured on the posed
/// mesh against its rest pose and its skeleton: volume, the sections across
/// a limb, growth away from the bones, self-intersection, turned triangles
/// and edge stretch (docs/deform.md, "Against the skins").

#include "curvenet/rig.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/surface_mesh.hpp"

#include <span>
#include <vector>

namespace curvenet {

struct QualityOptions {
  /// Chains of joints (indices into the skeleton, parent first) whose
  /// sections are measured: planes across each bone between consecutive
  /// joints, at the joints across the bisector.
  std::vector<std::vector<int>> limbs;
  int planes_per_bone = 24;
  /// Welded vertices whose growth away from the skeleton counts (empty: all).
  std::vector<char> bulge_vertices;
  /// Joints whose bones count for the growth (empty: all). A bone runs from
  /// a joint's parent to the joint.
  std::vector<char> bone_joints;
  /// A triangle is turned when its normal turns by more than this against
  /// its rest normal carried by its dominant joint's rotation.
  double turn_degrees = 90;
  /// Welded vertices whose mean-curvature normal counts for the detail
  /// change (empty: all).
  std::vector<char> detail_vertices;
};

struct DeformationQuality {
  double volume_change = 0; ///< posed / rest - 1
  /// Smallest posed / rest area of a section across a limb (1 when no limb is measured).
  double smallest_section = 1;
  /// Largest growth of a vertex's distance to the skeleton's bones, posed
  /// against rest, over the bounding-box diagonal.
  double bulge = 0;
  int self_intersections = 0; ///< pairs of triangles that share no vertex and intersect
  int turned = 0;
  double stretch_mean = 0, stretch_max = 0; ///< |length / rest length - 1| over the edges
  /// How much of the surface's detail changes: the mean over the counted
  /// vertices of |posed mean-curvature normal - the rest one turned by the
  /// vertex's dominant joint|, over the mean length of the rest one.
  double detail_change = 0;
};

/// Measures `posed` (one position per welded vertex of `mesh`) against the
/// mesh's rest positions. `joints` are the skeleton in the mesh's space,
/// `skinning` its matrices in the pose (M_j = G_j B_j^-1), and
/// `dominant_joint` each welded vertex's strongest joint, the same for every
/// deformation compared.
DeformationQuality measure_deformation(const SurfaceMesh& mesh, std::span<const Vec3> posed,
                                       const std::vector<Joint>& joints, std::span<const Mat4> skinning,
                                       std::span<const int> dominant_joint, const QualityOptions& options = {});

/// The triangles (polygons as fans) whose posed normal turns by more than
/// `degrees` against their rest normal carried by the rotation of their
/// dominant joint (of their corners', the one two share, or the first's):
/// where a deformation folds the surface over.
int turned_triangles(const SurfaceMesh& mesh, std::span<const Vec3> posed, std::span<const Mat4> skinning,
                     std::span<const int> dominant_joint, double degrees = 90);

/// The discrete mean-curvature normal H n at each welded vertex: the
/// cotangent Laplacian of the positions over twice the vertex's area (a
/// third of its triangles'), so 1/r long on a sphere of radius r, pointing
/// away from its centre. Zero at a vertex with no area.
std::vector<Vec3> mean_curvature_normals(const SurfaceMesh& mesh, std::span<const Vec3> positions);

/// Each welded vertex's strongest joint in a skinned file's own weights
/// (`skin` over the input vertices `mesh` was welded from).
std::vector<int> dominant_joints(const SurfaceMesh& mesh, const SkinnedMesh& skin);

/// Pairs of the mesh's triangles (polygons as fans) that share no vertex and
/// intersect, with the given welded positions. Exact: decided by orientation
/// predicates, not a tolerance.
int self_intersecting_pairs(const SurfaceMesh& mesh, std::span<const Vec3> positions);

/// The area of the smallest closed section around `point` of the plane
/// through it with normal `normal` (0 when no section winds around it).
double section_area(const SurfaceMesh& mesh, std::span<const Vec3> positions, const Vec3& point, const Vec3& normal);

} // namespace curvenet
