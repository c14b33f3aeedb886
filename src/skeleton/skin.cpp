#include "curvenet/skin.hpp"
#include "curvenet/surface_mesh.hpp"

#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "io/assimp_scene.hpp"
#include "io/file_bytes.hpp"
#include "io/gltf_scene.hpp"

#include <tiny_gltf.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <iomanip>
#include <set>
#include <sstream>

#include "core/dual_quaternion.hpp"
#include "core/matrix_checks.hpp"
#include "core/numbers.hpp"
#include <cmath>
#include <filesystem>
#include <limits>

namespace curvenet {

SkinnedMesh load_skinned_mesh_assimp(const std::string& path) {
  detail::AssimpScene a = detail::read_assimp_scene(path);
  if (a.joints.empty())
    throw InputError(path, "", "the file has no skinned mesh (no bones to take a skeleton from)");
  SkinnedMesh out;
  out.source = path;
  out.joints = std::move(a.joints);
  for (const auto& j : out.joints)
    out.inverse_bind.push_back(j.bind.inverse());
  out.vertex_joint = std::move(a.vertex_joint);
  out.vertex_weight = std::move(a.vertex_weight);
  return out; // no clips: animation comes from glTF files
}

std::vector<Joint> skin_joints_if_any(const std::string& path) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".fbx")
    return detail::read_assimp_scene(path).joints; // parsed once; no bones, no joints
  if ((ext == ".gltf" || ext == ".glb") && detail::read_gltf_scene(path).skin >= 0)
    return load_skinned_mesh(path).joints; // the parse above is kept, not repeated
  return {};
}

SkinnedMesh load_skinned_mesh(const std::string& path) {
  const std::string ext = detail::lower_extension(path);
  if (ext == ".fbx")
    return load_skinned_mesh_assimp(path);
  if (ext != ".gltf" && ext != ".glb")
    throw InputError(path, "", "skins are read from glTF, GLB or FBX files");
  auto scene = std::make_shared<detail::GltfScene>(detail::read_gltf_scene(path));
  if (scene->skin < 0)
    throw InputError(path, "", "the file has no skinned mesh (no skin to take a skeleton from)");
  const auto& model = *scene->model;
  const auto& skin = model.skins.at(scene->skin);
  const auto ibm = detail::inverse_bind_matrices(*scene);
  const int nslots = static_cast<int>(skin.joints.size());
  {
    // Singular matrices would give NaN joints (and `null` in a rig written from them).
    const auto world = detail::node_world_matrices(*scene, -1, 0);
    for (int s = 0; s < nslots; ++s) {
      if (!detail::invertible(ibm[s]))
        throw InputError(path, "skin " + std::to_string(scene->skin) + " inverseBindMatrices " + std::to_string(s),
                         "is singular");
      if (!detail::invertible(world[skin.joints[s]]))
        throw InputError(path, "node " + std::to_string(skin.joints[s]), "the joint's world matrix is singular");
    }
  }
  std::vector<int> slot_of_node(model.nodes.size(), -1);
  for (int s = 0; s < nslots; ++s)
    slot_of_node.at(skin.joints[s]) = s;
  // Parent slot: nearest ancestor node that is a joint.
  std::vector<int> parent_slot(nslots, -1);
  for (int s = 0; s < nslots; ++s)
    for (int n = scene->node_parent[skin.joints[s]]; n >= 0; n = scene->node_parent[n])
      if (slot_of_node[n] >= 0) {
        parent_slot[s] = slot_of_node[n];
        break;
      }
  // Order: parents first, otherwise the skin's order.
  std::vector<int> order, joint_of_slot(nslots, -1);
  std::vector<char> placed(nslots, 0);
  while (static_cast<int>(order.size()) < nslots) {
    bool progress = false;
    for (int s = 0; s < nslots; ++s)
      if (!placed[s] && (parent_slot[s] < 0 || placed[parent_slot[s]])) {
        joint_of_slot[s] = static_cast<int>(order.size());
        order.push_back(s);
        placed[s] = 1;
        progress = true;
      }
    if (!progress)
      throw InputError(path, "skin " + std::to_string(scene->skin), "joint hierarchy has a cycle");
  }
  SkinnedMesh out;
  out.source = path;
  auto name_of = [&](int slot) {
    const auto& node = model.nodes[skin.joints[slot]];
    return node.name.empty() ? "joint" + std::to_string(skin.joints[slot]) : node.name;
  };
  std::vector<std::string> names;
  for (int s : order) {
    Joint j;
    j.name = name_of(s);
    if (std::find(names.begin(), names.end(), j.name) != names.end())
      throw InputError(path, "node " + std::to_string(skin.joints[s]), "joint name '" + j.name + "' is not unique");
    names.push_back(j.name);
    if (parent_slot[s] >= 0)
      j.parent = name_of(parent_slot[s]);
    j.bind = ibm[s].inverse();
    j.bind.row(3) << 0, 0, 0, 1;
    out.joints.push_back(j);
    out.inverse_bind.push_back(ibm[s]);
    out.joint_node.push_back(skin.joints[s]);
  }
  const size_t nv = scene->mesh.positions.size();
  out.vertex_joint.assign(nv, {-1, -1, -1, -1});
  out.vertex_weight.assign(nv, {0, 0, 0, 0});
  for (size_t v = 0; v < nv; ++v) {
    double sum = 0;
    for (int k = 0; k < 4; ++k) {
      const int s = scene->vertex_joint[v][k];
      if (s < 0)
        continue;
      if (s >= nslots)
        throw InputError(path, "vertex " + std::to_string(v),
                         "JOINTS_0 names joint slot " + std::to_string(s) + " of " + std::to_string(nslots));
      out.vertex_joint[v][k] = joint_of_slot[s];
      out.vertex_weight[v][k] = scene->vertex_weight[v][k];
      sum += scene->vertex_weight[v][k];
    }
    if (sum > 0)
      for (double& w : out.vertex_weight[v])
        w /= sum;
  }
  for (const auto& a : model.animations)
    out.clip_names.push_back(a.name);
  out.scene = scene;
  return out;
}

