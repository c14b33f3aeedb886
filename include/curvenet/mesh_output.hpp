#pragma once
/// \file mesh_output.hpp
/// Writing results on the input's own topology: the input file's faces,
/// vertex order and UVs, with normals recomputed from the new positions but
/// split where the input's normals were split; and point caches.

#include "curvenet/surface_mesh.hpp"

#include <span>
#include <string>
#include <vector>

namespace curvenet {

/// The input file's faces on its own vertices, with its per-corner UVs and
/// normal slots (OBJ: its `vt` and `vn` indices; glTF: one UV and one normal
/// per vertex; other formats: none).
struct InputTopology {
  RawMesh faces; ///< positions are the rest positions, faces as in the file
  std::vector<Eigen::Vector2d> uv;
  std::vector<int> corner_uv;     ///< per face corner, -1 for none
  std::vector<int> corner_normal; ///< per face corner, a normal slot
  int num_normals = 0;
  /// The file's own normals for the first slots (OBJ `vn`, glTF NORMAL),
  /// where it has them; the other slots have none.
  std::vector<Eigen::Vector3d> normals;
  std::vector<int> face_material; ///< glTF only: per face, its material index (-1 for none)
};

/// \throw InputError for an unreadable file.
InputTopology read_input_topology(const std::string& path);

/// OBJ text of the input topology at `positions` (one per input vertex),
/// each coordinate as the shortest text that reads back to it exactly.
std::string posed_obj(const InputTopology& topology, std::span<const Eigen::Vector3d> positions);

/// A PC2 point cache (Blender's Mesh Cache modifier): float32 positions of
/// `points` vertices for each of `frames` samples, starting at `start_frame`,
/// one sample per frame. `data` holds frames * points * 3 floats.
std::string pc2_cache(int points, int frames, float start_frame, const std::vector<float>& data);

/// The 32-byte header of a PC2 cache, for writing its frames as a stream.
std::string pc2_header(int points, int frames, float start_frame);

} // namespace curvenet
