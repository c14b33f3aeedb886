#pragma once
/// \file deform.hpp
/// Binding a rig to a mesh, and deforming the mesh through the Curvenet.
///
/// Everything that does not depend on the pose is computed once, by bind():
/// the embedding, the constraints (every CutChain vertex, skinned with its
/// profile's interpolated node weights), the Laplacian of the cut mesh and
/// its factorisation, and from it, per input vertex, the harmonic joint
/// weights s_j = H(w_j) and the harmonic rest terms Y_j = H(w_j p). A frame
/// is then a sum over each vertex's joints, with no solve, no factorisation
/// and no allocation (docs/deform.md).

#include "curvenet/embed.hpp"
#include "curvenet/rig.hpp"
#include "curvenet/surface_mesh.hpp"
#include "curvenet/weights.hpp"

#include <memory>
#include <span>
#include <string>
#include <vector>

namespace curvenet {

class OutputFiles; // io.hpp

enum class LaplacianChoice { Uniform, IntrinsicDelaunay };
enum class RigidMode {
  /// Each vertex's detail moves with the harmonic blend of its joints'
  /// transforms, sum_j s_j A_j: linear in the joint matrices, exact at rest
  /// and for rigid poses, and it cannot pop.
  PerVertex,
  /// The thesis's mode: one rigid transform fitted (Horn) to the whole net,
  /// switched off when the fit is poor.
  Horn,
};

enum class DeformMethod {
  /// Each vertex blends its joints' transforms with the harmonic weights
  /// (linear in the joint matrices; docs/deform.md).
  Harmonic,
  /// Pixar's route: a deformation gradient per cut face, interpolated from
  /// the net with the cut-aware harmonic weights and kept a rotation (the
  /// polar factor of the blend) times a stretch, applied to the face's rest
  /// edges; then a Poisson solve for the positions with the CutChains pinned.
  Gradient,
  /// Each vertex blends its joints' rigid motions as dual quaternions, with
  /// the harmonic weights: the curves are posed by their own weights and
  /// keep their size, a twist turns instead of collapsing, and a bend keeps
  /// its volume, as dual-quaternion skinning does with the same weights.
  DualQuaternion,
};

/// "harmonic", "gradient" or "dq", as the front ends spell them.
const char* to_string(DeformMethod method);
/// The method spelled `name`; false when it is none of them.
bool parse_deform_method(const std::string& name, DeformMethod& method);

/// How the inside of a region is weighted between its curves.
enum class InteriorWeights {
  /// The harmonic extension of the curves' weights: a region blends the
  /// joints on its boundary, whatever bones pass through it.
  Harmonic,
  /// Bone heat (Blender's automatic weights) inside the region, corrected by
  /// the harmonic extension of how far the curves' weights differ from it: the
  /// curves keep their weights exactly, and a bone that bends inside a region
  /// with no ring of its own still bends the region there (docs/deform.md).
  BoneHeat,
};

/// "harmonic" or "bone-heat", as the front ends spell them.
const char* to_string(InteriorWeights interior);
/// The interior spelled `name`; false when it is neither.
bool parse_interior_weights(const std::string& name, InteriorWeights& interior);

struct BindOptions {
  DeformMethod method = DeformMethod::DualQuaternion;
  /// The dq mode: how a region's inside is weighted (the other modes use
  /// the harmonic extension).
  InteriorWeights interior = InteriorWeights::BoneHeat;
  /// Gradient mode: values per face corner, so the two sides of a curve may
  /// differ. Off, each vertex on a curve takes the average of its sides
  /// (only for showing what the cut-aware discretisation does).
  bool cut_aware = true;
  /// Gradient mode: a face's rotation from its joints' rotations, as the
  /// nearest rotation to their harmonic blend (polar), or as the normalised
  /// blend of their quaternions (docs/deform.md measures both).
  enum class RotationBlend { Polar, Quaternion } rotation_blend = RotationBlend::Polar;
  /// Gradient mode: also turn each curve side's frame to follow its posed
  /// curve (the smallest rotation from the joints' tangent to the curve's),
  /// interpolated over the surface per frame (3 more right-hand sides, about
  /// twice the frame time; docs/deform.md measures both).
  bool curve_frames = false;
  /// Gradient mode: targets that turn as cross-sections do about their
  /// bones (the blend's turn along each weight's gradient applied to the
  /// triangle's offset from its bone), so that twists and bends keep their
  /// sections. Uses the quaternion blend.
  bool sections = true;
  LaplacianChoice laplacian = LaplacianChoice::IntrinsicDelaunay;
  RigidMode rigid = RigidMode::PerVertex;
  AutoWeightOptions weights; ///< for nodes the rig gives no weights
  EmbedOptions embed;
  /// Horn mode: the fit is switched off when its RMS residual exceeds this
  /// fraction of the net's RMS spread.
  double horn_tolerance = 0.1;
};

struct BindReport {
  int vertices = 0;           ///< input (welded) vertices
  int constrained = 0;        ///< cut-mesh vertices on CutChains
  int free = 0;               ///< cut-mesh vertices solved for
  int rigid = 0;              ///< vertices of parts no profile touches
  int influences = 0;         ///< joint influences over all input vertices
  double mean_influences = 0; ///< per input vertex
  /// Edges of the cut mesh's Laplacian with a negative weight, before and
  /// after the intrinsic Delaunay flips. After them only boundary edges can
  /// stay negative (their one opposite angle is obtuse), and most boundary
  /// edges lie along the curves, between two constrained vertices, where a
  /// weight does not enter the solve: `negative_weights_solved` counts those
  /// with a vertex that is solved for, the ones that could break the
  /// maximum principle.
  int negative_weights_before = 0, negative_weights_after = 0, negative_weights_solved = 0, flips = 0;
  std::vector<std::pair<std::string, double>> timings_ms;
  std::vector<std::string> notes;
};

/// The report as JSON text: its counts, "timings_ms" (stage -> ms, in order)
/// and "notes".
std::string report_to_json(const BindReport& report);

class Binding {
public:
  struct Impl;
  explicit Binding(std::shared_ptr<const Impl> impl);

