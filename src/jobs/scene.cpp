// A deforming job's inputs, read once and bound.

#include "curvenet/scene.hpp"

#include "curvenet/errors.hpp"
#include "curvenet/skin.hpp"

#include <filesystem>

namespace curvenet {

Rig read_scene_rig(const SceneFiles& files) {
  Rig rig = read_rig(files.rig);
  if (!files.skeleton.empty())
    rig = with_skeleton(std::move(rig), load_skeleton(files.skeleton), files.skeleton);
  if (!rig.has_skeleton)
    throw InputError(files.rig, "/skeleton", "the rig has no skeleton: give one in the rig or with --skeleton");
  return rig;
}

std::vector<std::string> load_notes(const SurfaceMesh& mesh, const std::string& path) {
  std::vector<std::string> notes;
  for (const auto& n : mesh.notes)
    if (n.rfind("left out", 0) == 0 || n.rfind("repaired", 0) == 0 || n.rfind("closed open seams", 0) == 0 ||
        n.rfind("kept ", 0) == 0 || n.rfind("turned ", 0) == 0)
      notes.push_back(std::filesystem::path(path).filename().string() + ": " + n);
  return notes;
}

Scene read_scene(const SceneFiles& files) {
  Scene s;
  s.files = files;
  s.mesh = load_mesh(files.mesh);
  s.notes = load_notes(s.mesh, files.mesh);
  // A skeleton file is placed for the mesh (read_skeleton_file): a
  // Blender OBJ and the glTF its skeleton comes from are in other spaces.
  if (files.skeleton.empty()) {
    s.rig = read_scene_rig(files);
  } else {
    SkeletonFile skeleton = read_skeleton_file(files.skeleton, s.mesh);
    if (!skeleton.note.empty())
      s.notes.push_back(skeleton.note);
    s.rig = with_skeleton(read_rig(files.rig), std::move(skeleton.joints), files.skeleton);
  }
  return s;
}

BoundScene bind_scene(Scene scene, const BindOptions& options, OutputFiles& outputs) {
  const SceneFiles& f = scene.files;
  try {
    Binding binding = f.binding_cache.empty()
                          ? bind(scene.mesh, scene.rig, options)
                          : bind_cached(scene.mesh, scene.rig, options, f.binding_cache, nullptr, &outputs);
    return {std::move(scene), std::move(binding)};
  } catch (const EmbedError& e) {
    throw EmbedError(f.rig + ": " + e.what()); // an embedding failure names the rig file
  }
}

BoundScene bind_scene(const SceneFiles& files, const BindOptions& options, OutputFiles& outputs) {
  return bind_scene(read_scene(files), options, outputs);
}

} // namespace curvenet
