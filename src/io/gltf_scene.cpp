#include "io/gltf_scene.hpp"

#include "core/matrix_checks.hpp"
#include "curvenet/errors.hpp"
#include "io/file_bytes.hpp"
#include "io/json_text.hpp"

#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <optional>
#include <sstream>

namespace curvenet::detail {
namespace {

bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int, void*) {
  return true; // textures are not needed
}

/// Reads the elements of an accessor as doubles (normalised integers scaled to [0, 1]).
struct AccessorReader {
  const tinygltf::Accessor& acc;
  const unsigned char* base = nullptr;
  size_t stride = 0;
  int ncomp = 0;

  AccessorReader(const tinygltf::Model& m, int index, const std::string& path, const std::string& what)
      : acc(m.accessors.at(index)) {
    if (acc.sparse.isSparse)
      throw InputError(path, what, "sparse accessors are not supported");
    if (acc.bufferView < 0 || acc.bufferView >= static_cast<int>(m.bufferViews.size()))
      throw InputError(path, what, "accessor has no buffer view");
    const auto& view = m.bufferViews[acc.bufferView];
    if (view.buffer < 0 || view.buffer >= static_cast<int>(m.buffers.size()))
      throw InputError(path, what, "buffer view " + std::to_string(acc.bufferView) + " has no buffer");
    const auto& buf = m.buffers[view.buffer];
    ncomp = tinygltf::GetNumComponentsInType(acc.type);
    const int csize = tinygltf::GetComponentSizeInBytes(acc.componentType);
    if (ncomp <= 0 || csize <= 0)
      throw InputError(path, what, "accessor has an unknown type");
    const size_t element = static_cast<size_t>(ncomp) * static_cast<size_t>(csize);
    const int byte_stride = acc.ByteStride(view);
    if (byte_stride < 0)
      throw InputError(path, what, "buffer view has an invalid byteStride");
    stride = byte_stride > 0 ? static_cast<size_t>(byte_stride) : element;
    // Bounds without overflow: the view within its buffer, the accessor
    // within its view, every element within the accessor's part of it.
    const size_t buffer_size = buf.data.size();
    if (view.byteOffset > buffer_size || view.byteLength > buffer_size - view.byteOffset)
      throw InputError(path, what,
                       "buffer view " + std::to_string(acc.bufferView) + " reaches past the end of buffer " +
                           std::to_string(view.buffer));
    if (acc.byteOffset > view.byteLength)
      throw InputError(path, what, "accessor starts past the end of its buffer view");
    const size_t room = view.byteLength - acc.byteOffset;
    if (acc.count > 0 && (element > room || (acc.count - 1) > (room - element) / stride))
      throw InputError(path, what,
                       "accessor of " + std::to_string(acc.count) + " elements reads past the end of its buffer view");
    base = buf.data.data() + view.byteOffset + acc.byteOffset;
  }

  [[nodiscard]] size_t count() const { return acc.count; }

  [[nodiscard]] double get(size_t i, int c) const {
    const unsigned char* p = base + i * stride;
    auto load = [&](auto v, int size) {
      std::memcpy(&v, p + size * c, size);
      return v;
    };
    const bool norm = acc.normalized;
    switch (acc.componentType) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return load(float{}, 4);
    case TINYGLTF_COMPONENT_TYPE_DOUBLE:
      return load(double{}, 8);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return norm ? p[c] / 255.0 : p[c];
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return norm ? load(uint16_t{}, 2) / 65535.0 : load(uint16_t{}, 2);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return load(uint32_t{}, 4);
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return norm ? std::max(static_cast<int8_t>(p[c]) / 127.0, -1.0) : static_cast<int8_t>(p[c]);
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return norm ? std::max(load(int16_t{}, 2) / 32767.0, -1.0) : load(int16_t{}, 2);
    default:
      return 0;
    }
  }
};

struct Trs {
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Quaterniond r = Eigen::Quaterniond::Identity();
  Eigen::Vector3d s = Eigen::Vector3d::Ones();
  bool has_matrix = false;
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();

  [[nodiscard]] Eigen::Matrix4d matrix() const {
    if (has_matrix)
      return m;
    Eigen::Affine3d a = Eigen::Affine3d::Identity();
    a.translate(t);
    a.rotate(r.normalized());
    a.scale(s);
    return a.matrix();
  }
};

