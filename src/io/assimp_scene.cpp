#include "io/assimp_scene.hpp"

#include "curvenet/errors.hpp"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <map>
#include <set>

namespace curvenet::detail {
namespace {

Mat4 to_eigen(const aiMatrix4x4& m) {
  Mat4 e;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      e(r, c) = m[r][c]; // assimp is row-major and acts on column vectors, as we do
  return e;
}

} // namespace

AssimpScene read_assimp_scene(const std::string& path) {
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(path, aiProcess_JoinIdenticalVertices);
  if (!scene || !scene->mRootNode || (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE))
    throw InputError(path, "", std::string("cannot read mesh: ") + importer.GetErrorString());
  AssimpScene out;
  RawMesh& raw = out.mesh;
  // Bones by name: bind = world of the skinned mesh's node * inverse(offset).
  std::map<std::string, Mat4> bind;
  std::vector<std::vector<std::pair<std::string, double>>> influences;
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
      influences.resize(raw.positions.size());
      for (unsigned b = 0; b < mesh->mNumBones; ++b) {
        const aiBone* bone = mesh->mBones[b];
        const std::string name = bone->mName.C_Str();
        bind.emplace(name, to_eigen(world) * to_eigen(bone->mOffsetMatrix).inverse());
        for (unsigned w = 0; w < bone->mNumWeights; ++w)
          if (bone->mWeights[w].mWeight > 0 && bone->mWeights[w].mVertexId < mesh->mNumVertices)
            influences[base + bone->mWeights[w].mVertexId].emplace_back(name, bone->mWeights[w].mWeight);
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
  influences.resize(raw.positions.size());
  // Joints: the bones, each with its nearest ancestor node that is a bone as parent.
  std::map<std::string, std::string> parent;
  std::vector<std::string> order; // depth-first from the root: parents first
  std::vector<const aiNode*> walk{scene->mRootNode};
  while (!walk.empty()) {
    const aiNode* n = walk.back();
    walk.pop_back();
    const std::string name = n->mName.C_Str();
    if (bind.count(name)) {
      order.push_back(name);
      for (const aiNode* a = n->mParent; a; a = a->mParent)
        if (bind.count(a->mName.C_Str())) {
          parent[name] = a->mName.C_Str();
          break;
        }
    }
    for (unsigned c = n->mNumChildren; c-- > 0;)
      walk.push_back(n->mChildren[c]);
  }
  std::map<std::string, int> index;
  for (const std::string& name : order) {
    Joint j;
    j.name = name;
    if (parent.count(name))
      j.parent = parent[name];
    j.bind = bind[name];
    j.bind.row(3) << 0, 0, 0, 1;
    index[name] = static_cast<int>(out.joints.size());
    out.joints.push_back(j);
  }
  out.vertex_joint.assign(raw.positions.size(), {-1, -1, -1, -1});
  out.vertex_weight.assign(raw.positions.size(), {0, 0, 0, 0});
  for (size_t v = 0; v < influences.size(); ++v) {
    auto& list = influences[v];
    std::sort(list.begin(), list.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
    double sum = 0;
    for (size_t k = 0; k < list.size() && k < 4; ++k)
      if (index.count(list[k].first)) {
        out.vertex_joint[v][k] = index[list[k].first];
        out.vertex_weight[v][k] = list[k].second;
        sum += list[k].second;
      }
    if (sum > 0)
      for (double& w : out.vertex_weight[v])
        w /= sum;
  }
  return out;
}

} // namespace curvenet::detail
