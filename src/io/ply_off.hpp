#pragma once
// Readers of our own for PLY and OFF (see ply_off.cpp for why).

#include "curvenet/surface_mesh.hpp"

#include <string>

namespace curvenet::detail {

/// PLY, ASCII or binary of either byte order: the vertex element's x, y, z
/// and the face element's vertex_indices (or vertex_index); other elements
/// and properties are read past. Vertices keep the file's order.
/// \throw InputError naming the file and the header line, element or record.
RawMesh read_ply(const std::string& path);

/// OFF (also COFF, NOFF: the extra values on a line are skipped).
/// \throw InputError naming the file and the vertex or face.
RawMesh read_off(const std::string& path);

} // namespace curvenet::detail