Trs rest_trs(const tinygltf::Node& node) {
  Trs x;
  if (node.matrix.size() == 16) {
    x.has_matrix = true;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        x.m(r, c) = node.matrix[4 * c + r]; // column-major in glTF
    return x;
  }
  if (node.translation.size() == 3)
    x.t = {node.translation[0], node.translation[1], node.translation[2]};
  if (node.rotation.size() == 4)
    x.r = Eigen::Quaterniond(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
  if (node.scale.size() == 3)
    x.s = {node.scale[0], node.scale[1], node.scale[2]};
  return x;
}

/// The per-vertex attributes of a primitive's `count` vertices read at
/// `base`: texture coordinates, normals and skin influences.
void read_vertex_attributes(const tinygltf::Model& model, const tinygltf::Primitive& prim, const Eigen::Matrix4d& world,
                            const std::string& path, const std::string& what, bool skinned, int base, size_t count,
                            GltfScene& scene) {
  const RawMesh& raw = scene.mesh;
  // Skin influences (JOINTS_0 / WEIGHTS_0), when this primitive is skinned.
  scene.vertex_joint.resize(raw.positions.size(), {-1, -1, -1, -1});
  scene.vertex_weight.resize(raw.positions.size(), {0, 0, 0, 0});
  if (auto uvs = prim.attributes.find("TEXCOORD_0"); uvs != prim.attributes.end()) {
    AccessorReader uv(model, uvs->second, path, what + " TEXCOORD_0");
    if (uv.count() == count && uv.ncomp == 2) {
      scene.uv.resize(base, Eigen::Vector2d::Zero());
      for (size_t i = 0; i < uv.count(); ++i) {
        scene.uv.emplace_back(uv.get(i, 0), 1.0 - uv.get(i, 1)); // glTF's v runs down, OBJ's up
        if (!scene.uv.back().allFinite()) // it would be written out (OBJ vt, the bake's TEXCOORD_0)
          throw InputError(path, what + " TEXCOORD_0 " + std::to_string(i), "is not a finite number");
      }
    }
  }
  if (!scene.uv.empty())
    scene.uv.resize(raw.positions.size(), Eigen::Vector2d::Zero());
  if (auto ns = prim.attributes.find("NORMAL"); ns != prim.attributes.end()) {
    AccessorReader nr(model, ns->second, path, what + " NORMAL");
    if (nr.count() == count && nr.ncomp == 3) {
      scene.normal.resize(base, Eigen::Vector3d::Zero());
      const Eigen::Matrix3d to_world = world.topLeftCorner<3, 3>().inverse().transpose();
      for (size_t i = 0; i < nr.count(); ++i) {
        const Eigen::Vector3d n = to_world * Eigen::Vector3d(nr.get(i, 0), nr.get(i, 1), nr.get(i, 2));
        scene.normal.push_back(n.allFinite() && n.norm() > 0 ? n.normalized() : Eigen::Vector3d::Zero());
      }
    }
  }
  if (!scene.normal.empty())
    scene.normal.resize(raw.positions.size(), Eigen::Vector3d::Zero());
  auto jt = prim.attributes.find("JOINTS_0"), wt = prim.attributes.find("WEIGHTS_0");
  if (skinned && jt != prim.attributes.end() && wt != prim.attributes.end()) {
    AccessorReader joints(model, jt->second, path, what + " JOINTS_0");
    AccessorReader weights(model, wt->second, path, what + " WEIGHTS_0");
    if (joints.count() != count || weights.count() != count || joints.ncomp != 4 || weights.ncomp != 4)
      throw InputError(path, what, "JOINTS_0 and WEIGHTS_0 must be VEC4 with one entry per vertex");
    for (size_t i = 0; i < count; ++i)
      for (int k = 0; k < 4; ++k) {
        const double w = weights.get(i, k);
        scene.vertex_joint[base + i][k] = w > 0 ? static_cast<int>(joints.get(i, k)) : -1;
        scene.vertex_weight[base + i][k] = w > 0 ? w : 0;
      }
  }
}

void append_primitive(const tinygltf::Model& model, const tinygltf::Primitive& prim, const Eigen::Matrix4d& world,
                      const std::string& path, const std::string& what, bool skinned, GltfScene& scene) {
  auto it = prim.attributes.find("POSITION");
  if (it == prim.attributes.end())
    return;
  const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
  if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN)
    return; // points and lines carry no surface
  RawMesh& raw = scene.mesh;
  AccessorReader pos(model, it->second, path, what + " POSITION");
  if (pos.ncomp != 3)
    throw InputError(path, what, "POSITION is not a VEC3");
  std::array<int, 5> accessors{};
  {
    int k = 0;
    for (const char* name : {"POSITION", "NORMAL", "TEXCOORD_0", "JOINTS_0", "WEIGHTS_0"}) {
      const auto a = prim.attributes.find(name);
      accessors[k++] = a == prim.attributes.end() ? -1 : a->second;
    }
  }
  int base = static_cast<int>(raw.positions.size());
  bool shared = false;
  for (const auto& source : scene.vertex_sources)
    if (source.accessors == accessors && source.skinned == skinned && source.world == world) {
      base = source.base;
      shared = true;
      break;
    }
  if (!shared)
    scene.vertex_sources.push_back({accessors, world, skinned, base});
  for (size_t i = 0; i < (shared ? 0 : pos.count()); ++i) {
    const Eigen::Vector4d p(pos.get(i, 0), pos.get(i, 1), pos.get(i, 2), 1.0);
    raw.positions.push_back((world * p).head<3>());
    if (!raw.positions.back().allFinite()) // whatever the file is read for: a mesh, a skin or a skeleton
      throw InputError(path, what + " POSITION " + std::to_string(i), "is not a finite number");
  }
  if (!shared)
    read_vertex_attributes(model, prim, world, path, what, skinned, base, pos.count(), scene);
  std::vector<int> idx;
  if (prim.indices >= 0) {
    AccessorReader ind(model, prim.indices, path, what + " indices");
    for (size_t i = 0; i < ind.count(); ++i) {
      const double v = ind.get(i, 0);
      if (v >= static_cast<double>(pos.count()))
        throw InputError(path, what + " index " + std::to_string(i),
                         "refers to vertex " + std::to_string(static_cast<long>(v)) + " of " +
                             std::to_string(pos.count()));
      idx.push_back(static_cast<int>(v));
    }
  } else {
    for (size_t i = 0; i < pos.count(); ++i)
      idx.push_back(static_cast<int>(i));
  }
  const bool mirrored = world.topLeftCorner<3, 3>().determinant() < 0;
  auto tri = [&](int a, int b, int c) {
    std::array<int, 3> t{base + a, base + b, base + c};
    if (mirrored)
      std::swap(t[1], t[2]);
    raw.add_face(t);
    scene.face_material.push_back(prim.material);
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

/// What is wrong with a 4x4 matrix for a skeleton ("" if nothing): it must
/// be finite, affine (last row 0 0 0 1, to 1e-6) and invertible, scaling by
/// no more than 1e9.
std::string matrix_fault(Eigen::Matrix4d m) {
  if (!m.allFinite())
    return "has a value that is not a finite number";
  // Exporters and single precision leave the last row 0 0 0 1 only to within rounding.
  if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6)
    return "is not affine (its last row is not 0 0 0 1)";
  m.row(3) = Eigen::RowVector4d(0, 0, 0, 1);
  if (!detail::bounded_scale(m))
    return "is singular, nearly so, or scales by more than 1e9 (it has no usable inverse)";
  return "";
}

/// Every index, type and count the readers below rely on, checked once: a
/// damaged file is refused naming the element, before anything reads it.
void validate_model(const tinygltf::Model& m, const std::string& path) {
  auto in_range = [](int i, size_t n) { return i >= 0 && static_cast<size_t>(i) < n; };
  if (m.asset.version.rfind("2.", 0) != 0)
    throw InputError(path, "asset.version",
                     "glTF " + (m.asset.version.empty() ? std::string("(no version)") : m.asset.version) +
                         ": only glTF 2.x is read");
  const size_t nodes = m.nodes.size();
  auto finite = [](const std::vector<double>& v) {
    return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
  };
  if (m.defaultScene >= 0 && !in_range(m.defaultScene, m.scenes.size()))
    throw InputError(path, "scene",
                     "the default scene " + std::to_string(m.defaultScene) + " does not exist (the file has " +
                         std::to_string(m.scenes.size()) + ")");
  for (size_t s = 0; s < m.scenes.size(); ++s)
    for (int n : m.scenes[s].nodes)
      if (!in_range(n, nodes))
        throw InputError(path, "scene " + std::to_string(s),
                         "refers to node " + std::to_string(n) + ", and there are " + std::to_string(nodes));
  // The hierarchy: children that exist, one parent each, and no cycle.
  std::vector<int> parent(nodes, -1);
  for (size_t i = 0; i < nodes; ++i) {
    const auto& node = m.nodes[i];
    const std::string what = "node " + std::to_string(i);
    for (int c : node.children) {
      if (!in_range(c, nodes))
        throw InputError(path, what,
                         "has child " + std::to_string(c) + ", and there are " + std::to_string(nodes) + " nodes");
      if (c == static_cast<int>(i))
        throw InputError(path, what, "is its own child");
      if (parent[c] >= 0)
        throw InputError(path, "node " + std::to_string(c),
                         "has two parents (" + std::to_string(parent[c]) + " and " + std::to_string(i) + ")");
      parent[c] = static_cast<int>(i);
    }
    if (node.mesh >= 0 && !in_range(node.mesh, m.meshes.size()))
      throw InputError(path, what,
                       "refers to mesh " + std::to_string(node.mesh) + ", and there are " +
                           std::to_string(m.meshes.size()));
    if (node.skin >= 0 && !in_range(node.skin, m.skins.size()))
      throw InputError(path, what,
                       "refers to skin " + std::to_string(node.skin) + ", and there are " +
                           std::to_string(m.skins.size()));
    if (!(node.matrix.empty() || node.matrix.size() == 16) ||
        !(node.translation.empty() || node.translation.size() == 3) ||
        !(node.rotation.empty() || node.rotation.size() == 4) || !(node.scale.empty() || node.scale.size() == 3))
      throw InputError(path, what, "matrix, translation, rotation or scale has the wrong number of values");
    if (!finite(node.matrix) || !finite(node.translation) || !finite(node.rotation) || !finite(node.scale))
      throw InputError(path, what, "a transform value is not a finite number");
    if (node.matrix.size() == 16) {
      Eigen::Matrix4d x;
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
          x(r, c) = node.matrix[4 * c + r];
      if (const std::string fault = matrix_fault(x); !fault.empty())
        throw InputError(path, what + " matrix", fault);
    }
    if (node.rotation.size() == 4 &&
        !(std::hypot(node.rotation[0], node.rotation[1], node.rotation[2]) + std::abs(node.rotation[3]) > 1e-6))
      throw InputError(path, what + " rotation", "the quaternion is zero (no rotation to normalise)");
  }
  for (size_t i = 0; i < nodes; ++i) {
    size_t steps = 0;
    for (int c = parent[i]; c >= 0; c = parent[c])
      if (++steps > nodes)
        throw InputError(path, "node " + std::to_string(i), "the node hierarchy has a cycle");
  }
  auto accessor = [&](int a, const std::string& what, const std::vector<int>& types,
                      const std::vector<int>& components) {
    if (!in_range(a, m.accessors.size()))
      throw InputError(path, what,
                       "refers to accessor " + std::to_string(a) + ", and there are " +
                           std::to_string(m.accessors.size()));
    const auto& acc = m.accessors[a];
    if (types.size() > 0 && std::find(types.begin(), types.end(), acc.type) == types.end())
      throw InputError(path, what, "accessor " + std::to_string(a) + " has the wrong type for it");
    if (components.size() > 0 && std::find(components.begin(), components.end(), acc.componentType) == components.end())
      throw InputError(path, what, "accessor " + std::to_string(a) + " has the wrong component type for it");
    AccessorReader check(m, a, path, what); // bounds
    return check.count();
  };
  using T = std::vector<int>;
  const T floats{TINYGLTF_COMPONENT_TYPE_FLOAT};
  const T uv_types{TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                   TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT};
  const T index_types{TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                      TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT};
  // KHR_mesh_quantization: positions, normals and texture coordinates may
  // be stored as (normalised) integers; their scale and offset are in the
  // node's transform, or, for a skinned mesh, in its inverse bind matrices.
  const bool quantized =
      std::find(m.extensionsUsed.begin(), m.extensionsUsed.end(), "KHR_mesh_quantization") != m.extensionsUsed.end() ||
      std::find(m.extensionsRequired.begin(), m.extensionsRequired.end(), "KHR_mesh_quantization") !=
          m.extensionsRequired.end();
  const T position_types = quantized ? T{TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
                                         TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
                                         TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT}
                                     : floats;
  const T texcoord_types = quantized ? position_types : uv_types;
  for (size_t mi = 0; mi < m.meshes.size(); ++mi)
    for (size_t pi = 0; pi < m.meshes[mi].primitives.size(); ++pi) {
      const auto& prim = m.meshes[mi].primitives[pi];
      const std::string what = "mesh " + std::to_string(mi) + " primitive " + std::to_string(pi);
      for (const auto& [name, a] : prim.attributes) {
        const std::string w = what + " " + name;
        if (name == "POSITION")
          accessor(a, w, {TINYGLTF_TYPE_VEC3}, position_types);
        else if (name == "TEXCOORD_0")
          accessor(a, w, {TINYGLTF_TYPE_VEC2}, texcoord_types);
        else if (name == "JOINTS_0")
          accessor(a, w, {TINYGLTF_TYPE_VEC4},
                   {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT});
        else if (name == "WEIGHTS_0")
          accessor(a, w, {TINYGLTF_TYPE_VEC4}, uv_types);
        else
          accessor(a, w, {}, {});
      }
      if (prim.indices >= 0)
        accessor(prim.indices, what + " indices", {TINYGLTF_TYPE_SCALAR}, index_types);
    }
  for (size_t si = 0; si < m.skins.size(); ++si) {
    const auto& skin = m.skins[si];
    const std::string what = "skin " + std::to_string(si);
    std::vector<char> seen(nodes, 0);
    for (int j : skin.joints) {
      if (!in_range(j, nodes))
        throw InputError(path, what,
                         "joint node " + std::to_string(j) + " does not exist (there are " + std::to_string(nodes) +
                             " nodes)");
      if (seen[j]++)
        throw InputError(path, what, "lists node " + std::to_string(j) + " twice");
    }
    if (skin.inverseBindMatrices >= 0 && accessor(skin.inverseBindMatrices, what + " inverseBindMatrices",
                                                  {TINYGLTF_TYPE_MAT4}, floats) < skin.joints.size())
      throw InputError(path, what, "inverseBindMatrices must hold one MAT4 per joint");
    if (skin.inverseBindMatrices >= 0) {
      const AccessorReader acc(m, skin.inverseBindMatrices, path, what + " inverseBindMatrices");
      for (size_t j = 0; j < skin.joints.size(); ++j) {
        Eigen::Matrix4d x;
        for (int c = 0; c < 4; ++c)
          for (int r = 0; r < 4; ++r)
            x(r, c) = acc.get(j, 4 * c + r);
        if (const std::string fault = matrix_fault(x); !fault.empty())
          throw InputError(path, what + " inverse bind matrix " + std::to_string(j), fault);
      }
    }
  }
  // Each skinned primitive's JOINTS_0 names joints of its node's skin.
  for (size_t ni = 0; ni < nodes; ++ni) {
    const auto& node = m.nodes[ni];
    if (node.mesh < 0 || node.skin < 0)
      continue;
    const size_t joints = m.skins[node.skin].joints.size();
    for (size_t pi = 0; pi < m.meshes[node.mesh].primitives.size(); ++pi) {
      const auto& prim = m.meshes[node.mesh].primitives[pi];
      const auto jt = prim.attributes.find("JOINTS_0");
      if (jt == prim.attributes.end())
        continue;
      const auto wt = prim.attributes.find("WEIGHTS_0");
      const std::string what = "mesh " + std::to_string(node.mesh) + " primitive " + std::to_string(pi) + " JOINTS_0";
      const AccessorReader ji(m, jt->second, path, what);
      std::optional<AccessorReader> wi;
      if (wt != prim.attributes.end())
        wi.emplace(m, wt->second, path, what);
      for (size_t v = 0; v < ji.count(); ++v)
        for (int k = 0; k < ji.ncomp; ++k) {
          const bool weighted = !wi || v >= wi->count() || k >= wi->ncomp || wi->get(v, k) > 0;
          if (weighted && ji.get(v, k) >= static_cast<double>(joints))
            throw InputError(path, what + " vertex " + std::to_string(v),
                             "names joint " + std::to_string(static_cast<long>(ji.get(v, k))) + " of a skin with " +
                                 std::to_string(joints) + " joints");
        }
    }
  }
  for (size_t ai = 0; ai < m.animations.size(); ++ai) {
    const auto& anim = m.animations[ai];
    const std::string what = "animation " + std::to_string(ai) + (anim.name.empty() ? "" : " '" + anim.name + "'");
    for (size_t si = 0; si < anim.samplers.size(); ++si) {
      const auto& sampler = anim.samplers[si];
      const std::string w = what + " sampler " + std::to_string(si);
      if (sampler.interpolation != "LINEAR" && sampler.interpolation != "STEP" &&
          sampler.interpolation != "CUBICSPLINE")
        throw InputError(path, w, "unknown interpolation '" + sampler.interpolation + "'");
      const size_t keys = accessor(sampler.input, w + " input", {TINYGLTF_TYPE_SCALAR}, floats);
      accessor(sampler.output, w + " output", {}, {});
      const AccessorReader times(m, sampler.input, path, w + " input");
      double last = -std::numeric_limits<double>::infinity();
      for (size_t k = 0; k < keys; ++k) {
        const double t = times.get(k, 0);
        if (!std::isfinite(t))
          throw InputError(path, w + " input", "key time " + std::to_string(k) + " is not a finite number");
        if (!(t > last))
          throw InputError(path, w + " input", "key times do not increase at key " + std::to_string(k));
        last = t;
      }
      // A declared time range must agree with the keys (it gives the clip's length).
      const auto& acc = m.accessors[sampler.input];
      if (keys > 0 && acc.minValues.size() == 1 && acc.maxValues.size() == 1) {
        const double first = times.get(0, 0), end = times.get(keys - 1, 0);
        auto near = [](double a, double b) {
          return std::abs(a - b) <= 1e-6 * std::max({1.0, std::abs(a), std::abs(b)});
        };
        if (!near(acc.minValues[0], first) || !near(acc.maxValues[0], end))
          throw InputError(path, w + " input",
                           "declares its times to run from " + std::to_string(acc.minValues[0]) + " to " +
                               std::to_string(acc.maxValues[0]) + ", but its keys run from " + std::to_string(first) +
                               " to " + std::to_string(end));
      }
    }
    for (size_t ci = 0; ci < anim.channels.size(); ++ci) {
      const auto& ch = anim.channels[ci];
      const std::string w = what + " channel " + std::to_string(ci);
      if (!in_range(ch.sampler, anim.samplers.size()))
        throw InputError(path, w,
                         "refers to sampler " + std::to_string(ch.sampler) + ", and there are " +
                             std::to_string(anim.samplers.size()));
      if (ch.target_node >= 0 && !in_range(ch.target_node, nodes))
        throw InputError(path, w,
                         "targets node " + std::to_string(ch.target_node) + ", and there are " + std::to_string(nodes));
      const std::string& target = ch.target_path;
      if (target != "translation" && target != "rotation" && target != "scale" && target != "weights")
        throw InputError(path, w, "unknown target path '" + target + "'");
      if (target == "weights")
        continue;
      const auto& sampler = anim.samplers[ch.sampler];
      const auto& out = m.accessors[sampler.output];
      const int want = target == "rotation" ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3;
      if (out.type != want)
        throw InputError(path, w, "a " + target + " output must be " + (target == "rotation" ? "VEC4" : "VEC3"));
      const size_t keys = m.accessors[sampler.input].count;
      if (out.count < keys * (sampler.interpolation == "CUBICSPLINE" ? 3 : 1))
        throw InputError(path, w, "output has fewer values than the input has times");
      const AccessorReader values(m, sampler.output, path, w + " output");
      for (size_t k = 0; k < values.count(); ++k) {
        for (int c = 0; c < values.ncomp; ++c)
          if (!std::isfinite(values.get(k, c)))
            throw InputError(path, w + " output", "value " + std::to_string(k) + " is not a finite number");
        // A rotation key (not a cubic spline's tangent) is a quaternion to normalise.
        const bool key = sampler.interpolation != "CUBICSPLINE" || k % 3 == 1;
        if (target == "rotation" && key && values.ncomp == 4 &&
            !(std::abs(values.get(k, 0)) + std::abs(values.get(k, 1)) + std::abs(values.get(k, 2)) +
                  std::abs(values.get(k, 3)) >
              1e-6))
          throw InputError(path, w + " output", "rotation key " + std::to_string(k) + " is a zero quaternion");
      }
    }
  }
}

std::vector<int> scene_roots(const tinygltf::Model& model, const std::vector<int>& parent) {
  const int scene = model.defaultScene >= 0 ? model.defaultScene : (model.scenes.empty() ? -1 : 0);
  if (scene >= 0)
    return model.scenes[scene].nodes;
  std::vector<int> roots;
  for (size_t i = 0; i < parent.size(); ++i)
    if (parent[i] < 0)
      roots.push_back(static_cast<int>(i));
  return roots;
}

} // namespace

