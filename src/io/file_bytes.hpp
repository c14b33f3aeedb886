#pragma once
// A whole file's bytes, for the readers that parse from memory; and a
// file's stamp, which lets a parse cache know a file unchanged without
// reading it again.

#include "curvenet/errors.hpp"

#include <optional>
#include <string>

namespace curvenet::detail {

/// \throw InputError naming the file when it cannot be opened.
std::string file_bytes(const std::string& path);

/// A path's extension in lower case, with its dot (".glb"), or "" for none.
std::string lower_extension(const std::string& path);

/// How many times file_bytes() has read `path` in this process (the tests
/// count a command's reads).
long file_reads(const std::string& path);

/// A file's identity: device, inode, size, and its modification and change
/// times in nanoseconds.
struct FileStamp {
  unsigned long long device = 0, inode = 0, size = 0;
  long long mtime_ns = 0, ctime_ns = 0;
  bool operator==(const FileStamp&) const = default;
};

/// The file's stamp, when it proves the file unchanged while the stamp
/// stays the same: only when its times are more than 2 s old. A file is
/// stamped with a coarse clock, so one rewritten within the same tick keeps
/// its times; a fresh file's stamp proves nothing (git's "racy" rule), and
/// its bytes must be compared.
std::optional<FileStamp> settled_stamp(const std::string& path);

} // namespace curvenet::detail
