// Mesh readers. OBJ goes through tinyobjloader (it keeps the file's vertex
// order), glTF/GLB through tinygltf (exact accessors), and PLY, OFF and FBX
// through assimp. Validation and welding happen in make_surface_mesh.

#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <tiny_gltf.h>
#include <tiny_obj_loader.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <unistd.h>

namespace curvenet {
namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

RawMesh read_obj(const std::string& path) {
  tinyobj::ObjReaderConfig config;
  config.triangulate = false;
  config.vertex_color = false;
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path, config)) {
    std::string msg = reader.Error();
    while (!msg.empty() && std::isspace(static_cast<unsigned char>(msg.back())))
      msg.pop_back();
    throw InputError(path, "", "cannot read OBJ: " + (msg.empty() ? std::string("unknown error") : msg));
  }
  const auto& attrib = reader.GetAttrib();
  RawMesh raw;
  const size_t nv = attrib.vertices.size() / 3;
  raw.positions.reserve(nv);
  for (size_t v = 0; v < nv; ++v)
    raw.positions.emplace_back(attrib.vertices[3 * v], attrib.vertices[3 * v + 1], attrib.vertices[3 * v + 2]);
  std::vector<int> corners;
  for (const auto& shape : reader.GetShapes()) {
    size_t k = 0;
    for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
      const int n = shape.mesh.num_face_vertices[f];
      corners.clear();
      for (int i = 0; i < n; ++i)
        corners.push_back(shape.mesh.indices[k + i].vertex_index);
      k += n;
      raw.add_face(corners);
    }
  }
  return raw;
}

// ---- glTF ----------------------------------------------------------------

bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true; // textures are not needed
}

Eigen::Matrix4d node_local_matrix(const tinygltf::Node& node) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  if (node.matrix.size() == 16) {
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        m(r, c) = node.matrix[4 * c + r]; // column-major in glTF
    return m;
  }
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  if (node.translation.size() == 3)
    t.translate(Eigen::Vector3d(node.translation[0], node.translation[1], node.translation[2]));
  if (node.rotation.size() == 4)
    t.rotate(Eigen::Quaterniond(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]).normalized());
  if (node.scale.size() == 3)
    t.scale(Eigen::Vector3d(node.scale[0], node.scale[1], node.scale[2]));
  return t.matrix();
}

/// Reads `count` components of accessor `a` element `i` as doubles.
struct AccessorReader {
  const tinygltf::Model& model;
  const tinygltf::Accessor& acc;
  const std::string& path;
  const unsigned char* base = nullptr;
  size_t stride = 0;
  int ncomp = 0;

  AccessorReader(const tinygltf::Model& m, int index, const std::string& p, const std::string& what)
      : model(m), acc(m.accessors.at(index)), path(p) {
    if (acc.sparse.isSparse)
      throw InputError(path, what, "sparse accessors are not supported");
    if (acc.bufferView < 0 || acc.bufferView >= static_cast<int>(m.bufferViews.size()))
      throw InputError(path, what, "accessor has no buffer view");
    const auto& view = m.bufferViews[acc.bufferView];
    const auto& buf = m.buffers.at(view.buffer);
    ncomp = tinygltf::GetNumComponentsInType(acc.type);
    const int csize = tinygltf::GetComponentSizeInBytes(acc.componentType);
    if (ncomp <= 0 || csize <= 0)
      throw InputError(path, what, "accessor has an unknown type");
    stride = acc.ByteStride(view) > 0 ? static_cast<size_t>(acc.ByteStride(view)) : static_cast<size_t>(ncomp * csize);
    const size_t start = view.byteOffset + acc.byteOffset;
    const size_t need = acc.count == 0 ? 0 : start + stride * (acc.count - 1) + static_cast<size_t>(ncomp * csize);
    if (need > buf.data.size())
      throw InputError(path, what, "accessor reads past the end of its buffer");
    base = buf.data.data() + start;
  }

  [[nodiscard]] double get(size_t i, int c) const {
    const unsigned char* p = base + i * stride;
    switch (acc.componentType) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float v;
      std::memcpy(&v, p + 4 * c, 4);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_DOUBLE: {
      double v;
      std::memcpy(&v, p + 8 * c, 8);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return p[c];
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p + 2 * c, 2);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
      uint32_t v;
      std::memcpy(&v, p + 4 * c, 4);
      return v;
    }
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return static_cast<int8_t>(p[c]);
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p + 2 * c, 2);
      return v;
    }
    default:
      throw InputError(path, "", "unsupported accessor component type");
    }
  }
};

