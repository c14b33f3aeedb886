#include "io/file_bytes.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>

#include <sys/stat.h>

namespace curvenet::detail {

namespace {
struct Reads {
  std::mutex mutex;
  std::map<std::string, long> count;
};
Reads& reads() {
  static Reads r;
  return r;
}
std::string key_of(const std::string& path) {
  std::error_code ec;
  return std::filesystem::absolute(path, ec).lexically_normal().string();
}
} // namespace

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw InputError(path, "", "cannot open the file for reading");
  {
    Reads& r = reads();
    std::lock_guard lock(r.mutex);
    ++r.count[key_of(path)];
  }
  // Read straight into a string of the file's size (a string stream grows
  // by copies, and copies again to hand its text over); a pipe, or a file
  // that grows meanwhile, is read on to its end.
  std::string text;
  std::error_code ec;
  const auto size = std::filesystem::is_regular_file(path, ec) ? std::filesystem::file_size(path, ec) : 0;
  if (!ec && size > 0) {
    text.resize(static_cast<size_t>(size));
    in.read(text.data(), static_cast<std::streamsize>(size));
    text.resize(static_cast<size_t>(in.gcount()));
  }
  char chunk[1 << 16];
  while (in && (in.read(chunk, sizeof chunk), in.gcount() > 0))
    text.append(chunk, static_cast<size_t>(in.gcount()));
  if (in.bad())
    throw InputError(path, "", "read error");
  return text;
}

long file_reads(const std::string& path) {
  Reads& r = reads();
  std::lock_guard lock(r.mutex);
  const auto it = r.count.find(key_of(path));
  return it == r.count.end() ? 0 : it->second;
}

std::optional<FileStamp> settled_stamp(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode))
    return std::nullopt;
  FileStamp s;
  s.device = st.st_dev;
  s.inode = st.st_ino;
  s.size = static_cast<unsigned long long>(st.st_size);
  s.mtime_ns = static_cast<long long>(st.st_mtim.tv_sec) * 1'000'000'000LL + st.st_mtim.tv_nsec;
  s.ctime_ns = static_cast<long long>(st.st_ctim.tv_sec) * 1'000'000'000LL + st.st_ctim.tv_nsec;
  const long long now =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  if (now - std::max(s.mtime_ns, s.ctime_ns) < 2'000'000'000LL)
    return std::nullopt;
  return s;
}

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

} // namespace curvenet::detail
