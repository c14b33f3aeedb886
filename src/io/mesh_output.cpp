#include "curvenet/mesh_output.hpp"

#include "core/numbers.hpp"

#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "io/file_bytes.hpp"
#include "io/gltf_scene.hpp"
#include "io/obj_read.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <sstream>

namespace curvenet {

InputTopology read_input_topology(const std::string& path) {
  const std::string ext = detail::lower_extension(path);
  InputTopology out;
  if (ext == ".obj") {
    const auto obj = detail::parse_obj(path); // the parse load_mesh made, if it read this file
    out.faces.positions = obj->positions;
    out.faces.face_offsets = obj->face_offsets;
    out.faces.face_vertices = obj->corner_vertex;
    out.uv = obj->texcoords;
    out.corner_uv = obj->corner_texcoord;
    // Corners with a normal keep its slot; corners without one share a slot
    // per vertex, after the file's own normals.
    out.normals = obj->normals;
    out.num_normals = static_cast<int>(obj->normals.size());
    std::vector<int> vertex_slot(obj->positions.size(), -1);
    out.corner_normal.reserve(obj->corner_normal.size());
    for (size_t k = 0; k < obj->corner_normal.size(); ++k) {
      if (obj->corner_normal[k] >= 0) {
        out.corner_normal.push_back(obj->corner_normal[k]);
      } else {
        int& slot = vertex_slot[obj->corner_vertex[k]];
        if (slot < 0)
          slot = out.num_normals++;
        out.corner_normal.push_back(slot);
      }
    }
    return out;
  }
  if (ext == ".gltf" || ext == ".glb") {
    const detail::GltfScene scene = detail::read_gltf_scene(path);
    out.faces = scene.mesh;
    out.uv = scene.uv;
    out.normals = scene.normal;
    out.face_material = scene.face_material;
    out.num_normals = static_cast<int>(out.faces.positions.size());
    for (int v : out.faces.face_vertices) {
      out.corner_uv.push_back(out.uv.empty() ? -1 : v);
      out.corner_normal.push_back(v);
    }
    return out;
  }
  out.faces = read_raw_mesh(path);
  out.num_normals = static_cast<int>(out.faces.positions.size());
  for (int v : out.faces.face_vertices) {
    out.corner_uv.push_back(-1);
    out.corner_normal.push_back(v);
  }
  return out;
}

std::string posed_obj(const InputTopology& t, std::span<const Eigen::Vector3d> positions) {
  const RawMesh& f = t.faces;
  for (size_t v = 0; v < positions.size(); ++v)
    if (!positions[v].allFinite())
      throw Error("the posed vertex " + std::to_string(v) +
                  " is not finite (the pose scales or moves the mesh out of range); nothing was written");
  // Normals: area-weighted face normals summed into each normal slot, from
  // the positions scaled to the unit box (a direction does not depend on the
  // scale, and products of coordinates near 1e200 would overflow).
  double extent = 0;
  for (const auto& p : positions)
    extent = std::max(extent, p.cwiseAbs().maxCoeff());
  const double unit = extent > 0 ? 1 / extent : 1;
  std::vector<Eigen::Vector3d> normals(t.num_normals, Eigen::Vector3d::Zero());
  for (size_t face = 0; face + 1 < f.face_offsets.size(); ++face) {
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    const int b = f.face_offsets[face], e = f.face_offsets[face + 1];
    for (int k = b; k < e; ++k)
      n += (unit * positions[f.face_vertices[k]]).cross(unit * positions[f.face_vertices[k + 1 < e ? k + 1 : b]]);
    for (int k = b; k < e; ++k)
      normals[t.corner_normal[k]] += n;
  }
  std::string out = "# curvenet: posed on the input's topology\n";
  out.reserve(64 * (positions.size() + normals.size()) + 24 * f.face_vertices.size());
  auto triple = [&](const char* tag, const Eigen::Vector3d& p) {
    out += tag;
    for (int c = 0; c < 3; ++c) {
      out += ' ';
      detail::append_number(out, p[c]);
    }
    out += '\n';
  };
  for (const auto& p : positions)
    triple("v", p);
  for (const auto& uv : t.uv) {
    out += "vt ";
    detail::append_number(out, uv.x());
    out += ' ';
    detail::append_number(out, uv.y());
    out += '\n';
  }
  for (auto n : normals) {
    if (n.norm() > 0)
      n.normalize();
    if (!n.allFinite())
      throw Error("a normal of the posed mesh is not finite; nothing was written");
    triple("vn", n);
  }
  for (size_t face = 0; face + 1 < f.face_offsets.size(); ++face) {
    out += 'f';
    for (int k = f.face_offsets[face]; k < f.face_offsets[face + 1]; ++k) {
      out += ' ';
      detail::append_number(out, f.face_vertices[k] + 1);
      out += '/';
      if (t.corner_uv[k] >= 0)
        detail::append_number(out, t.corner_uv[k] + 1);
      out += '/';
      detail::append_number(out, t.corner_normal[k] + 1);
    }
    out += '\n';
  }
  return out;
}

std::string pc2_header(int points, int frames, float start_frame) {
  if (!std::isfinite(start_frame))
    throw Error("the point cache's start frame is not a finite number; nothing was written");
  std::string out(32, '\0');
  char* p = out.data();
  std::memcpy(p, "POINTCACHE2\0", 12);
  const int32_t version = 1, n = points, samples = frames;
  const float rate = 1.0f;
  std::memcpy(p + 12, &version, 4);
  std::memcpy(p + 16, &n, 4);
  std::memcpy(p + 20, &start_frame, 4);
  std::memcpy(p + 24, &rate, 4);
  std::memcpy(p + 28, &samples, 4);
  return out;
}

std::string pc2_cache(int points, int frames, float start_frame, const std::vector<float>& data) {
  for (size_t i = 0; i < data.size(); ++i)
    if (!std::isfinite(data[i]))
      throw Error("frame " + std::to_string(i / (3 * static_cast<size_t>(std::max(points, 1)))) +
                  " of the cache has a position that is not finite in single precision (the pose scales or moves "
                  "the mesh out of range); nothing was written");
  std::string out = pc2_header(points, frames, start_frame);
  out.resize(32 + data.size() * sizeof(float));
  std::memcpy(out.data() + 32, data.data(), data.size() * sizeof(float));
  return out;
}

} // namespace curvenet