  /// The joints, in mesh space (the rig's bind matrices through its frame).
  [[nodiscard]] const std::vector<Joint>& joints() const;
  [[nodiscard]] const BindReport& report() const;
  /// The embedding it was made from. A binding read from a cache file has none.
  [[nodiscard]] bool has_embedding() const;
  [[nodiscard]] const Embedding& embedding() const;
  /// Node weights after completion (given, or automatic), by node id.
  [[nodiscard]] const std::map<std::string, std::map<std::string, double>>& node_weights() const;
  [[nodiscard]] int num_input_vertices() const;

  /// Deforms the mesh: `skinning` holds one matrix per joint (M_j = G_j B_j^-1
  /// in the rig's coordinates), `out` receives one position per vertex of the
  /// input file, in its order. Thread-safe; allocates nothing.
  /// \pre skinning.size() == joints().size(), out.size() == num_input_vertices().
  /// \throw Error when the sizes are not these.
  void deform(std::span<const Mat4> skinning, std::span<Eigen::Vector3d> out) const;

  /// Deforms many poses at once, in parallel (TBB): `skinning` holds
  /// frames x joints matrices, frame after frame, and `out` receives frames x
  /// vertices positions. Each frame is exactly what deform() gives for it.
  /// \throw Error when the sizes do not fit.
  void deform_frames(std::span<const Mat4> skinning, std::span<Eigen::Vector3d> out) const;

  /// The harmonic joint weights s_j = H(w_j) of one input vertex, as (joint
  /// index, weight) pairs with s_j > 0; they sum to 1 (docs/deform.md).
  void harmonic_weights(int input_vertex, std::vector<std::pair<int, double>>& out) const;

  /// Writes the binding to a cache file (atomically).
  /// \throw Error for a binding in the gradient mode, which is not cached.
  void save(const std::string& path) const;
  /// The cache file's bytes, as save() writes them; `path` names it in errors.
  [[nodiscard]] std::string cache_bytes(const std::string& path) const;
  [[nodiscard]] DeformMethod method() const;

private:
  friend Binding bind_cached(const SurfaceMesh&, const Rig&, const struct BindOptions&, const std::string&, bool*,
                             OutputFiles*);
  std::shared_ptr<const Impl> impl_;
};

/// Binds `rig` to `mesh`.
/// \throw EmbedError when the rig does not embed with ok.
/// \throw InputError when the rig has no skeleton, or its weights name joints it lacks.
Binding bind(const SurfaceMesh& mesh, const Rig& rig, const BindOptions& options = {});

/// A binding from a cache file, if the file was written for this mesh, rig
/// and options; otherwise bind() anew and write the cache. `reused` says
/// which happened. Given `outputs`, a new cache is added to that set of
/// files (io.hpp) and written when they are committed, with the command's
/// other outputs or not at all.
Binding bind_cached(const SurfaceMesh& mesh, const Rig& rig, const BindOptions& options, const std::string& cache_path,
                    bool* reused = nullptr, OutputFiles* outputs = nullptr);

/// The rig with every node's weights filled in (automatic weights where the
/// rig gives none), normalised.
Rig complete_weights(const Rig& rig, const AutoWeightOptions& options = {});

} // namespace curvenet
