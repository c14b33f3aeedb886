// Mesh readers. OBJ through a strict reader of our own (obj_read.cpp; it
// keeps the file's vertex order), glTF/GLB through tinygltf (exact
// accessors), PLY and OFF through readers of our own (ply_off.cpp), and FBX
// through assimp. Validation and welding happen in make_surface_mesh.

#include "core/numbers.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "io/assimp_scene.hpp"
#include "io/file_bytes.hpp"
#include "io/gltf_scene.hpp"
#include "io/obj_read.hpp"
#include "io/ply_off.hpp"

#include <mutex>
#include <optional>

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <unistd.h>
#include <unordered_map>
#include <unordered_set>

namespace curvenet {

namespace {

RawMesh read_obj(const std::string& path) {
  const auto data = detail::parse_obj(path);
  RawMesh raw;
  raw.positions = data->positions;
  raw.face_offsets = data->face_offsets;
  raw.face_vertices = data->corner_vertex;
  return raw;
}

RawMesh read_gltf(const std::string& path) {
  return detail::read_gltf_scene(path).mesh;
}

// ---- assimp --------------------------------------------------------------

RawMesh read_assimp(const std::string& path) {
  return detail::read_assimp_scene(path).mesh;
}

/// ASCII FBX declares each array's length (`Vertices: *12 {`), and assimp
/// allocates it before reading: a length the file cannot hold is refused
/// first (found by fuzzing: `*2147483648` asked for 24 GB). Binary FBX is
/// left to assimp.
void check_fbx_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  const std::string text = s.str();
  if (text.rfind("Kaydara FBX Binary", 0) == 0)
    return;
  long long line = 1;
  for (size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '\n')
      ++line;
    if (text[i] != '*')
      continue;
    size_t j = i + 1;
    while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j])))
      ++j;
    if (j == i + 1)
      continue;
    long long n = 0;
    if (!detail::parse_whole(std::string_view(text).substr(i + 1, j - i - 1), n) ||
        n > static_cast<long long>(text.size()) / 2)
      throw InputError(path, "line " + std::to_string(line),
                       "an array declares " + text.substr(i + 1, j - i - 1) + " values, more than the file's " +
                           std::to_string(text.size()) + " bytes can hold");
  }
}

} // namespace

RawMesh read_raw_mesh(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw InputError(path, "", "is a folder, not a mesh file");
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(path, "",
                     std::filesystem::exists(path, ec)
                         ? "not a regular file (a pipe or a device): a mesh is read from a file, more than once"
                         : "no such file");
  if (::access(path.c_str(), R_OK) != 0) // checked without opening: a cached parse needs no read
    throw InputError(path, "", "cannot open the file for reading");
  const std::string ext = detail::lower_extension(path);
  if (ext == ".obj")
    return read_obj(path);
  if (ext == ".gltf" || ext == ".glb")
    return read_gltf(path);
  if (ext == ".ply")
    return detail::read_ply(path);
  if (ext == ".off")
    return detail::read_off(path);
  if (ext == ".fbx") {
    check_fbx_text(path);
    return read_assimp(path);
  }
  throw InputError(path, "", "unknown mesh format '" + ext + "' (expected .obj, .ply, .off, .gltf, .glb or .fbx)");
}

SurfaceMesh load_mesh(const std::string& path) {
  return make_surface_mesh(read_raw_mesh(path), path);
}

std::string mesh_to_obj(const std::vector<Vec3>& positions, const std::vector<int>& face_offsets,
                        const std::vector<int>& face_vertices) {
  for (size_t v = 0; v < positions.size(); ++v)
    if (!positions[v].allFinite())
      throw Error("vertex " + std::to_string(v) + " of the mesh to write is not finite; nothing was written");
  std::string out;
  out.reserve(64 * positions.size() + 8 * face_vertices.size());
  for (const auto& p : positions) {
    out += 'v';
    for (int c = 0; c < 3; ++c) {
      out += ' ';
      detail::append_number(out, p[c]);
    }
    out += '\n';
  }
  for (size_t f = 0; f + 1 < face_offsets.size(); ++f) {
    out += 'f';
    for (int k = face_offsets[f]; k < face_offsets[f + 1]; ++k) {
      out += ' ';
      detail::append_number(out, face_vertices[k] + 1);
    }
    out += '\n';
  }
  return out;
}

namespace {

constexpr const char* kTempTag = ".tmp-curvenet-";

std::string temp_name(const std::string& path) {
  return path + kTempTag + std::to_string(::getpid());
}

/// Whether the process that named a temporary is gone (or is this one).
bool gone(long pid) {
  return pid == ::getpid() || (::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH);
}

/// A temporary of a folder and the process it names.
struct Temporary {
  std::filesystem::path path;
  long pid;
};

/// The DEST.tmp-curvenet-PID files of a folder whose process is gone (what
/// a killed run left behind), by DEST's file name: the folder is read once,
/// however many files are written into it (each is checked again when its
/// destination is written: a process id may be taken again meanwhile).
std::unordered_map<std::string, std::vector<Temporary>> stale_temporaries(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  std::unordered_map<std::string, std::vector<Temporary>> out;
  std::error_code ec;
  const std::string tag = kTempTag;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const size_t at = name.rfind(tag);
    if (at == std::string::npos || at == 0)
      continue;
    const std::string pid_text = name.substr(at + tag.size());
    if (pid_text.empty() || pid_text.size() > 10 ||
        !std::all_of(pid_text.begin(), pid_text.end(), [](unsigned char c) { return std::isdigit(c); }))
      continue;
    const long pid = std::strtol(pid_text.c_str(), nullptr, 10);
    if (gone(pid))
      out[name.substr(0, at)].push_back({it->path(), pid});
  }
  return out;
}

} // namespace

