#pragma once
// The gradient mode (docs/deform.md): per cut face a deformation gradient,
// interpolated over the surface from the net's constraints with the
// cut-aware harmonic weights and kept a rotation (polar projection of the
// blend), times a stretch; applied to the face's rest edges, then a Poisson
// solve for the positions, with the CutChains pinned where the net puts them.

#include "curvenet/rig.hpp"
#include "core/dual_quaternion.hpp"
#include "cut/cut_mesh.hpp"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace curvenet::detail {

/// How a face's rotation is taken from the blend of its joints' rotations.
enum class RotationBlend {
  Polar,      ///< the nearest rotation to the blended matrix (its polar factor)
  Quaternion, ///< the normalised blend of the joints' quaternions (hemisphere-aligned)
};

struct GradientBind {
  int num_cut_vertices = 0;
  RotationBlend rotation = RotationBlend::Polar;
  // Per cut face: the joints and weights its gradient blends (CSR), and a
  // rest stretch U (identity unless the rig gives its profiles' sides scales).
  std::vector<int> face_corner_offset, face_corner; ///< per cut face, its corners' vertices (CSR)
  std::vector<int> face_offset, face_joint;
  std::vector<double> face_weight;
  std::vector<Eigen::Matrix3d> face_stretch;
  bool stretched = false;
  // The Poisson energy: sum over triangle edges of w |(x_j - x_i) - F_t e|^2,
  // the triangles those of each cut face's ear clipping.
  struct Edge {
    int i, j, tri;
    double w;
    Eigen::Vector3d e; ///< rest X_j - X_i
  };
  std::vector<Edge> edges;
  std::vector<int> tri_face; ///< per triangle, its cut face
  // Sections: per triangle, the offset r of its centroid from the nearest
  // bone, and the gradient of each of its face's joint weights (one per
  // entry of face_joint, CSR by tri_grad_offset). A triangle's target then
  // turns with the blend as a cross-section does about its own axis:
  // F_t = R S + sum_j (w_j x R r) grad s_j^T, w_j the turn of the blend per unit of s_j.
  bool sections = false;
  std::vector<Eigen::Vector3d> tri_offset;
  std::vector<int> tri_grad_offset;
  std::vector<Eigen::Vector3d> tri_grad;
  // Unknowns: every cut vertex that is neither on a CutChain nor in a rigid part.
  std::vector<int> unknown; ///< per cut vertex, its unknown index or -1
  int num_unknowns = 0;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  // Pinned vertices (CutChains): LBS of their constraint weights (CSR); rigid ones: one joint.
  std::vector<int> pin_offset, pin_joint;
  std::vector<double> pin_weight;
  std::vector<Eigen::Vector3d> rest; ///< per cut vertex
  // Curve frames: per CutChain vertex between two others of one chain, its
  // neighbours along the chain and its rest tangent; the harmonic system that
  // carries their turn over the surface (free unknowns, constraint entries).
  struct FrameSample {
    int vertex, prev, next;
    Eigen::Vector3d tangent; ///< rest, unit
  };
  std::vector<FrameSample> frames;
  std::vector<int> sample_of; ///< per cut vertex, its frame sample or -1
  std::shared_ptr<const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>> harmonic;
  std::vector<int> harmonic_index;                         ///< per cut vertex, free unknown or -1
  std::vector<std::vector<std::pair<int, double>>> harmonic_fc; ///< free unknown -> (cut vertex, L entry)
};

/// What the binding has computed that the gradient mode builds on.
struct GradientInput {
  const CutMesh* cut = nullptr;
  const std::vector<int>* face_region = nullptr;           ///< per cut face
  const std::vector<std::vector<Vertex>>* chain_vertices = nullptr;
  const std::vector<std::string>* profile_ids = nullptr;
  const std::vector<char>* constrained = nullptr;          ///< per cut vertex
  const std::vector<std::map<int, double>>* constraint_weights = nullptr; ///< per cut vertex
  const std::vector<int>* free_index = nullptr;            ///< per cut vertex, harmonic unknowns
  const std::vector<int>* rigid_joint = nullptr;           ///< per cut vertex, -1 unless in a rigid part
  const std::vector<Eigen::VectorXd>* harmonic = nullptr;  ///< per joint, s_j per free index (may be empty)
  /// The harmonic solve's factorisation and its constraint entries, for
  /// interpolating the sides' stretch.
  std::shared_ptr<const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>> harmonic_solver;
  const std::vector<std::vector<std::pair<int, double>>>* harmonic_fc = nullptr;
  const std::vector<int>* free_vertices = nullptr;
  /// Profile id -> width scale of its left and right side (rig extension x_side_scales).
  std::map<std::string, std::pair<double, double>> side_scales;
  /// Values per face corner, so the two sides of a curve may differ (false:
  /// one value per vertex, the average of its sides: for comparison only).
  bool cut_aware = true;
  RotationBlend rotation = RotationBlend::Polar;
  bool curve_frames = true;
  /// Targets that turn like cross-sections about their bones (the blend's
  /// derivative along the weights' gradient), so that twists and bends are
  /// compatible; needs `joints` (mesh space) and the quaternion blend.
  bool sections = false;
  const std::vector<Joint>* joints = nullptr;
};

std::shared_ptr<const GradientBind> build_gradient(const GradientInput& in);

/// Positions of every cut vertex for the skinning matrices. Allocates only
/// the first time a thread deforms this binding.
void deform_gradient(const GradientBind& g, std::span<const Mat4> skinning, std::span<Eigen::Vector3d> cut_out);

/// Reads the rig extension x_side_scales: {"profile id": [left, right], ...}.
std::map<std::string, std::pair<double, double>> side_scales_of(const Rig& rig);

} // namespace curvenet::detail