int SkinnedMesh::find_clip(const std::string& key) const {
  for (int c = 0; c < num_clips(); ++c)
    if (clip_names[c] == key)
      return c;
  if (!key.empty() && std::all_of(key.begin(), key.end(), [](unsigned char ch) { return std::isdigit(ch); })) {
    long long i = 0;
    if (detail::parse_whole(key, i) && i < num_clips())
      return static_cast<int>(i);
  }
  // Blender's exporter names a clip "Armature|Walk": "Walk" finds it when no
  // other clip ends the same way.
  int found = -1;
  for (int c = 0; c < num_clips(); ++c) {
    const std::string& n = clip_names[c];
    const size_t bar = n.rfind('|');
    if (!key.empty() && bar != std::string::npos && n.compare(bar + 1, std::string::npos, key) == 0) {
      if (found >= 0)
        return -1; // ambiguous
      found = c;
    }
  }
  return found;
}

std::pair<double, double> SkinnedMesh::clip_range(int clip) const {
  const auto& model = *scene->model;
  const auto& anim = model.animations.at(clip);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const auto& sampler : anim.samplers) {
    const auto& acc = model.accessors.at(sampler.input);
    if (acc.minValues.size() == 1 && acc.maxValues.size() == 1) {
      lo = std::min(lo, acc.minValues[0]);
      hi = std::max(hi, acc.maxValues[0]);
    }
  }
  if (!(lo <= hi))
    return {0, 0};
  return {lo, hi};
}

std::vector<Mat4> SkinnedMesh::joint_world(int clip, double t) const {
  if (!scene) { // a skin without clips (FBX): the rest pose
    std::vector<Mat4> rest;
    for (const auto& j : joints)
      rest.push_back(j.bind);
    return rest;
  }
  const auto world = detail::node_world_matrices(*scene, clip, t);
  std::vector<Mat4> out;
  out.reserve(joint_node.size());
  for (int n : joint_node)
    out.push_back(world[n]);
  return out;
}

Mat4 SkinnedMesh::armature() const {
  if (!scene)
    return Mat4::Identity();
  std::set<int> holders; // the parent nodes of the root joints
  for (size_t j = 0; j < joints.size() && j < joint_node.size(); ++j)
    if (!joints[j].parent)
      holders.insert(scene->node_parent[static_cast<size_t>(joint_node[j])]);
  if (holders.size() != 1 || *holders.begin() < 0)
    return Mat4::Identity();
  const Mat4 a = detail::node_world_matrices(*scene, -1, 0)[static_cast<size_t>(*holders.begin())];
  return a.allFinite() ? a : Mat4::Identity();
}