void append_primitive(const tinygltf::Model& model, const tinygltf::Primitive& prim, const Eigen::Matrix4d& world,
                      const std::string& path, const std::string& what, RawMesh& raw) {
  auto it = prim.attributes.find("POSITION");
  if (it == prim.attributes.end())
    return;
  const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
  if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN)
    return; // points and lines carry no surface
  AccessorReader pos(model, it->second, path, what + " POSITION");
  if (pos.ncomp != 3)
    throw InputError(path, what, "POSITION is not a VEC3");
  const int base = static_cast<int>(raw.positions.size());
  for (size_t i = 0; i < pos.acc.count; ++i) {
    Eigen::Vector4d p(pos.get(i, 0), pos.get(i, 1), pos.get(i, 2), 1.0);
    raw.positions.push_back((world * p).head<3>());
  }
  std::vector<int> idx;
  if (prim.indices >= 0) {
    AccessorReader ind(model, prim.indices, path, what + " indices");
    for (size_t i = 0; i < ind.acc.count; ++i) {
      const double v = ind.get(i, 0);
      if (v >= static_cast<double>(pos.acc.count))
        throw InputError(path, what + " index " + std::to_string(i),
                         "refers to vertex " + std::to_string(static_cast<long>(v)) + " of " +
                             std::to_string(pos.acc.count));
      idx.push_back(static_cast<int>(v));
    }
  } else {
    for (size_t i = 0; i < pos.acc.count; ++i)
      idx.push_back(static_cast<int>(i));
  }
  const bool mirrored = world.topLeftCorner<3, 3>().determinant() < 0;
  auto tri = [&](int a, int b, int c) {
    std::array<int, 3> t{base + a, base + b, base + c};
    if (mirrored)
      std::swap(t[1], t[2]);
    raw.add_face(t);
  };
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    if (idx.size() % 3 != 0)
      throw InputError(path, what, "index count is not a multiple of 3");
    for (size_t i = 0; i + 2 < idx.size(); i += 3)
      tri(idx[i], idx[i + 1], idx[i + 2]);
  } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
    for (size_t i = 0; i + 2 < idx.size(); ++i)
      (i % 2 == 0) ? tri(idx[i], idx[i + 1], idx[i + 2]) : tri(idx[i + 1], idx[i], idx[i + 2]);
  } else {
    for (size_t i = 1; i + 1 < idx.size(); ++i)
      tri(idx[0], idx[i], idx[i + 1]);
  }
}

RawMesh read_gltf(const std::string& path, bool binary) {
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&skip_image, nullptr);
  tinygltf::Model model;
  std::string err, warn;
  const bool ok = binary ? loader.LoadBinaryFromFile(&model, &err, &warn, path)
                         : loader.LoadASCIIFromFile(&model, &err, &warn, path);
  if (!ok) {
    while (!err.empty() && std::isspace(static_cast<unsigned char>(err.back())))
      err.pop_back();
    throw InputError(path, "", "cannot read glTF: " + (err.empty() ? std::string("unknown error") : err));
  }
  RawMesh raw;
  // Walk the default scene (or every root when there is none). A skinned
  // mesh's node transform is ignored, as glTF requires: its vertices stay in
  // the mesh's object space, which is where rigs are authored.
  std::vector<int> roots;
  const int scene = model.defaultScene >= 0 ? model.defaultScene : (model.scenes.empty() ? -1 : 0);
  if (scene >= 0) {
    roots = model.scenes[scene].nodes;
  } else {
    std::vector<char> child(model.nodes.size(), 0);
    for (const auto& n : model.nodes)
      for (int c : n.children)
        child.at(c) = 1;
    for (size_t i = 0; i < model.nodes.size(); ++i)
      if (!child[i])
        roots.push_back(static_cast<int>(i));
  }
  std::vector<std::pair<int, Eigen::Matrix4d>> stack;
  for (auto it = roots.rbegin(); it != roots.rend(); ++it)
    stack.emplace_back(*it, Eigen::Matrix4d::Identity());
  int guard = 0;
  while (!stack.empty()) {
    auto [ni, parent] = stack.back();
    stack.pop_back();
    if (ni < 0 || ni >= static_cast<int>(model.nodes.size()) || ++guard > 1000000)
      throw InputError(path, "node " + std::to_string(ni), "invalid node hierarchy");
    const auto& node = model.nodes[ni];
    const Eigen::Matrix4d world = parent * node_local_matrix(node);
    if (node.mesh >= 0) {
      const Eigen::Matrix4d m = node.skin >= 0 ? Eigen::Matrix4d::Identity() : world;
      const auto& mesh = model.meshes.at(node.mesh);
      for (size_t p = 0; p < mesh.primitives.size(); ++p)
        append_primitive(model, mesh.primitives[p], m, path, "mesh '" + mesh.name + "' primitive " + std::to_string(p),
                         raw);
    }
    for (auto it = node.children.rbegin(); it != node.children.rend(); ++it)
      stack.emplace_back(*it, world);
  }
  if (raw.positions.empty())
    throw InputError(path, "", "the glTF scene holds no triangle mesh");
  return raw;
}

