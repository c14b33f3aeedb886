// A skinned glTF 2.0 binary from a mesh file, a skeleton and baked weights
// (tinygltf writes it). See curvenet/bake.hpp and docs/bake.md.

#include "core/polygon.hpp"
#include "curvenet/bake.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/mesh_output.hpp"
#include "curvenet/pose.hpp"
#include "io/file_bytes.hpp"
#include "io/gltf_scene.hpp"

#include <tiny_gltf.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <numeric>
#include <set>
#include <sstream>

namespace curvenet {
namespace {

/// Keys per clip that a bake writes at most (100 hours at 24 fps): the
/// jobs refuse long clips before this by --max-frames, and a direct call
/// of skinned_glb is refused here before it would allocate for them.
constexpr double kMaxKeys = 1e7;

/// One binary buffer, with a bufferView per block, each 4-byte aligned.
struct BinaryWriter {
  tinygltf::Model& model;
  std::vector<unsigned char>& bytes;

  int view(const void* data, size_t size, int target) {
    while (bytes.size() % 4 != 0)
      bytes.push_back(0);
    tinygltf::BufferView v;
    v.buffer = 0;
    v.byteOffset = bytes.size();
    v.byteLength = size;
    v.target = target;
    const auto* p = static_cast<const unsigned char*>(data);
    bytes.insert(bytes.end(), p, p + size);
    model.bufferViews.push_back(v);
    return static_cast<int>(model.bufferViews.size()) - 1;
  }

  template <class T>
  int accessor(const std::vector<T>& data, int component, int type, size_t count, int target, bool with_bounds = false,
               int ncomp = 1) {
    tinygltf::Accessor a;
    a.bufferView = view(data.data(), data.size() * sizeof(T), target);
    a.componentType = component;
    a.type = type;
    a.count = count;
    if (with_bounds) {
      a.minValues.assign(ncomp, std::numeric_limits<double>::infinity());
      a.maxValues.assign(ncomp, -std::numeric_limits<double>::infinity());
      for (size_t i = 0; i < count; ++i)
        for (int c = 0; c < ncomp; ++c) {
          a.minValues[c] = std::min(a.minValues[c], static_cast<double>(data[i * ncomp + c]));
          a.maxValues[c] = std::max(a.maxValues[c], static_cast<double>(data[i * ncomp + c]));
        }
    }
    model.accessors.push_back(a);
    return static_cast<int>(model.accessors.size()) - 1;
  }
};

/// Translation, rotation and scale of a joint's local transform (glTF
/// animates nodes by TRS): the rotation is the nearest one to the linear part
/// with its column lengths taken out.
struct Trs {
  Eigen::Vector3d t, s;
  Eigen::Quaterniond r;
};
Trs decompose(const Mat4& m) {
  Trs x;
  x.t = m.block<3, 1>(0, 3);
  Eigen::Matrix3d a = m.topLeftCorner<3, 3>();
  for (int c = 0; c < 3; ++c)
    x.s[c] = a.col(c).norm();
  if (a.determinant() < 0)
    x.s[0] = -x.s[0];
  for (int c = 0; c < 3; ++c)
    if (x.s[c] != 0)
      a.col(c) /= x.s[c];
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(a, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0)
    r = -r;
  x.r = Eigen::Quaterniond(r).normalized();
  return x;
}
Mat4 compose(const Trs& x) {
  Eigen::Affine3d a = Eigen::Affine3d::Identity();
  a.translate(x.t);
  a.rotate(x.r);
  a.scale(x.s);
  return a.matrix();
}

/// Whether a node's TRS can hold the transform: its linear part is a
/// rotation and scales along the local axes to within a millionth (a clip's
/// single-precision keys leave shears of about 1e-7; the keys are written in
/// single precision anyway).
bool carried_by_trs(const Mat4& L) {
  if (!L.allFinite())
    return false;
  const Eigen::Matrix3d A = L.topLeftCorner<3, 3>();
  const double size = A.cwiseAbs().maxCoeff();
  const Eigen::Matrix3d back = compose(decompose(L)).topLeftCorner<3, 3>();
  return size > 0 && (back - A).cwiseAbs().maxCoeff() <= 1e-6 * size;
}


std::string mime_of(const std::string& uri) {
  const std::string ext = detail::lower_extension(uri);
  if (ext == ".png")
    return "image/png";
  if (ext == ".jpg" || ext == ".jpeg")
    return "image/jpeg";
  if (ext == ".ktx2")
    return "image/ktx2";
  if (ext == ".webp")
    return "image/webp";
  return "application/octet-stream";
}

std::string base64_decoded(std::string_view s) {
  auto value = [](char c) -> int {
    if (c >= 'A' && c <= 'Z')
      return c - 'A';
    if (c >= 'a' && c <= 'z')
      return c - 'a' + 26;
    if (c >= '0' && c <= '9')
      return c - '0' + 52;
    return c == '+' ? 62 : c == '/' ? 63 : -1;
  };
  std::string out;
  int acc = 0, bits = 0;
  for (char c : s) {
    const int v = value(c);
    if (v < 0)
      continue; // padding and whitespace
    acc = (acc << 6) | v;
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<char>((acc >> bits) & 0xff));
    }
  }
  return out;
}