namespace {

/// The scenes read last, by file: a command reads its mesh's surface, its
/// input topology and its skin from one file, and each is built from one
/// parse. The file's bytes are read each time and hashed (cheap beside the
/// parse); a file whose bytes changed is parsed again.
struct SceneCache {
  struct Entry {
    std::string path;
    size_t size = 0, hash = 0; ///< of the bytes: a file rewritten within the clock's tick keeps its mtime
    std::shared_ptr<const GltfScene> scene;
    std::optional<FileStamp> stamp; ///< settled when read: then an unchanged stamp needs no second read
  };
  std::mutex mutex;
  std::vector<Entry> entries; // the most recent last, at most kKept
  long parses = 0;
  static constexpr size_t kKept = 2;
};

SceneCache& scene_cache() {
  static SceneCache cache;
  return cache;
}

GltfScene parse_gltf_scene(const std::string& path, const std::string& bytes);

} // namespace

void forget_gltf_parses() {
  SceneCache& c = scene_cache();
  std::lock_guard lock(c.mutex);
  c.entries.clear();
}

long gltf_parses() {
  SceneCache& c = scene_cache();
  std::lock_guard lock(c.mutex);
  return c.parses;
}

GltfScene read_gltf_scene(const std::string& path) {
  std::error_code ec;
  const std::string key = std::filesystem::absolute(path, ec).lexically_normal().string();
  const std::optional<FileStamp> stamp = settled_stamp(path);
  SceneCache& c = scene_cache();
  {
    std::lock_guard lock(c.mutex);
    for (const auto& e : c.entries)
      if (e.path == key && stamp && e.stamp == stamp)
        return *e.scene; // a settled file, unchanged: not read again
  }
  const std::string bytes = file_bytes(path);
  const size_t hash = std::hash<std::string_view>{}(bytes);
  {
    std::lock_guard lock(c.mutex);
    for (auto& e : c.entries)
      if (e.path == key && e.size == bytes.size() && e.hash == hash) {
        e.stamp = stamp;
        return *e.scene;
      }
  }
  auto scene = std::make_shared<const GltfScene>(parse_gltf_scene(path, bytes));
  std::lock_guard lock(c.mutex);
  ++c.parses;
  std::erase_if(c.entries, [&](const SceneCache::Entry& e) { return e.path == key; });
  c.entries.push_back({key, bytes.size(), hash, scene, stamp});
  if (c.entries.size() > SceneCache::kKept)
    c.entries.erase(c.entries.begin());
  return *scene;
}