std::vector<Mat4> SkinnedMesh::rest_placing() const {
  std::vector<Mat4> out(joints.size(), Mat4::Identity());
  if (!scene)
    return out;
  const std::vector<Mat4> rest = skinning_matrices(-1, 0);
  std::map<std::string, size_t> index;
  for (size_t j = 0; j < joints.size(); ++j)
    index[joints[j].name] = j;
  auto similarity = [](const Mat4& m) {
    if (!m.allFinite() || m.row(3) != Eigen::RowVector4d(0, 0, 0, 1))
      return false;
    const Eigen::Matrix3d a = m.topLeftCorner<3, 3>();
    const double det = a.determinant();
    if (!(det > 0))
      return false;
    const double s = std::cbrt(det);
    return ((a.transpose() * a) / (s * s) - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() <= 1e-4;
  };
  for (size_t j = 0; j < joints.size() && j < rest.size(); ++j) {
    size_t root = j;
    for (int hops = 0; joints[root].parent && hops < static_cast<int>(joints.size()); ++hops) {
      const auto it = index.find(*joints[root].parent);
      if (it == index.end())
        break;
      root = it->second;
    }
    if (root < rest.size() && similarity(rest[root]))
      out[j] = rest[root];
  }
  return out;
}

std::vector<std::vector<Mat4>> SkinnedMesh::scene_placings() const {
  Eigen::AlignedBox3d box;
  for (const Joint& j : joints)
    box.extend(Vec3(j.bind.block<3, 1>(0, 3)));
  const double extent = joints.empty() ? 0.0 : box.diagonal().norm();
  auto places = [&](const Mat4& m) {
    return m.allFinite() && ((m.topLeftCorner<3, 3>() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
                             m.block<3, 1>(0, 3).norm() > 1e-6 * extent);
  };
  std::vector<std::vector<Mat4>> ways;
  if (const Mat4 a = armature(); places(a))
    ways.emplace_back(joints.size(), a);
  if (std::vector<Mat4> rest = rest_placing(); std::any_of(rest.begin(), rest.end(), places))
    ways.push_back(std::move(rest));
  return ways;
}

std::vector<Mat4> SkinnedMesh::skinning_matrices(int clip, double t) const {
  auto m = joint_world(clip, t);
  for (size_t j = 0; j < m.size(); ++j)
    m[j] = m[j] * inverse_bind[j];
  return m;
}

std::vector<Eigen::Vector3d> skin_positions(const SkinnedMesh& skin, const std::vector<Eigen::Vector3d>& positions,
                                            const std::vector<Mat4>& matrices, Skinning method) {
  std::vector<Eigen::Vector3d> out(positions.size());
  std::vector<detail::DualJoint> dual;
  if (method == Skinning::DualQuaternion)
    for (const Mat4& m : matrices)
      dual.push_back(detail::split_joint(m));
  detail::DualBlend blend;
  for (size_t v = 0; v < positions.size(); ++v) {
    Eigen::Vector4d acc = Eigen::Vector4d::Zero();
    double total = 0;
    blend.clear();
    for (int k = 0; k < 4; ++k) {
      const int j = skin.vertex_joint[v][k];
      const double w = skin.vertex_weight[v][k];
      if (j < 0 || !(w > 0))
        continue;
      if (method == Skinning::DualQuaternion)
        blend.add(dual[j], w);
      else
        acc += w * (matrices[j] * positions[v].homogeneous());
      total += w;
    }
    if (!(total > 0))
      out[v] = positions[v];
    else if (method == Skinning::Linear)
      out[v] = acc.head<3>();
    else
      out[v] = blend.valid() ? blend.apply(positions[v]) : positions[v];
  }
  return out;
}

std::set<std::string> weighted_joints(const SkinnedMesh& skin) {
  std::set<std::string> out;
  for (size_t v = 0; v < skin.vertex_joint.size(); ++v)
    for (int k = 0; k < 4; ++k) {
      const int j = skin.vertex_joint[v][k];
      if (j >= 0 && static_cast<size_t>(j) < skin.joints.size() && skin.vertex_weight[v][k] > 0)
        out.insert(skin.joints[j].name);
    }
  return out;
}

bool is_skinned_file(const std::string& path) {
  const std::string ext = detail::lower_extension(path);
  return ext == ".gltf" || ext == ".glb" || ext == ".fbx";
}

SkeletonFile read_skeleton_file(const std::string& path) {
  if (is_skinned_file(path)) {
    SkinnedMesh skin = load_skinned_mesh(path);
    std::set<std::string> deforming = weighted_joints(skin);
    return {std::move(skin.joints), std::move(deforming), ""};
  }
  Rig rig = read_rig(path);
  if (!rig.has_skeleton)
    throw InputError(path, "/skeleton", "the rig file has no skeleton");
  return {std::move(rig.joints), {}, ""};
}

std::vector<Joint> load_skeleton(const std::string& path) {
  return read_skeleton_file(path).joints;
}

namespace {

/// The share of a skeleton's joints and bones' middles that lie inside the
/// mesh (winding number a half or more, either way round: an inside-out
/// mesh holds them too): at most 64 of them, evenly spread over the list
/// (the same ones for every placing of one skeleton), in parallel, as each
/// costs a pass over the faces.
double share_inside(const std::vector<Joint>& joints, const SurfaceMesh& mesh) {
  std::map<std::string, Vec3> at;
  for (const Joint& j : joints)
    at[j.name] = j.bind.block<3, 1>(0, 3);
  std::vector<Vec3> points;
  for (const Joint& j : joints) {
    const Vec3 p = at[j.name];
    points.push_back(p);
    if (j.parent)
      if (const auto it = at.find(*j.parent); it != at.end())
        points.push_back((p + it->second) / 2);
  }
  if (points.empty())
    return 0.0;
  constexpr size_t most = 64;
  if (points.size() > most) {
    std::vector<Vec3> some;
    for (size_t k = 0; k < most; ++k)
      some.push_back(points[k * points.size() / most]);
    points = std::move(some);
  }
  std::vector<char> inside(points.size(), 0);
  tbb::parallel_for(size_t{0}, points.size(),
                    [&](size_t k) { inside[k] = std::abs(mesh.winding_number(points[k])) >= 0.5; });
  return static_cast<double>(std::count(inside.begin(), inside.end(), 1)) / static_cast<double>(points.size());
}

} // namespace

SkeletonFile read_skeleton_file(const std::string& path, const SurfaceMesh& mesh) {
  const std::string ext = detail::lower_extension(path);
  if ((ext != ".gltf" && ext != ".glb") || mesh.positions.empty()) // an FBX has no node hierarchy read: bound
    return read_skeleton_file(path);
  SkinnedMesh skin = load_skinned_mesh(path);
  SkeletonFile file{skin.joints, weighted_joints(skin), ""};
  // The ways the file's scene may show its joints (placed_by_armature):
  // under its armature at their binds, or at their roots' rest. The one
  // that lies inside the mesh, by the share of its joints and bones'
  // middles the mesh winds round, is taken where it lies inside (half or
  // more) and the bound skeleton clearly less (by a quarter).
  const std::vector<std::vector<Mat4>> ways = skin.scene_placings();
  if (ways.empty())
    return file;
  const double bound = share_inside(file.joints, mesh);
  double best = 0;
  std::vector<Joint> chosen;
  for (const auto& way : ways) {
    std::vector<Joint> placed = file.joints;
    for (size_t j = 0; j < placed.size(); ++j)
      placed[j].bind = way[j] * placed[j].bind;
    if (const double in = share_inside(placed, mesh); in > best) {
      best = in;
      chosen = std::move(placed);
    }
  }
  if (!(best >= 0.5 && best >= bound + 0.25))
    return file;
  file.joints = std::move(chosen);
  std::ostringstream note;
  note << std::filesystem::path(path).filename().string() << ": its joints lie inside "
       << std::filesystem::path(mesh.source).filename().string() << " as the file's scene places them ("
       << std::lround(100 * best) << "% of its joints and bones' middles, against " << std::lround(100 * bound)
       << "% as bound): taken as placed (a mesh exported in the scene's space, as Blender writes an OBJ)";
  file.note = note.str();
  return file;
}

Rig with_skeleton(Rig rig, std::vector<Joint> joints, const std::string& source) {
  std::set<std::string> names;
  for (const auto& j : joints)
    names.insert(j.name);
  for (const auto& [node, w] : rig.weights)
    for (const auto& [joint, v] : w)
      if (!names.count(joint))
        throw InputError(source, joint,
                         "the rig's weights for node '" + node + "' name this joint, which the skeleton lacks");
  rig.joints = std::move(joints);
  rig.has_skeleton = true;
  return rig;
}

} // namespace curvenet