// ---- assimp --------------------------------------------------------------

RawMesh read_assimp(const std::string& path) {
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(path, aiProcess_JoinIdenticalVertices);
  if (!scene || !scene->mRootNode || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE))
    throw InputError(path, "", std::string("cannot read mesh: ") + importer.GetErrorString());
  RawMesh raw;
  std::vector<std::pair<const aiNode*, aiMatrix4x4>> stack{{scene->mRootNode, aiMatrix4x4()}};
  std::vector<int> corners;
  while (!stack.empty()) {
    auto [node, parent] = stack.back();
    stack.pop_back();
    const aiMatrix4x4 world = parent * node->mTransformation;
    const bool mirrored = world.Determinant() < 0;
    for (unsigned m = 0; m < node->mNumMeshes; ++m) {
      const aiMesh* mesh = scene->mMeshes[node->mMeshes[m]];
      const int base = static_cast<int>(raw.positions.size());
      for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
        const aiVector3D p = world * mesh->mVertices[v];
        raw.positions.emplace_back(p.x, p.y, p.z);
      }
      for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
        const aiFace& face = mesh->mFaces[f];
        if (face.mNumIndices < 3)
          continue; // points and lines
        corners.clear();
        for (unsigned k = 0; k < face.mNumIndices; ++k)
          corners.push_back(base + static_cast<int>(face.mIndices[k]));
        if (mirrored)
          std::reverse(corners.begin(), corners.end());
        raw.add_face(corners);
      }
    }
    for (unsigned c = node->mNumChildren; c-- > 0;)
      stack.emplace_back(node->mChildren[c], world);
  }
  if (raw.positions.empty())
    throw InputError(path, "", "the file holds no polygon mesh");
  return raw;
}

} // namespace

RawMesh read_raw_mesh(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(path, "", "no such file");
  std::ifstream probe(path, std::ios::binary);
  if (!probe)
    throw InputError(path, "", "cannot open the file for reading");
  const std::string ext = lower_extension(path);
  if (ext == ".obj")
    return read_obj(path);
  if (ext == ".gltf")
    return read_gltf(path, false);
  if (ext == ".glb")
    return read_gltf(path, true);
  if (ext == ".ply" || ext == ".off" || ext == ".fbx")
    return read_assimp(path);
  throw InputError(path, "", "unknown mesh format '" + ext + "' (expected .obj, .ply, .off, .gltf, .glb or .fbx)");
}

SurfaceMesh load_mesh(const std::string& path) {
  return make_surface_mesh(read_raw_mesh(path), path);
}

std::string mesh_to_obj(const std::vector<Vec3>& positions, const std::vector<int>& face_offsets,
                        const std::vector<int>& face_vertices) {
  std::ostringstream out;
  out << std::setprecision(17);
  for (const auto& p : positions)
    out << "v " << p.x() << ' ' << p.y() << ' ' << p.z() << '\n';
  for (size_t f = 0; f + 1 < face_offsets.size(); ++f) {
    out << 'f';
    for (int k = face_offsets[f]; k < face_offsets[f + 1]; ++k)
      out << ' ' << face_vertices[k] + 1;
    out << '\n';
  }
  return out.str();
}

void write_file_atomic(const std::string& path, const std::string& contents) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  if (target.has_parent_path()) {
    std::error_code ec;
    fs::create_directories(target.parent_path(), ec);
  }
  const fs::path tmp = target.string() + ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out)
      throw Error(path + ": cannot open for writing");
    out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
    out.flush();
    if (!out) {
      out.close();
      std::error_code ec;
      fs::remove(tmp, ec);
      throw Error(path + ": write failed");
    }
  }
  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw Error(path + ": cannot move the finished file into place");
  }
}

} // namespace curvenet
