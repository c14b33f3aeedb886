#pragma once
/// \file layer.hpp
/// Curvenet as a layer (docs/deform.md, "Layered over a skin"). The base is
/// the mesh moved by its own skin (linear or dual-quaternion skinning with
/// the file's weights), or by the net's own deformation. The correction
/// takes the base surface's cut chains to the net's posed curves, and to
/// their nodes' offsets where a pose gives them. It spreads that
/// displacement over each region the curves bound, as the harmonic
/// extension of its values on the chains (the cut mesh's Laplacian, the
/// chains held). The correction is scaled by an envelope (per frame) and a
/// mask (per vertex). Envelope 0, or mask 0, gives the base exactly.

#include "curvenet/deform.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"

#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace curvenet {

struct LayerOptions {
  /// How the net is bound: its method also poses the curves (dq: the
  /// chains' weights blended as dual quaternions; harmonic: linearly).
  BindOptions bind;
  /// The base: the mesh's own skin (`skin` given to bind_layer), or the
  /// net's deformation (no skin): then only node offsets correct it.
  Skinning skinning = Skinning::Linear;
  /// Per input vertex, 0 to 1: how much of the correction it takes (empty:
  /// all of it). A region left out of the correction is masked with 0.
  std::vector<double> mask;
  /// Over a linear skin with the curves posed linearly (`bind.method`
  /// harmonic), solve the correction once per joint at bind time, so that a
  /// frame is a skin-like sum over joints instead of a solve (the same
  /// result, to rounding). Off: solve every frame, as the other cases do.
  bool precompute_linear = true;
};

class CurveLayer {
public:
  struct Impl;
  explicit CurveLayer(std::shared_ptr<const Impl> impl);

  /// The joints, in mesh space: the order of the skinning matrices.
  [[nodiscard]] const std::vector<Joint>& joints() const;
  [[nodiscard]] int num_input_vertices() const;
  /// The net's binding (its embedding, its report).
  [[nodiscard]] const Binding& binding() const;
  [[nodiscard]] bool over_skin() const;
  /// The base's weights of an input vertex, as (joint, weight) pairs: the
  /// skin's (over a skin), or the net's harmonic weights.
  void base_weights(int input_vertex, std::vector<std::pair<int, double>>& out) const;

  /// The same layer (sharing its binding and solver) with another mask:
  /// one value from 0 to 1 per input vertex, or none (all of the
  /// correction). Cheap: a vertex group edited in a tool is a new mask, not
  /// a new binding.
  /// \throw InputError as bind_layer() does for a bad mask.
  [[nodiscard]] CurveLayer with_mask(std::vector<double> mask) const;
  /// The mask, per input vertex (empty: 1 everywhere).
  [[nodiscard]] std::span<const double> mask() const;
  /// A mask by region (for with_mask): each region named by its key (as
  /// EmbedReport::region_list gives it, "profile:L|profile:R") takes its
  /// value, from 0 to 1, and every other region `others`. A vertex takes the
  /// largest value of the regions around it, so the curves between a masked
  /// region and an open one still follow the net. With a `falloff` (a
  /// fraction of the bounding-box diagonal), a region's value rises towards
  /// a larger one across its curves smoothly over that distance along the
  /// surface, inside the region with the smaller value; beyond it every
  /// vertex has its region's value exactly.
  /// \throw InputError naming a key no region has, or a value outside [0, 1].
  [[nodiscard]] std::vector<double> region_mask(const std::map<std::string, double>& values, double others = 1,
                                                double falloff = 0) const;

  /// The base moved by `skinning` (one matrix per joint, as Binding::deform
  /// takes them), plus `envelope` times the masked correction. Output in
  /// the input file's vertex order. Thread-safe.
  /// \throw Error for wrong sizes; InputError naming a node of `offsets`
  ///   that the rig lacks.
  void deform(std::span<const Mat4> skinning, std::span<Vec3> out, double envelope = 1,
              const NodeOffsets* offsets = nullptr) const;
  /// The posed cut mesh (Embedding::cut_surface's vertices): the base
  /// surface at each cut vertex, corrected. Over a skin, its chain vertices
  /// lie on the posed curves, and their nodes' offsets, at envelope 1; over
  /// the net's own deformation they lie on the posed curves at any envelope
  /// (the harmonic extension takes the chords between the posed input
  /// vertices to the curves), and on their offsets at envelope 1. So on a
  /// coarse mesh, whose own vertices make a bent curve a chord, the cut mesh
  /// shows the curve's shape. The mask, per input vertex, does not apply.
  void deform_cut(std::span<const Mat4> skinning, std::vector<Vec3>& cut, double envelope = 1,
                  const NodeOffsets* offsets = nullptr) const;
  /// Over a skin: the displacement `out` (one per input vertex, in rest
  /// space) such that the skin moves `rest + out` to what deform() gives.
  /// So a tool whose own skinning comes after it (Blender's Armature
  /// modifier after a shape key) plays the layer: the skin's blend is affine
  /// in the rest position at each vertex, and its linear part is inverted.
  /// \throw Error when the layer is not over a skin.
  void rest_correction(std::span<const Mat4> skinning, std::span<Vec3> out, double envelope = 1,
                       const NodeOffsets* offsets = nullptr) const;
  /// Many frames at once, in parallel: frames x joints matrices, frames x
  /// vertices positions; each frame exactly what deform() gives.
  void deform_frames(std::span<const Mat4> skinning, std::span<Vec3> out, double envelope = 1) const;

private:
  void deform_impl(std::span<const Mat4> skinning, std::span<Vec3> out, double envelope, const NodeOffsets* offsets,
                   std::vector<Vec3>* cut) const;
  void linear_frame(std::span<const Mat4> skinning, std::span<Vec3> out, double envelope) const;
  std::shared_ptr<const Impl> impl_;
  std::shared_ptr<const std::vector<double>> mask_; ///< per input vertex; null: 1
};

/// Binds `rig` to `mesh` as a layer over `skin` (the mesh file's own skin,
/// per file vertex), or over the net's own deformation when `skin` is null.
/// \throw InputError naming the skin file when a joint its weights use is
///   missing from the rig's skeleton, or has another bind matrix there; or
///   when the mask does not have one finite value in [0, 1] per input
///   vertex. \throw EmbedError as bind() does.
/// Over the net's own deformation (no skin), `bound` may give the binding
/// of `rig` on `mesh` made with `options.bind`, with its embedding, to use
/// instead of binding again.
CurveLayer bind_layer(const SurfaceMesh& mesh, const Rig& rig, const SkinnedMesh* skin,
                      const LayerOptions& options = {}, const Binding* bound = nullptr);

} // namespace curvenet
