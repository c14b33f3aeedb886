#pragma once
/// \file scene.hpp
/// The inputs of a deforming job, read once and bound: the mesh file, the
/// rig (its skeleton replaced by another file's when one is given) and the
/// binding, through a cache file when one is named. Every job in jobs.hpp,
/// and so every front end, starts here.

#include "curvenet/deform.hpp"
#include "curvenet/io.hpp"

#include <string>
#include <vector>

namespace curvenet {

/// The files a deforming job reads.
struct SceneFiles {
  std::string mesh;          ///< OBJ, glTF/GLB, PLY, OFF or FBX
  std::string rig;           ///< `*.cnrig.json`
  std::string skeleton;      ///< optional: a rig or skinned file whose joints replace the rig's, by name
  std::string binding_cache; ///< optional: a binding cache file, read when it fits, written when not
};

/// The rig of `files`, with its skeleton replaced by `files.skeleton`'s when
/// given, as bound: with no mesh read, the skeleton file's joints are not
/// placed for one (read_scene() places them; read_skeleton_file()).
/// \throw InputError naming the rig when it has no skeleton either way.
Rig read_scene_rig(const SceneFiles& files);

/// The repairs made on load that change the surface the engine works on
/// (degenerate or doubled faces left out, faces turned, open seams closed),
/// one line each, naming the file.
std::vector<std::string> load_notes(const SurfaceMesh& mesh, const std::string& path);

/// The mesh and the rig of a job, each file read once.
struct Scene {
  SceneFiles files;
  SurfaceMesh mesh;
  Rig rig;
  std::vector<std::string> notes; ///< load_notes() of the mesh
};
/// \throw InputError for a bad mesh, rig or skeleton file.
Scene read_scene(const SceneFiles& files);

struct BoundScene : Scene {
  Binding binding;
};

/// Binds the scene's rig to its mesh. A new binding cache joins `outputs`
/// (written when they are committed, with the job's other outputs or not
/// at all).
/// \throw EmbedError, naming the rig file, when the rig does not embed.
BoundScene bind_scene(Scene scene, const BindOptions& options, OutputFiles& outputs);
/// read_scene() and bind_scene().
BoundScene bind_scene(const SceneFiles& files, const BindOptions& options, OutputFiles& outputs);

} // namespace curvenet
