#pragma once
/// \file io.hpp
/// Reading and writing meshes and rig files. Every reader validates its input
/// and throws InputError naming the file and the element at fault. Every
/// writer writes to a temporary file and renames it, so a failed write never
/// leaves a partial file behind.

#include "curvenet/rig.hpp"
#include "curvenet/surface_mesh.hpp"

#include <memory>
#include <ostream>
#include <string>

namespace curvenet {

/// Reads OBJ and PLY or OFF (readers of our own), glTF/GLB (tinygltf), or FBX
/// (assimp), then validates and welds it (make_surface_mesh).
/// \throw InputError for an unreadable file or an invalid mesh.
SurfaceMesh load_mesh(const std::string& path);

/// Reads the polygons of a mesh file without validating them.
/// \throw InputError for an unreadable file.
RawMesh read_raw_mesh(const std::string& path);

/// Reads and validates a rig file (`*.cnrig.json`).
/// \throw InputError with the JSON path of the fault, e.g. `/nodes/4/id`.
Rig read_rig(const std::string& path);
/// Parses a rig from JSON text; `source` names it in messages.
Rig parse_rig(const std::string& text, const std::string& source);
/// Serialises a rig as JSON text, in the format that read_rig reads.
std::string rig_to_json(const Rig& rig);
/// Checks a rig built in memory (from Python, say) by the rules read_rig
/// applies to a file: ids unique, profiles naming existing nodes, curves
/// well formed, joints listed after their parents, weights naming joints
/// the skeleton has. embed(), bind() and transfer() expect a valid rig.
/// \throw InputError naming `source` and the JSON path of the fault.
void validate_rig(const Rig& rig, const std::string& source);
/// Writes a rig file atomically, after checking it as validate_rig() does.
void write_rig(const Rig& rig, const std::string& path);

/// Writes `contents` to `path` through a temporary file and a rename.
/// \throw Error when the file cannot be written.
void write_file_atomic(const std::string& path, const std::string& contents);

/// Files written all or nothing. Each goes to a temporary file beside its
/// destination (`DEST.tmp-curvenet-PID`); commit() moves them all into
/// place. Until then the destinations are untouched, and if commit() is
/// never reached (an exception), the destructor removes the temporary
/// files and the folders the set made for them. Temporary files that a
/// killed run left beside a destination are removed when the destination
/// is next written. A destination that is not a regular file (a device such
/// as /dev/null, a FIFO, /dev/stdout) is written in place, never replaced;
/// a symbolic link keeps its place and the file it names is replaced.
class OutputFiles {
public:
  OutputFiles();
  OutputFiles(const OutputFiles&) = delete;
  OutputFiles& operator=(const OutputFiles&) = delete;
  ~OutputFiles();
  /// Written and closed at once (a sequence of thousands of frames holds
  /// no file open). \throw Error naming the path when it cannot be written.
  void add(const std::string& path, const std::string& contents);
  /// A stream to write `path` progressively (a point cache frame by frame).
  /// Write errors are found by commit().
  std::ostream& stream(const std::string& path);
  /// \throw Error naming the first file that could not be finished.
  void commit();

private:
  struct File;
  struct Seen;
  std::vector<std::unique_ptr<File>> files_;
  std::unique_ptr<Seen> seen_;         ///< destinations and the folders' stale temporaries, looked up once
  std::vector<std::string> made_dirs_; ///< folders this set created, outermost first
  bool committed_ = false;
};

/// Writes a polygon mesh as OBJ, each number as the shortest text that
/// reads back to it exactly.
std::string mesh_to_obj(const std::vector<Vec3>& positions, const std::vector<int>& face_offsets,
                        const std::vector<int>& face_vertices);

} // namespace curvenet
