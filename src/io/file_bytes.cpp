#include "io/file_bytes.hpp"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include <cerrno>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

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

namespace {
/// A FIFO's bytes (a named pipe, or a shell's process substitution): opened
/// without blocking (opening one that no one writes blocks for ever), read
/// to its end once a writer is there, however slow it is, and refused when
/// no writer comes within 5 s. Without blocking, a read gives 0 while there
/// is no writer, and EAGAIN while one is there with nothing written yet.
std::string fifo_bytes(const std::string& path) {
  struct Fd {
    int fd;
    ~Fd() {
      if (fd >= 0)
        ::close(fd);
    }
  } f{::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC)};
  if (f.fd < 0)
    throw InputError(path, "", "cannot open the file for reading");
  std::string text;
  char chunk[1 << 16];
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  for (;;) { // until a writer is there
    const ssize_t n = ::read(f.fd, chunk, sizeof chunk);
    if (n > 0) {
      text.append(chunk, static_cast<size_t>(n));
      break;
    }
    if (n < 0 && errno == EAGAIN)
      break;
    if (n < 0 && errno != EINTR)
      throw InputError(path, "", "read error");
    if (n == 0) {
      if (std::chrono::steady_clock::now() > give_up)
        throw InputError(path, "", "a FIFO that no one wrote to within 5 s");
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  ::fcntl(f.fd, F_SETFL, ::fcntl(f.fd, F_GETFL) & ~O_NONBLOCK); // then to its end, as slow as it comes
  for (;;) {
    const ssize_t n = ::read(f.fd, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR)
      continue;
    if (n < 0)
      throw InputError(path, "", "read error");
    if (n == 0)
      break;
    text.append(chunk, static_cast<size_t>(n));
  }
  return text;
}
} // namespace

std::string file_bytes(const std::string& path) {
  if (struct stat st {}; ::stat(path.c_str(), &st) == 0 && S_ISFIFO(st.st_mode)) {
    {
      Reads& r = reads();
      std::lock_guard lock(r.mutex);
      ++r.count[key_of(path)];
    }
    return fifo_bytes(path);
  }
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