struct OutputFiles::File {
  std::string dest, temp; ///< temp is empty for a destination written in place
  std::ofstream out;
  bool closed = false; ///< written whole by add() and closed
};

struct OutputFiles::Seen {
  std::unordered_set<std::string> keys; ///< the destinations given, resolved
  std::unordered_map<std::string, std::unordered_map<std::string, std::vector<Temporary>>> stale; ///< by folder
};

namespace {

/// A destination with nothing to make atomic, written in place: a device,
/// a FIFO or a socket (`-o /dev/null`, a pipe), or the process's own
/// streams (`/dev/stdout`, `/dev/fd/N`, `/proc/self/fd/N`). Renaming a
/// temporary over one of these would replace it with a regular file.
bool written_in_place(const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  const std::string text = path.lexically_normal().string();
  for (const char* prefix : {"/dev/stdout", "/dev/stderr", "/dev/fd/", "/proc/self/fd/"})
    if (text.rfind(prefix, 0) == 0)
      return true;
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec); // through symbolic links
  return !ec && fs::exists(st) && !fs::is_regular_file(st) && !fs::is_directory(st);
}

} // namespace

OutputFiles::OutputFiles() : seen_(std::make_unique<Seen>()) {}

OutputFiles::~OutputFiles() {
  if (committed_)
    return;
  for (auto& f : files_) {
    f->out.close();
    std::error_code ec;
    if (!f->temp.empty())
      std::filesystem::remove(f->temp, ec);
  }
  // The folders this set made, deepest first, if nothing else is in them.
  for (auto it = made_dirs_.rbegin(); it != made_dirs_.rend(); ++it) {
    std::error_code ec;
    std::filesystem::remove(*it, ec); // removes only an empty folder
  }
}

std::ostream& OutputFiles::stream(const std::string& path) {
  namespace fs = std::filesystem;
  fs::path target(path);
  std::error_code ec;
  auto f = std::make_unique<File>();
  f->dest = path;
  if (written_in_place(target)) {
    f->out.open(path, std::ios::binary);
  } else {
    if (fs::is_directory(target, ec))
      throw Error(path + ": is a folder, not a file to write");
    // A symbolic link to a file keeps pointing at it: the file it names is replaced.
    if (fs::is_symlink(fs::symlink_status(target, ec))) {
      const fs::path resolved = fs::weakly_canonical(target, ec);
      if (!ec)
        target = resolved;
    }
    // The folders to make, up to the nearest one there is. A file there
    // (`--obj-sequence` given a file's name) says so, not just that the
    // frame cannot be opened.
    std::vector<fs::path> missing;
    fs::path there = target.parent_path();
    for (; !there.empty() && !fs::exists(there, ec); there = there.parent_path()) {
      missing.push_back(there);
      if (there == there.parent_path())
        break;
    }
    if (!there.empty() && fs::exists(there, ec) && !fs::is_directory(there, ec))
      throw Error(path + ": " + there.string() + " is a file, not a folder to write into");
    if (!missing.empty()) {
      fs::create_directories(target.parent_path(), ec);
      made_dirs_.insert(made_dirs_.end(), missing.rbegin(), missing.rend());
    }
    // Two outputs given one path: the second would replace the first.
    const fs::path key = fs::weakly_canonical(fs::absolute(target, ec), ec);
    if (!seen_->keys.insert(key.string()).second)
      throw Error(path + ": two outputs were given this one path; give each its own");
    const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
    const std::string dir_key = key.parent_path().string();
    auto in_dir = seen_->stale.find(dir_key);
    if (in_dir == seen_->stale.end())
      in_dir = seen_->stale.emplace(dir_key, stale_temporaries(dir)).first;
    if (const auto old = in_dir->second.find(target.filename().string()); old != in_dir->second.end()) {
      for (const Temporary& t : old->second)
        if (gone(t.pid))
          fs::remove(t.path, ec);
      in_dir->second.erase(old);
    }
    f->dest = target.string();
    f->temp = temp_name(f->dest);
    f->out.open(f->temp, std::ios::binary | std::ios::trunc);
  }
  if (!f->out)
    throw Error(path + ": cannot open for writing");
  files_.push_back(std::move(f));
  return files_.back()->out;
}

void OutputFiles::add(const std::string& path, const std::string& contents) {
  stream(path);
  File& f = *files_.back();
  f.out.write(contents.data(), static_cast<std::streamsize>(contents.size()));
  f.out.close();
  f.closed = true;
  if (f.out.fail())
    throw Error(path + ": write failed (is the disk full?)");
}

void OutputFiles::commit() {
  // Every file finished before any destination is touched.
  for (auto& f : files_) {
    if (!f->closed) {
      f->out.flush();
      f->out.close();
    }
    if (f->out.fail())
      throw Error(f->dest + ": write failed (is the disk full?)");
  }
  for (auto& f : files_) {
    if (f->temp.empty())
      continue; // written in place
    std::error_code ec;
    std::filesystem::rename(f->temp, f->dest, ec);
    if (ec)
      throw Error(f->dest + ": cannot move the finished file into place (" + ec.message() + ")");
  }
  committed_ = true;
}

void write_file_atomic(const std::string& path, const std::string& contents) {
  OutputFiles out;
  out.add(path, contents);
  out.commit();
}

} // namespace curvenet