namespace {

/// A compression extension the file requires whose data curvenet does not
/// decode (empty if none): its buffers hold compressed bytes that would
/// read as garbage, or make the reader fail with a message about sizes.
std::string compression_required(const std::vector<std::string>& required) {
  for (const char* name : {"KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression"})
    if (std::find(required.begin(), required.end(), name) != required.end())
      return name;
  return {};
}

[[noreturn]] void refuse_compression(const std::string& path, const std::string& name) {
  throw InputError(path, "extensionsRequired",
                   "the file is compressed with " + name +
                       ", which curvenet does not decode: write it uncompressed first (`gltf-transform copy IN "
                       "OUT` decodes it)");
}

/// tinygltf's file reader for external buffers, refusing what is not a
/// regular file: a folder read as a buffer ended in std::bad_alloc, and a
/// FIFO no one writes blocked for ever.
bool read_regular_file(std::vector<unsigned char>* out, std::string* err, const std::string& file, void* user) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) {
    if (err)
      *err += "'" + file + "' is " + (std::filesystem::exists(file, ec) ? "not a regular file" : "missing") + "\n";
    return false;
  }
  return tinygltf::ReadWholeFile(out, err, file, user);
}

/// Whether a file is there, without opening it (tinygltf's own opens it,
/// and the open of a FIFO no one writes blocks).
bool file_is_there(const std::string& file, void*) {
  std::error_code ec;
  return std::filesystem::exists(file, ec);
}

