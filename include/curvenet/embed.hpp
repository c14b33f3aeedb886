#pragma once
/// \file embed.hpp
/// Embedding a Curvenet in a mesh: sample the profiles, place them on the
/// surface, cut the mesh along them, and partition it into regions.

#include "curvenet/rig.hpp"
#include "curvenet/surface_mesh.hpp"

#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace curvenet {

struct EmbedOptions {
  /// Samples per local edge length of the target mesh (the thesis's rho):
  /// samples lie at most h / density apart, h the mean edge length of the
  /// triangle under the sample. The points the rigger placed are always
  /// samples; the tracer adds midpoints where a walk strays.
  double density = 5.0;
  /// The mesh is a control cage that stands for its limit surface (transfer
  /// to or from a cage): its faces are not the surface the curves were
  /// placed on, so the chains run straight inside them, and their fidelity
  /// is measured and reported but not enforced.
  bool cage = false;
  /// Embeddings estimated to need more profile samples than this (length
  /// times density over the mean edge length) are refused before they start.
  long long max_samples = 20'000'000;
  /// Overrides the rig's coverage when set.
  std::optional<Coverage> coverage;
  /// Called with a stage name and the fraction done, for progress display:
  /// one call at a time, from the calling thread or a worker, with each
  /// stage's fraction going up.
  std::function<void(std::string_view stage, double fraction)> progress;
};

/// One region of the partition. Its identity does not depend on the mesh:
/// the sorted set of (profile id, side) pairs on its boundary, where side is
/// 'L' when the region lies left of the profile's direction (seen from
/// outside the surface) and 'R' when it lies right of it.
struct RegionInfo {
  std::vector<std::pair<std::string, char>> boundary;
  int faces = 0;                         ///< cut-mesh faces
  double area = 0;                       ///< surface area
  int colour = 0;                        ///< preview colour index; adjacent regions differ
  [[nodiscard]] std::string key() const; ///< "a:L|b:R", or "" for no boundary
};

struct EmbedReport {
  bool ok = false;
  Coverage coverage = Coverage::Full; ///< the mode used (never Auto)
  int logical_nodes = 0;
  int profiles = 0;
  int components = 0;        ///< connected components of the net (C)
  int mesh_components = 0;   ///< connected components of the mesh
  int closed_components = 0; ///< closed ones among them (K)
  int regions = 0;
  std::optional<int> expected_regions; ///< empty on a surface of higher genus
  int mapped_faces = 0;                ///< cut-mesh faces that belong to a region
  int unmapped_faces = 0;              ///< cut-mesh faces in no region and not outside
  int outside_faces = 0;               ///< local coverage: faces outside the net
  int physical_nodes = 0;              ///< node vertices in the cut mesh
  int cut_vertices = 0;
  int cut_faces = 0;
  int input_vertices = 0;
  int input_faces = 0;
  int samples = 0;     ///< profile samples placed on the surface
  int crossings = 0;   ///< edge crossings and vertex hits cut into the mesh
  int refinements = 0; ///< curve midpoints the tracer added where a walk strayed or failed
  int cut_rounds = 0;  ///< extra cuts after two profiles were traced more closely where they came close
  /// Faces a profile runs straight across because its placed curve folds
  /// there (it crossed itself; the fold is not measured for fidelity).
  int unfolded_faces = 0;
  /// How far each CutChain strays from its drawn curve placed on the
  /// surface (symmetric Hausdorff distance, mesh units), per profile in rig
  /// order, and the largest; the tolerance is 1e-3 of the bounding-box diagonal.
  std::vector<std::pair<std::string, double>> fidelity;
  double fidelity_max = 0;
  double fidelity_tolerance = 0;
  bool fidelity_enforced = true; ///< false on a cage (EmbedOptions::cage)
  double diagonal = 0;           ///< the mesh's bounding-box diagonal, which the tolerances scale with
  std::vector<std::pair<std::string, double>> timings_ms; ///< one entry per stage
  std::vector<std::string> problems;                      ///< why ok is false, one line each
  std::vector<std::string> notes;                         ///< repairs and remarks
  std::vector<RegionInfo> region_list;
};

/// The report as JSON text (see docs/cli.md for the keys).
std::string report_to_json(const EmbedReport& report);

/// The result of embedding one rig in one mesh. Cheap to copy (shared).
class Embedding {
public:
  struct Impl;
  explicit Embedding(std::shared_ptr<const Impl> impl);

  [[nodiscard]] const EmbedReport& report() const;
  /// The cut mesh as OBJ: polygons, plus one `l` polyline per CutChain.
  [[nodiscard]] std::string cut_mesh_obj() const;
  /// The same at other positions, one per cut-mesh vertex (a posed cut mesh).
  /// \throw Error when the count is wrong or a position is not finite.
  [[nodiscard]] std::string cut_mesh_obj(std::span<const Vec3> positions) const;
  /// The cut mesh as a surface mesh: the input's surface with every curve
  /// along its edges, its vertices in cut-mesh order. Bound to the same rig
  /// and posed, it shows the curves' shape between a coarse mesh's vertices.
  [[nodiscard]] SurfaceMesh cut_surface() const;
  /// The cut mesh as ASCII PLY with one colour per face, graph-coloured by region.
  [[nodiscard]] std::string regions_ply() const;
  /// Region index of each cut-mesh face: -1 outside a local net.
  [[nodiscard]] const std::vector<int>& face_regions() const;
  /// The cut mesh's polygons, for drawing: its faces are face_regions()'s.
  [[nodiscard]] RawMesh cut_mesh() const;
  /// Each profile's CutChain as points, in rig order, by profile id.
  [[nodiscard]] std::vector<std::pair<std::string, std::vector<Vec3>>> chains() const;
  /// The preview colour (RGB, 0-255) of a cut-mesh face: its region's, grey outside.
  [[nodiscard]] std::array<int, 3> face_colour(int face) const;
  [[nodiscard]] const Impl& impl() const { return *impl_; }
  [[nodiscard]] bool has_impl() const { return impl_ != nullptr; }

private:
  std::shared_ptr<const Impl> impl_;
};

/// Embeds `rig` in `mesh`.
/// \throw EmbedError when a profile cannot be placed on the surface, or when
///   two profiles cross away from a node (the message names both).
/// \note A completed embedding whose region count is wrong is not an error:
///   its report has ok == false and lists the problems.
Embedding embed(const SurfaceMesh& mesh, const Rig& rig, const EmbedOptions& options = {});

/// Places the nodes and traces every profile on the surface, without
/// cutting: per profile in rig order, the path its cut will follow (for
/// drawing a net while it is edited).
/// \throw EmbedError as embed() does when a node or profile cannot be placed.
std::vector<std::vector<Vec3>> trace_profiles(const SurfaceMesh& mesh, const Rig& rig,
                                              const EmbedOptions& options = {});

} // namespace curvenet
