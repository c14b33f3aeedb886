#pragma once
// The one place for numerical tolerances. Each is relative and is scaled by
// the model's bounding-box diagonal, so a hand in metres and a tube in
// centimetres behave the same. Combinatorial decisions never use these: they
// use the exact predicates in predicates.hpp.

namespace curvenet::detail {

struct Tolerances {
  /// A node closer than this to a mesh vertex or edge is placed on it, so that
  /// no sliver face of near-zero area is cut next to it.
  static constexpr double node_snap_rel = 1e-7;
  /// Two corners of a degenerate face (one the loader leaves out) closer
  /// than this are welded into one vertex: an exporter that rewrites a
  /// face's corners in single precision leaves "two corners at one point"
  /// a few units in the last place apart, and kept apart they leave a slit.
  static constexpr double degenerate_weld_rel = 1e-6;
  /// Boundary vertices of an open mesh closer than this to another boundary
  /// vertex are welded to it where that closes the seam: a file whose
  /// primitives were quantized one by one (Draco's 14 bits over each
  /// primitive's box) writes a seam's two copies up to about 6e-5 apart.
  static constexpr double seam_weld_rel = 1e-4;
  /// Walking the surface between two samples stops with an error when the
  /// path grows longer than this many times the straight distance plus a few
  /// mean edge lengths (the walk has left the intended part of the surface).
  static constexpr double walk_length_factor = 8.0;
  static constexpr double walk_length_edges = 4.0;

  /// A point on an edge within this fraction of the edge's length of one of
  /// its ends is taken to be that end: a path that crosses an edge this close
  /// to a vertex goes through the vertex. Without it the cut would hold
  /// slivers too thin for the angle order around their corners to mean
  /// anything. The path's topology stays valid either way.
  static constexpr double crossing_min_param = 1e-6;

  /// A CutChain may stray from its drawn curve, placed on the surface, by
  /// at most this much (symmetric Hausdorff distance). Where a walk strays
  /// further the tracer refines; a chain still over it is refused.
  static constexpr double fidelity_rel = 1e-3;
  /// Two profiles closer than this (away from a shared node) are refused as
  /// touching; above it, the tracer refines them apart however fine the mesh.
  static constexpr double floor_rel = 1e-6;
  /// How many times a piece between two samples may be halved.
  static constexpr int refine_depth = 16;
  /// How many times the cut may be redone after two profiles that met were
  /// traced more closely.
  static constexpr int cut_rounds = 8;

  /// A chain that would leave a bent polygon's layout passes over its
  /// diagonals instead, no nearer either end of a diagonal than this
  /// fraction of its length (the straight chord meets the diagonal's line
  /// beyond a reflex corner; the chain passes that corner this close).
  static constexpr double detour_margin = 0.01;

  /// A matrix whose smallest singular value is at most this fraction of its
  /// largest is singular (bind matrices, frames, inverse bind matrices).
  static constexpr double invertible_rel = 1e-12;
  /// No such matrix scales by more than this, or less than its inverse (a
  /// scale of 1e200 overflows the moment two are multiplied).
  static constexpr double max_matrix_scale = 1e9;
  /// A cotangent weight (dimensionless) within this of zero is zero: a
  /// right angle's cotangent is 1e-16, not negative; only a weight below
  /// -this is flipped away or counted as negative.
  static constexpr double cot_weight_zero = 1e-12;
  /// An embedding takes coordinates up to this, and sizes down to its
  /// inverse: an orientation predicate multiplies three coordinates, and
  /// squared tolerances multiply further (1e150 cubed is past a double, and
  /// a mesh 1e-86 across lost its cut to underflow). Generated scales from
  /// 1e-200 to 1e200 check the range (fuzz_test).
  static constexpr double max_coordinate = 1e40;
  /// A rig's frame is a similarity when M^T M = s^2 I to this relative error.
  static constexpr double similarity_rel = 1e-6;

  /// A node placed farther than this (relative to the diagonal) from where
  /// the rig puts it is refused: the rig is for another mesh, or scale.
  static constexpr double max_node_offset_rel = 0.25;
  /// A rig whose nodes span less than this fraction of the mesh's diagonal
  /// is refused: it is in other units (a rig in metres on a mesh in
  /// centimetres spans 0.01; one made for the mesh spans at least a limb).
  static constexpr double min_rig_extent_rel = 1e-3;

  /// Whether a vertex sees a bone (bone heat, bind/bone_heat.hpp): the
  /// segment from it to the bone must cross no triangle past this first
  /// stretch, which leaves out the triangles the vertex itself lies on.
  static constexpr double visibility_skip_rel = 1e-4;

  /// Two skeletons line up their meshes (transfer's Alignment::Skeletons)
  /// when, after the best similarity, no joint lies farther than this from
  /// its match: exports of one rig agree to float precision; another rig,
  /// or a skeleton posed away from its bind, is refused.
  static constexpr double skeleton_fit_rel = 1e-3;

  /// A plane section passes over a box of triangles only when the box lies
  /// off the plane by more than this fraction of its reach from the plane's
  /// origin: a bound on rounding, a million times over, so no triangle the
  /// plane crosses is missed; each vertex's side is still decided exactly.
  static constexpr double plane_prune_rel = 1e-9;

  double diagonal = 1.0;
  [[nodiscard]] double node_snap() const { return node_snap_rel * diagonal; }
  [[nodiscard]] double fidelity() const { return fidelity_rel * diagonal; }
  [[nodiscard]] double floor() const { return floor_rel * diagonal; }

  static Tolerances for_model(double bbox_diagonal) {
    Tolerances t;
    t.diagonal = bbox_diagonal > 0 ? bbox_diagonal : 1.0;
    return t;
  }
};

} // namespace curvenet::detail