GltfScene parse_gltf_scene(const std::string& path, const std::string& bytes) {
  const std::string ext = detail::lower_extension(path);
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&skip_image, nullptr);
  loader.SetFsCallbacks({&file_is_there, &tinygltf::ExpandFilePath, &read_regular_file, &tinygltf::WriteWholeFile,
                         nullptr});
  auto model = std::make_shared<tinygltf::Model>();
  std::string err, warn;
  // The JSON's nesting bounded before tinygltf parses it.
  if (bytes.size() > std::numeric_limits<unsigned int>::max())
    throw InputError(path, "", "the file is larger than 4 GB, more than a glTF reader takes");
  std::string_view json = bytes;
  if (ext == ".glb" && bytes.size() >= 20) {
    std::uint32_t length = 0;
    std::memcpy(&length, bytes.data() + 12, 4);
    json = std::string_view(bytes).substr(20, std::min<size_t>(length, bytes.size() - 20));
  }
  if (const auto at = too_deep(json, kMaxJsonDepth))
    throw InputError(path, ext == ".glb" ? "JSON chunk byte " + std::to_string(*at) : line_column(bytes, *at),
                     "JSON nested more than " + std::to_string(kMaxJsonDepth) + " levels deep");
  const std::string base_dir = std::filesystem::path(path).parent_path().string();
  const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
  const bool ok = ext == ".glb" ? loader.LoadBinaryFromMemory(model.get(), &err, &warn, data,
                                                              static_cast<unsigned int>(bytes.size()), base_dir)
                                : loader.LoadASCIIFromString(model.get(), &err, &warn, bytes.data(),
                                                             static_cast<unsigned int>(bytes.size()), base_dir);
  if (!ok) {
    // A compressed file fails on its buffers' sizes or its accessors' views:
    // said as what it is.
    if (const auto doc = nlohmann::json::parse(json, nullptr, false);
        doc.is_object() && doc.contains("extensionsRequired") && doc["extensionsRequired"].is_array()) {
      std::vector<std::string> required;
      for (const auto& e : doc["extensionsRequired"])
        if (e.is_string())
          required.push_back(e.get<std::string>());
      if (const std::string name = compression_required(required); !name.empty())
        refuse_compression(path, name);
    }
    while (!err.empty() && std::isspace(static_cast<unsigned char>(err.back())))
      err.pop_back();
    std::replace(err.begin(), err.end(), '\n', ';'); // one line
    // The JSON library's own tag ("[json.exception.parse_error.101] ") says
    // nothing to a user; the line and column after it do.
    for (size_t at; (at = err.find("[json.exception.")) != std::string::npos;) {
      const size_t end = err.find("] ", at);
      if (end == std::string::npos)
        break;
      err.erase(at, end + 2 - at);
    }
    throw InputError(path, "", "cannot read glTF: " + (err.empty() ? std::string("unknown error") : err));
  }
  if (const std::string name = compression_required(model->extensionsRequired); !name.empty())
    refuse_compression(path, name);
  validate_model(*model, path);
  GltfScene scene;
  scene.path = path;
  scene.node_parent.assign(model->nodes.size(), -1);
  for (size_t i = 0; i < model->nodes.size(); ++i)
    for (int c : model->nodes[i].children) {
      if (c < 0 || c >= static_cast<int>(model->nodes.size()) || scene.node_parent[c] >= 0)
        throw InputError(path, "node " + std::to_string(i), "invalid node hierarchy");
      scene.node_parent[c] = static_cast<int>(i);
    }
  // Walk the default scene. A skinned mesh's node transform is ignored, as
  // glTF requires: its vertices stay in the mesh's object space, which is
  // where rigs are authored.
  scene.model = model;
  const auto world = node_world_matrices(scene, -1, 0);
  std::vector<int> stack;
  const auto roots = scene_roots(*model, scene.node_parent);
  for (auto it = roots.rbegin(); it != roots.rend(); ++it)
    stack.push_back(*it);
  size_t guard = 0;
  while (!stack.empty()) {
    const int ni = stack.back();
    stack.pop_back();
    if (ni < 0 || ni >= static_cast<int>(model->nodes.size()) || ++guard > model->nodes.size())
      throw InputError(path, "node " + std::to_string(ni), "invalid node hierarchy");
    const auto& node = model->nodes[ni];
    if (node.mesh >= 0) {
      const bool skinned = node.skin >= 0;
      if (skinned && scene.skin < 0)
        scene.skin = node.skin;
      const Eigen::Matrix4d m = skinned ? Eigen::Matrix4d::Identity() : world[ni];
      const auto& mesh = model->meshes.at(node.mesh);
      for (size_t p = 0; p < mesh.primitives.size(); ++p)
        append_primitive(*model, mesh.primitives[p], m, path,
                         (mesh.name.empty() ? "mesh " + std::to_string(node.mesh) : "mesh '" + mesh.name + "'") +
                             " primitive " + std::to_string(p),
                         skinned && node.skin == scene.skin, scene);
    }
    for (auto it = node.children.rbegin(); it != node.children.rend(); ++it)
      stack.push_back(*it);
  }
  if (scene.mesh.positions.empty())
    throw InputError(path, "", "the glTF scene holds no triangle mesh");
  scene.model = model;
  return scene;
}

} // namespace