/// The bytes of a source image: its bufferView, a data URI, or a file beside the source.
std::string image_bytes(const tinygltf::Model& src, const tinygltf::Image& img, const std::string& source) {
  if (img.bufferView >= 0) {
    const auto& v = src.bufferViews.at(img.bufferView);
    const auto& b = src.buffers.at(v.buffer);
    if (v.byteOffset + v.byteLength > b.data.size())
      throw InputError(source, "image '" + img.name + "'", "its bufferView runs past its buffer");
    return std::string(reinterpret_cast<const char*>(b.data.data() + v.byteOffset), v.byteLength);
  }
  const std::string& uri = img.uri;
  if (uri.rfind("data:", 0) == 0) {
    const auto comma = uri.find(',');
    if (comma == std::string::npos || uri.substr(0, comma).find(";base64") == std::string::npos)
      throw InputError(source, "image '" + img.name + "'", "a data URI that is not base64");
    return base64_decoded(std::string_view(uri).substr(comma + 1));
  }
  const auto path = std::filesystem::path(source).parent_path() / uri;
  std::error_code ec;
  std::ifstream in;
  if (std::filesystem::is_regular_file(path, ec)) // not a folder, nor a FIFO no one writes
    in.open(path, std::ios::binary);
  if (!in)
    throw InputError(source, "image '" + uri + "'", "cannot read the image file " + path.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

} // namespace

std::string skinned_glb(const std::string& mesh_path, const std::vector<Joint>& joints, const SkinWeights& weights,
                        const SkinnedMesh* clips, const GltfBakeOptions& options) {
  const InputTopology topo = read_input_topology(mesh_path);
  const RawMesh& faces = topo.faces;
  const int nv = static_cast<int>(faces.positions.size());
  const int k = weights.influences;
  if (weights.num_vertices() != nv)
    throw InputError(mesh_path, "",
                     "the weights are for " + std::to_string(weights.num_vertices()) + " vertices, the file has " +
                         std::to_string(nv));
  if (joints.size() != static_cast<size_t>(weights.rig_joints()) || weights.helpers.size() > weights.joints.size() ||
      joints.empty())
    throw InputError(mesh_path, "skeleton",
                     "the weights name " + std::to_string(weights.rig_joints()) + " joints, the skeleton has " +
                         std::to_string(joints.size()));
  for (const auto& [a, b] : weights.helpers)
    if (a < 0 || b < 0 || a >= static_cast<int>(joints.size()) || b >= static_cast<int>(joints.size()))
      throw InputError(mesh_path, "helper joint", "it names a joint the skeleton does not have");
  std::map<std::string, int> joint_index;
  for (size_t j = 0; j < joints.size(); ++j) {
    if (joints[j].name != weights.joints[j])
      throw InputError(mesh_path, "joint " + std::to_string(j), "the weights and the skeleton list different joints");
    if (joints[j].parent && !joint_index.count(*joints[j].parent))
      throw InputError(mesh_path, "joint '" + joints[j].name + "'", "its parent is not listed before it");
    joint_index[joints[j].name] = static_cast<int>(j);
  }
  if (!(options.fps > 0 && options.fps <= 1000))
    throw InputError("fps", std::to_string(options.fps), "must be in (0, 1000]");

  // The source's axes to glTF's: Y-up as it is, Z-up turned about X.
  Mat4 C = Mat4::Identity();
  if (options.up == GltfBakeOptions::Up::Z)
    C.topLeftCorner<3, 3>() << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  const Eigen::Matrix3d C3 = C.topLeftCorner<3, 3>();

  // Normals per slot: the file's where it has them, else from the surface.
  std::vector<Vec3> normals(static_cast<size_t>(topo.num_normals), Vec3::Zero());
  for (size_t f = 0; f + 1 < faces.face_offsets.size(); ++f) {
    Vec3 n = Vec3::Zero();
    const int b = faces.face_offsets[f], e = faces.face_offsets[f + 1];
    for (int c = b; c < e; ++c)
      n += faces.positions[faces.face_vertices[c]].cross(faces.positions[faces.face_vertices[c + 1 < e ? c + 1 : b]]);
    for (int c = b; c < e; ++c)
      normals[topo.corner_normal[c]] += n;
  }
  for (size_t s = 0; s < normals.size(); ++s) {
    if (s < topo.normals.size() && topo.normals[s].allFinite() && topo.normals[s].norm() > 0)
      normals[s] = topo.normals[s];
    normals[s] = normals[s].norm() > 0 ? Vec3(normals[s].normalized()) : Vec3(0, 1, 0);
  }

  // Output vertices: the file's, in its order, then a copy for each other
  // (UV, normal) pair a vertex's corners carry.
  struct Key {
    int uv, normal;
  };
  std::vector<std::vector<std::pair<Key, int>>> combos(nv); // per file vertex: (attributes, output vertex)
  std::vector<int> out_vertex_of(nv);                       // output vertex -> file vertex
  std::iota(out_vertex_of.begin(), out_vertex_of.end(), 0);
  std::vector<Key> out_key(nv, Key{-1, -1}); // output vertex -> its corners' attributes
  std::vector<int> corner_out(faces.face_vertices.size());
  for (size_t c = 0; c < faces.face_vertices.size(); ++c) {
    const int v = faces.face_vertices[c];
    const Key key{topo.corner_uv[c], topo.corner_normal[c]};
    int out = -1;
    for (const auto& [kk, o] : combos[v])
      if (kk.uv == key.uv && kk.normal == key.normal)
        out = o;
    if (out < 0) {
      // The first pair a vertex carries keeps its place; others are copies.
      out = combos[v].empty() ? v : static_cast<int>(out_vertex_of.size());
      if (out != v) {
        out_vertex_of.push_back(v);
        out_key.push_back(key);
      } else {
        out_key[v] = key;
      }
      combos[v].push_back({key, out});
    }
    corner_out[c] = out;
  }
  const size_t no = out_vertex_of.size();
  const bool has_uv = !topo.uv.empty();

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "curvenet bake";
  model.buffers.resize(1);
  BinaryWriter bin{model, model.buffers[0].data};

  std::vector<float> pos, nrm, uv;
  for (size_t o = 0; o < no; ++o) {
    const Vec3 p = C3 * faces.positions[out_vertex_of[o]];
    const Key key = out_key[o];
    const Vec3 n = C3 * (key.normal >= 0 ? normals[key.normal] : Vec3(0, 0, 1));
    for (int c = 0; c < 3; ++c) {
      pos.push_back(static_cast<float>(p[c]));
      nrm.push_back(static_cast<float>(n[c]));
    }
    if (has_uv) {
      const Eigen::Vector2d t =
          key.uv >= 0 && key.uv < static_cast<int>(topo.uv.size()) ? topo.uv[key.uv] : Eigen::Vector2d::Zero();
      uv.push_back(static_cast<float>(t.x()));
      uv.push_back(static_cast<float>(1.0 - t.y())); // glTF's v runs down
    }
  }
  for (float x : pos)
    if (!std::isfinite(x))
      throw InputError(mesh_path, "", "a vertex is out of the range of single precision");
  tinygltf::Primitive base;
  base.mode = TINYGLTF_MODE_TRIANGLES;
  base.attributes["POSITION"] =
      bin.accessor(pos, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, no, TINYGLTF_TARGET_ARRAY_BUFFER, true, 3);
  base.attributes["NORMAL"] =
      bin.accessor(nrm, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, no, TINYGLTF_TARGET_ARRAY_BUFFER);
  if (has_uv)
    base.attributes["TEXCOORD_0"] =
        bin.accessor(uv, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC2, no, TINYGLTF_TARGET_ARRAY_BUFFER);
  // Joints and weights: sets of four slots; unused slots are joint 0 with
  // weight 0. The largest weight takes the single-precision rounding, so that
  // each vertex's weights sum to 1 as stored.
  const int sets = (k + 3) / 4;
  const int slots = 4 * sets;
  std::vector<int> jall(no * slots, 0);
  std::vector<float> wall(no * slots, 0.0f);
  for (size_t o = 0; o < no; ++o) {
    const size_t v = static_cast<size_t>(out_vertex_of[o]);
    double sum = 0;
    for (int i = 0; i < k; ++i) {
      const int j = weights.joint[v * k + i];
      if (j < 0)
        continue;
      jall[o * slots + i] = j;
      wall[o * slots + i] = static_cast<float>(weights.weight[v * k + i]);
      sum += wall[o * slots + i];
    }
    wall[o * slots] = static_cast<float>(wall[o * slots] + (1.0 - sum));
  }
  const bool wide = weights.joints.size() > 255;
  for (int set = 0; set < sets; ++set) {
    std::vector<unsigned char> j8;
    std::vector<unsigned short> j16;
    std::vector<float> w;
    for (size_t o = 0; o < no; ++o)
      for (int i = 4 * set; i < 4 * set + 4; ++i) {
        if (wide)
          j16.push_back(static_cast<unsigned short>(jall[o * slots + i]));
        else
          j8.push_back(static_cast<unsigned char>(jall[o * slots + i]));
        w.push_back(wall[o * slots + i]);
      }
    const std::string suffix = "_" + std::to_string(set);
    base.attributes["JOINTS" + suffix] = wide ? bin.accessor(j16, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                                             TINYGLTF_TYPE_VEC4, no, TINYGLTF_TARGET_ARRAY_BUFFER)
                                              : bin.accessor(j8, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                                             TINYGLTF_TYPE_VEC4, no, TINYGLTF_TARGET_ARRAY_BUFFER);
    base.attributes["WEIGHTS" + suffix] =
        bin.accessor(w, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC4, no, TINYGLTF_TARGET_ARRAY_BUFFER);
  }

  // Triangles, one primitive per material.
  std::map<int, std::vector<uint32_t>> by_material;
  std::vector<Vec3> corners;
  for (size_t f = 0; f + 1 < faces.face_offsets.size(); ++f) {
    const int b = faces.face_offsets[f], e = faces.face_offsets[f + 1];
    const int mat = f < topo.face_material.size() ? topo.face_material[f] : -1;
    auto& idx = by_material[mat];
    corners.clear();
    for (int c = b; c < e; ++c)
      corners.push_back(faces.positions[faces.face_vertices[c]]);
    for (const auto& t : detail::triangulate_polygon(corners))
      for (int c : t)
        idx.push_back(static_cast<uint32_t>(corner_out[b + c]));
  }

  // Materials, textures and images of a glTF source.
  std::shared_ptr<const tinygltf::Model> src;
  if (const std::string ext = detail::lower_extension(mesh_path); ext == ".gltf" || ext == ".glb")
    src = detail::read_gltf_scene(mesh_path).model;
  if (src) {
    model.materials = src->materials;
    model.textures = src->textures;
    model.samplers = src->samplers;
    for (const auto& img : src->images) {
      tinygltf::Image out;
      out.name = img.name;
      const std::string data = image_bytes(*src, img, mesh_path);
      out.bufferView = bin.view(data.data(), data.size(), 0);
      out.mimeType = !img.mimeType.empty() ? img.mimeType : mime_of(img.uri);
      model.images.push_back(out);
    }
    const std::set<std::string> geometry_only{"KHR_draco_mesh_compression", "EXT_meshopt_compression",
                                              "KHR_mesh_quantization", "EXT_mesh_gpu_instancing"};
    for (const auto& e : src->extensionsUsed)
      if (!geometry_only.count(e))
        model.extensionsUsed.push_back(e);
    for (const auto& e : src->extensionsRequired)
      if (!geometry_only.count(e))
        model.extensionsRequired.push_back(e);
  }
  tinygltf::Mesh mesh;
  mesh.name = std::filesystem::path(mesh_path).stem().string();
  for (auto& [mat, idx] : by_material) {
    if (idx.empty())
      continue;
    tinygltf::Primitive p = base;
    p.indices = bin.accessor(idx, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT, TINYGLTF_TYPE_SCALAR, idx.size(),
                             TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    p.material = mat >= 0 && mat < static_cast<int>(model.materials.size()) ? mat : -1;
    mesh.primitives.push_back(p);
  }
  model.meshes.push_back(mesh);

  // Where the source puts its skeleton, so that the file at rest shows the
  // skin where the source shows it, and a clip's root keys stay the clip's
  // own: the node that holds the source's root joints (an armature: Blender's
  // exports scale it by 100 and turn it to Y-up) becomes a node above the
  // root joints, and each root rests where the source's skin puts it (its
  // rest skinning matrix times its bind: the bind itself for a file whose
  // inverse bind matrices hold the armature). The inverse bind matrices are
  // the joints' binds either way, and every key's world is what it was:
  // only the rest and the root keys' parent change. Done only where every
  // root of the rig that moves the mesh is a root of the skinned glTF
  // source with the same rest skinning (to a thousandth) there and in the
  // clip file (a clip whose root keys do not carry that placing would jump
  // from the rest to the clip), and not with --up z, which turns the source
  // itself. The roots may rest apart as the source rests them (the wolf's
  // IK roots, which hold its feet, a third of a degree off its body's).
  Mat4 armature = Mat4::Identity();
  std::vector<Mat4> placing(joints.size(), Mat4::Identity()); // each root's
  bool has_armature = false;
  if (options.up == GltfBakeOptions::Up::Y)
    if (const std::string ext = detail::lower_extension(mesh_path);
        (ext == ".gltf" || ext == ".glb") && detail::read_gltf_scene(mesh_path).skin >= 0) {
      std::optional<SkinnedMesh> own;
      try {
        own.emplace(load_skinned_mesh(mesh_path));
      } catch (const InputError&) { // a skin the bake does not use (the rig has its own skeleton): no placing
      }
      // A root's rest skinning matrix in a file, where it is a root there.
      auto root_placing = [](const SkinnedMesh& file, const std::string& name) -> std::optional<Mat4> {
        const std::vector<Mat4> rest = file.skinning_matrices(-1, 0);
        for (size_t j = 0; j < file.joints.size() && j < rest.size(); ++j)
          if (file.joints[j].name == name)
            return file.joints[j].parent ? std::nullopt : std::optional<Mat4>(rest[j]);
        return std::nullopt;
      };
      // The roots whose bones move the mesh (a weighted joint under them). A
      // weightless root neither sets the placing nor blocks it: it rests by
      // the first moving root's. Where no root moves the mesh, every root
      // counts.
      std::vector<char> moves(joints.size(), 0);
      auto mark = [&](int j) {
        for (int p = j; p >= 0 && !moves[static_cast<size_t>(p)];
             p = joints[static_cast<size_t>(p)].parent ? joint_index.at(*joints[static_cast<size_t>(p)].parent) : -1)
          moves[static_cast<size_t>(p)] = 1;
      };
      for (size_t i = 0; i < weights.joint.size(); ++i)
        if (const int j = weights.joint[i]; j >= 0 && weights.weight[i] > 0) {
          if (j < weights.rig_joints()) {
            mark(j);
          } else if (const size_t h = static_cast<size_t>(j - weights.rig_joints()); h < weights.helpers.size()) {
            mark(weights.helpers[h][0]);
            mark(weights.helpers[h][1]);
          }
        }
      const bool any_moves = std::any_of(joints.begin(), joints.end(), [&](const Joint& jt) {
        return !jt.parent && moves[static_cast<size_t>(joint_index.at(jt.name))];
      });
      std::optional<Mat4> first; // the first moving root's placing
      bool agree = own.has_value();
      for (size_t j = 0; j < joints.size() && agree; ++j) {
        if (joints[j].parent || (any_moves && !moves[j]))
          continue;
        std::optional<Mat4> one;
        for (const SkinnedMesh* file : {own ? static_cast<const SkinnedMesh*>(&*own) : nullptr, clips}) {
          if (!file)
            continue;
          const std::optional<Mat4> p = root_placing(*file, joints[j].name);
          agree = p && p->allFinite() &&
                  (!one || (*p - *one).cwiseAbs().maxCoeff() <= 1e-3 * one->cwiseAbs().maxCoeff());
          if (!agree)
            break;
          one = one ? one : p;
        }
        if (!agree || !one)
          break;
        placing[j] = *one;
        first = first ? first : one;
      }
      if (agree && first) {
        armature = own->armature();
        const Mat4 armature_inverse = armature.inverse();
        has_armature = carried_by_trs(armature) && armature_inverse.allFinite();
        bool moved = !armature.isIdentity(1e-9);
        for (size_t j = 0; j < joints.size() && has_armature; ++j)
          if (!joints[j].parent) {
            if (any_moves && !moves[j])
              placing[j] = *first;
            moved = moved || !placing[j].isIdentity(1e-9);
            has_armature = carried_by_trs(Mat4(armature_inverse * placing[j] * joints[j].bind));
          }
        has_armature = has_armature && moved;
      }
    }
  if (!has_armature) {
    armature.setIdentity();
    std::fill(placing.begin(), placing.end(), Mat4::Identity());
  }
  const Mat4 armature_inverse = armature.inverse();
  auto root_rest = [&](int j, const Mat4& bind_world) { // root j's rest, under the armature
    return Mat4(armature_inverse * placing[static_cast<size_t>(j)] * bind_world);
  };

  // The skeleton: node 0 is the skinned mesh, nodes 1.. the joints (then the
  // helpers, then the armature's node).
  const int nj = static_cast<int>(joints.size());
  std::vector<Mat4> bind(nj), rest_local(nj), world(nj);
  for (int j = 0; j < nj; ++j) {
    bind[j] = C * joints[j].bind;
    const int p = joints[j].parent ? joint_index.at(*joints[j].parent) : -1;
    rest_local[j] = p >= 0 ? Mat4(bind[p].inverse() * bind[j]) : bind[j];
  }
  tinygltf::Node mesh_node;
  mesh_node.name = mesh.name;
  mesh_node.mesh = 0;
  mesh_node.skin = 0;
  model.nodes.push_back(mesh_node);
  tinygltf::Skin skin;
  skin.name = "curvenet";
  std::vector<int> roots;
  for (int j = 0; j < nj; ++j) {
    Trs x = decompose(rest_local[j]);
    // The inverse bind matrices are the inverse of the nodes' own rest worlds
    // at the binds, so the skin is exactly at rest in its rest pose (or, with
    // the source's placing, exactly as the source's skin at rest).
    const int p = joints[j].parent ? joint_index.at(*joints[j].parent) : -1;
    world[j] = p >= 0 ? Mat4(world[p] * compose(x)) : compose(x);
    if (p < 0 && has_armature)
      x = decompose(root_rest(j, rest_local[j]));
    tinygltf::Node n;
    n.name = joints[j].name;
    n.translation = {x.t.x(), x.t.y(), x.t.z()};
    n.rotation = {x.r.x(), x.r.y(), x.r.z(), x.r.w()};
    n.scale = {x.s.x(), x.s.y(), x.s.z()};
    model.nodes.push_back(n);
    skin.joints.push_back(1 + j);
    if (p >= 0)
      model.nodes[1 + p].children.push_back(1 + j);
    else
      roots.push_back(1 + j);
  }
  // The clips to carry, and each key's local and posed world transforms
  // (each joint's rest local times its pose entry, one key per frame).
  std::vector<int> carried;
  if (clips) {
    for (const auto& name : options.clips)
      if (clips->find_clip(name) < 0)
        throw InputError(clips->source, "clip '" + name + "'", "no clip has this name");
    int matched = 0;
    for (const auto& j : clips->joints)
      matched += joint_index.count(j.name) > 0;
    if (clips->num_clips() > 0 && matched == 0)
      throw InputError(clips->source, "skin", "no joint of the clip's skeleton matches a joint of the rig by name");
    // Each named clip as find_clip finds it ("Walk" for "AnimalArmature|Walk"), in the file's order.
    std::set<int> named;
    for (const auto& name : options.clips)
      named.insert(clips->find_clip(name));
    for (int c = 0; c < clips->num_clips(); ++c)
      if (named.empty() || named.count(c))
        carried.push_back(c);
  }
  auto key_times = [&](int c) {
    const auto [t0, t1] = clips->clip_range(c);
    const double span = std::ceil((t1 - t0) * options.fps - 1e-9);
    if (!(span < kMaxKeys))
      throw InputError(clips->source, "clip '" + clips->clip_names[static_cast<size_t>(c)] + "'",
                       "it comes to more than " + std::to_string(static_cast<long long>(kMaxKeys)) +
                           " keys at the fps of the bake");
    const int keys = std::max(2, static_cast<int>(span) + 1);
    std::vector<float> times;
    for (int i = 0; i < keys; ++i)
      times.push_back(static_cast<float>(std::min(t1, t0 + i / options.fps)));
    if (times.size() >= 2 && times[times.size() - 1] <= times[times.size() - 2])
      times.back() = std::nextafter(times[times.size() - 2], std::numeric_limits<float>::infinity());
    return times;
  };
  auto pose_at = [&](int c, double time, std::vector<Mat4>& local, std::vector<Mat4>& posed,
                     std::vector<bool>& animated) {
    const Pose pose = clip_pose_for(joints, *clips, c, time);
    for (int j = 0; j < nj; ++j) {
      const auto it = pose.find(joints[j].name);
      local[j] = rest_local[j];
      if (it != pose.end()) {
        animated[j] = true;
        local[j] = rest_local[j] * it->second.matrix();
      }
      const int p = joints[j].parent ? joint_index.at(*joints[j].parent) : -1;
      posed[j] = p >= 0 ? Mat4(posed[p] * local[j]) : local[j];
    }
  };

  // Helper joints, after the rig's: a helper's skinning matrix is the mean
  // of its joints' (helper_matrix). It is a node under the deeper of its two
  // joints, at that joint's rest frame (its local the identity at rest), so
  // that an engine that does not drive it still carries it with the limb.
  // Where a clip scales that joint so that no local translation, rotation
  // and scale under it carries the helper (a shear), or flattens it, the
  // helper is a root node instead, at a rigid frame scaled as that joint is
  // at rest: a similarity times a similarity, which a node carries exactly.
  auto depth = [&](int j) {
    int d = 0;
    for (int p = j; joints[p].parent; p = joint_index.at(*joints[p].parent))
      ++d;
    return d;
  };
  const int nh = static_cast<int>(weights.helpers.size());
  std::vector<int> helper_parent(nh);
  for (int h = 0; h < nh; ++h) {
    const auto [a, b] = weights.helpers[h];
    helper_parent[h] = depth(b) > depth(a) ? b : a;
  }
  std::vector<Mat4> unbind(nj); // the joints' rest worlds inverted, once
  for (int j = 0; j < nj; ++j)
    unbind[j] = world[j].inverse();
  auto helper_skinning = [&](int h, const std::vector<Mat4>& posed) {
    const auto [a, b] = weights.helpers[h];
    return helper_matrix(Mat4(posed[a] * unbind[a]), Mat4(posed[b] * unbind[b]));
  };
  auto under_parent = [&](int h, const std::vector<Mat4>& posed, const Mat4& S) {
    const int p = helper_parent[h];
    return Mat4(posed[p].inverse() * S * world[p]);
  };
  std::vector<char> rooted(nh, 0);
  if (nh > 0 && clips) {
    std::vector<Mat4> local(nj), posed(nj);
    std::vector<bool> animated(nj, false);
    for (const int c : carried)
      for (const float time : key_times(c)) {
        pose_at(c, time, local, posed, animated);
        for (int h = 0; h < nh; ++h)
          if (!rooted[h])
            rooted[h] = !carried_by_trs(under_parent(h, posed, helper_skinning(h, posed)));
      }
  }
  std::vector<Mat4> helper_rest(nh); // the rest world of a rooted helper
  std::vector<int> helper_roots;
  for (int h = 0; h < nh; ++h) {
    const Mat4& W = world[helper_parent[h]];
    const int j = nj + h;
    tinygltf::Node n;
    n.name = weights.joints[static_cast<size_t>(j)];
    for (const auto& other : joints)
      if (other.name == n.name)
        throw InputError(mesh_path, "helper joint '" + n.name + "'", "a joint of the skeleton has its name");
    const auto [a, b] = weights.helpers[h];
    tinygltf::Value::Array between{tinygltf::Value(joints[a].name), tinygltf::Value(joints[b].name)};
    tinygltf::Value::Object extras;
    extras["curvenet_helper"] = tinygltf::Value(between);
    n.extras = tinygltf::Value(extras);
    if (rooted[h]) {
      Mat4 R = Mat4::Identity();
      const Eigen::Matrix3d w3 = W.topLeftCorner<3, 3>();
      R.topLeftCorner<3, 3>() = std::cbrt(std::abs(w3.determinant())) * decompose(W).r.toRotationMatrix();
      R.block<3, 1>(0, 3) = W.block<3, 1>(0, 3);
      helper_rest[h] = R;
      int top = helper_parent[h]; // placed as the root above its joint is
      while (joints[static_cast<size_t>(top)].parent)
        top = joint_index.at(*joints[static_cast<size_t>(top)].parent);
      const Trs x = decompose(has_armature ? root_rest(top, R) : R);
      n.translation = {x.t.x(), x.t.y(), x.t.z()};
      n.rotation = {x.r.x(), x.r.y(), x.r.z(), x.r.w()};
      n.scale = {x.s.x(), x.s.y(), x.s.z()};
      world.push_back(R);
      helper_roots.push_back(1 + j);
    } else {
      world.push_back(W);
      model.nodes[1 + helper_parent[h]].children.push_back(1 + j);
    }
    model.nodes.push_back(n);
    skin.joints.push_back(1 + j);
  }
  std::vector<float> ibm;
  for (int j = 0; j < nj + nh; ++j) {
    const Mat4 inv = world[j].inverse();
    if (!inv.allFinite())
      throw InputError(mesh_path, "joint '" + weights.joints[static_cast<size_t>(j)] + "'",
                       "its rest transform is singular");
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        ibm.push_back(static_cast<float>(inv(r, c))); // column-major
  }
  skin.inverseBindMatrices = bin.accessor(ibm, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_MAT4, nj + nh, 0);
  // The skeleton root, where one joint is the root of all and no armature
  // node holds it: Blender's importer takes the joints' rest from that node
  // down, without the armature above it, so a bake of a Blender re-export
  // (whose inverse bind matrices hold the armature) rested turned by the
  // armature's quarter turn. The source leaves it out too.
  if (roots.size() == 1 && armature.isIdentity(1e-9))
    skin.skeleton = roots[0];
  model.skins.push_back(skin);
  tinygltf::Scene scene;
  scene.name = "curvenet bake";
  scene.nodes.push_back(0);
  if (!armature.isIdentity(1e-9)) {
    tinygltf::Node a;
    a.name = "Armature";
    const Trs x = decompose(armature);
    a.translation = {x.t.x(), x.t.y(), x.t.z()};
    a.rotation = {x.r.x(), x.r.y(), x.r.z(), x.r.w()};
    a.scale = {x.s.x(), x.s.y(), x.s.z()};
    a.children = roots;
    a.children.insert(a.children.end(), helper_roots.begin(), helper_roots.end());
    scene.nodes.push_back(static_cast<int>(model.nodes.size()));
    model.nodes.push_back(a);
  } else {
    scene.nodes.insert(scene.nodes.end(), roots.begin(), roots.end());
    scene.nodes.insert(scene.nodes.end(), helper_roots.begin(), helper_roots.end());
  }
  model.scenes.push_back(scene);
  model.defaultScene = 0;

  // Clips, retargeted by joint name, one key per frame.
  if (clips) {
    for (const int c : carried) {
      const std::vector<float> times = key_times(c);
      const int keys = static_cast<int>(times.size());
      std::vector<std::vector<float>> tr(nj + nh), rot(nj + nh), sc(nj + nh);
      std::vector<bool> animated(nj + nh, false);
      std::vector<Mat4> local(nj + nh), posed(nj);
      for (int i = 0; i < keys; ++i) {
        pose_at(c, times[i], local, posed, animated);
        for (int h = 0; h < nh; ++h) {
          const Mat4 S = helper_skinning(h, posed);
          local[nj + h] = rooted[h] ? Mat4(S * helper_rest[h]) : under_parent(h, posed, S);
          animated[nj + h] = true;
        }
        for (int j = 0; j < nj + nh; ++j) {
          if (!animated[j])
            continue;
          const bool top = j < nj ? !joints[j].parent : rooted[j - nj] != 0; // a child of the armature's node
          const Trs x = decompose(top && has_armature ? Mat4(armature_inverse * local[j]) : local[j]);
          Eigen::Quaterniond q = x.r;
          if (!rot[j].empty()) {
            const size_t b = rot[j].size() - 4;
            const Eigen::Quaterniond prev(rot[j][b + 3], rot[j][b], rot[j][b + 1], rot[j][b + 2]);
            if (prev.dot(q) < 0)
              q.coeffs() = -q.coeffs(); // the short way round
          }
          for (int d = 0; d < 3; ++d) {
            tr[j].push_back(static_cast<float>(x.t[d]));
            sc[j].push_back(static_cast<float>(x.s[d]));
          }
          for (double v : {q.x(), q.y(), q.z(), q.w()})
            rot[j].push_back(static_cast<float>(v));
        }
      }
      tinygltf::Animation anim;
      anim.name = clips->clip_names[c];
      const int input =
          bin.accessor(times, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_SCALAR, times.size(), 0, true, 1);
      auto channel = [&](int j, const std::vector<float>& values, int type, const char* path) {
        tinygltf::AnimationSampler s;
        s.input = input;
        s.output = bin.accessor(values, TINYGLTF_COMPONENT_TYPE_FLOAT, type, times.size(), 0);
        s.interpolation = "LINEAR";
        anim.samplers.push_back(s);
        tinygltf::AnimationChannel ch;
        ch.sampler = static_cast<int>(anim.samplers.size()) - 1;
        ch.target_node = 1 + j;
        ch.target_path = path;
        anim.channels.push_back(ch);
      };
      for (int j = 0; j < nj + nh; ++j) {
        if (!animated[j])
          continue;
        for (float x : tr[j])
          if (!std::isfinite(x))
            throw InputError(clips->source, "clip '" + anim.name + "' joint '" + weights.joints[j] + "'",
                             "moves out of the range of single precision");
        channel(j, tr[j], TINYGLTF_TYPE_VEC3, "translation");
        channel(j, rot[j], TINYGLTF_TYPE_VEC4, "rotation");
        channel(j, sc[j], TINYGLTF_TYPE_VEC3, "scale");
      }
      if (!anim.channels.empty())
        model.animations.push_back(anim);
    }
  }

  model.buffers[0].name = "curvenet";
  std::ostringstream out;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, out, false, true))
    throw Error("bake: the glTF writer failed");
  return out.str();
}

} // namespace curvenet