std::vector<Eigen::Matrix4d> inverse_bind_matrices(const GltfScene& scene) {
  const auto& model = *scene.model;
  const auto& skin = model.skins.at(scene.skin);
  std::vector<Eigen::Matrix4d> out(skin.joints.size(), Eigen::Matrix4d::Identity());
  if (skin.inverseBindMatrices >= 0) {
    AccessorReader acc(model, skin.inverseBindMatrices, scene.path, "skin inverseBindMatrices");
    if (acc.ncomp != 16 || acc.count() < skin.joints.size())
      throw InputError(scene.path, "skin " + std::to_string(scene.skin),
                       "inverseBindMatrices must hold one MAT4 per joint");
    for (size_t j = 0; j < out.size(); ++j)
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
          out[j](r, c) = acc.get(j, 4 * c + r);
  }
  return out;
}

std::vector<Eigen::Matrix4d> node_world_matrices(const GltfScene& scene, int clip, double t) {
  const auto& model = *scene.model;
  const size_t n = model.nodes.size();
  std::vector<Trs> local(n);
  for (size_t i = 0; i < n; ++i)
    local[i] = rest_trs(model.nodes[i]);
  if (clip >= 0) {
    const auto& anim = model.animations.at(clip);
    for (size_t ci = 0; ci < anim.channels.size(); ++ci) {
      const auto& ch = anim.channels[ci];
      if (ch.target_node < 0 || ch.target_node >= static_cast<int>(n))
        continue;
      const auto& sampler = anim.samplers.at(ch.sampler);
      const std::string what = "animation '" + anim.name + "' channel " + std::to_string(ci);
      AccessorReader in(model, sampler.input, scene.path, what + " input");
      AccessorReader out(model, sampler.output, scene.path, what + " output");
      const size_t keys = in.count();
      if (keys == 0)
        continue;
      const bool cubic = sampler.interpolation == "CUBICSPLINE";
      const bool step = sampler.interpolation == "STEP";
      if (out.count() < keys * (cubic ? 3 : 1))
        throw InputError(scene.path, what, "output has fewer values than the input has times");
      const int dim = ch.target_path == "rotation" ? 4 : 3;
      if (ch.target_path != "translation" && ch.target_path != "rotation" && ch.target_path != "scale")
        continue;                            // morph weights do not move joints
      auto value = [&](size_t k, int slot) { // slot: 0 in-tangent, 1 value, 2 out-tangent (cubic only)
        Eigen::Vector4d v = Eigen::Vector4d::Zero();
        const size_t e = cubic ? 3 * k + slot : k;
        for (int c = 0; c < dim; ++c)
          v[c] = out.get(e, c);
        return v;
      };
      // The keyframe interval that holds t.
      size_t k = 0;
      while (k + 1 < keys && in.get(k + 1, 0) <= t)
        ++k;
      Eigen::Vector4d v;
      if (t <= in.get(0, 0) || k + 1 >= keys || step) {
        v = value(t <= in.get(0, 0) ? 0 : k, 1);
      } else {
        const double t0 = in.get(k, 0), t1 = in.get(k + 1, 0), td = t1 - t0;
        const double s = td > 0 ? (t - t0) / td : 0;
        if (cubic) {
          const double s2 = s * s, s3 = s2 * s;
          v = (2 * s3 - 3 * s2 + 1) * value(k, 1) + (s3 - 2 * s2 + s) * td * value(k, 2) +
              (-2 * s3 + 3 * s2) * value(k + 1, 1) + (s3 - s2) * td * value(k + 1, 0);
        } else if (dim == 4) {
          const Eigen::Vector4d a = value(k, 1), b = value(k + 1, 1);
          const Eigen::Quaterniond qa(a[3], a[0], a[1], a[2]), qb(b[3], b[0], b[1], b[2]);
          const Eigen::Quaterniond q = qa.normalized().slerp(s, qb.normalized());
          v << q.x(), q.y(), q.z(), q.w();
        } else {
          v = (1 - s) * value(k, 1) + s * value(k + 1, 1);
        }
      }
      Trs& x = local[ch.target_node];
      if (ch.target_path == "translation")
        x.t = v.head<3>();
      else if (ch.target_path == "scale")
        x.s = v.head<3>();
      else
        x.r = Eigen::Quaterniond(v[3], v[0], v[1], v[2]).normalized();
    }
  }
  std::vector<Eigen::Matrix4d> world(n, Eigen::Matrix4d::Identity());
  std::vector<char> done(n, 0);
  for (size_t i = 0; i < n; ++i) {
    // Compose up the parent chain (parents may come after children in the file).
    std::vector<int> chain;
    for (int c = static_cast<int>(i); c >= 0 && !done[c]; c = scene.node_parent[c])
      chain.push_back(c);
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      const int c = *it, p = scene.node_parent[c];
      world[c] = (p >= 0 ? world[p] : Eigen::Matrix4d::Identity()) * local[c].matrix();
      done[c] = 1;
    }
  }
  return world;
}

} // namespace curvenet::detail
