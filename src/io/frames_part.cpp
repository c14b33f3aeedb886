#include "io/frames_part.hpp"

#include "curvenet/errors.hpp"

#include <cstring>
#include <filesystem>

namespace curvenet::detail {

FramesPartSink::FramesPartSink(OutputFiles& files, const std::string& path, int vertices, const FrameRange& range,
                               std::uint64_t key)
    : out_(&files.stream(path)) {
  FramesPartHeader h{};
  std::memcpy(h.magic, kFramesMagic, sizeof kFramesMagic);
  h.first = range.first;
  h.count = range.count();
  h.vertices = vertices;
  h.key = key;
  hash_.eat(&h, sizeof h);
  out_->write(reinterpret_cast<const char*>(&h), sizeof h);
}

void FramesPartSink::write(int /*frame*/, std::span<const Vec3> positions) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double));
  const size_t n = positions.size() * sizeof(Vec3);
  hash_.eat(positions.data(), n);
  out_->write(reinterpret_cast<const char*>(positions.data()), static_cast<std::streamsize>(n));
}

void FramesPartSink::finish() {
  const std::uint64_t h = hash_.value;
  out_->write(reinterpret_cast<const char*>(&h), sizeof h);
}

FramesPartReader::FramesPartReader(const std::string& path) : path_(path), in_(path, std::ios::binary) {
  std::error_code ec;
  size_ = std::filesystem::file_size(path, ec);
  if (!in_ || ec)
    throw InputError(path, "", "missing: the part was not written");
  if (!in_.read(reinterpret_cast<char*>(&header_), sizeof header_))
    throw InputError(path, "header", "too short for a part file's header (truncated)");
  if (std::memcmp(header_.magic, kFramesMagic, sizeof kFramesMagic) != 0)
    throw InputError(path, "header", "not a curvenet frames part file");
  if (header_.count < 0 || header_.vertices < 0)
    throw InputError(path, "header", "a negative frame or vertex count");
  hash_.eat(&header_, sizeof header_);
}

bool FramesPartReader::complete() const {
  const auto expected =
      sizeof(FramesPartHeader) + static_cast<std::uintmax_t>(header_.count) * header_.vertices * sizeof(Vec3) + 8;
  return size_ == expected;
}

bool FramesPartReader::next(std::span<Vec3> positions) {
  if (read_ >= header_.count)
    return false;
  const auto n = static_cast<std::streamsize>(positions.size() * sizeof(Vec3));
  if (!in_.read(reinterpret_cast<char*>(positions.data()), n))
    throw InputError(path_, "frame " + std::to_string(header_.first + read_),
                     "the file ends inside this frame (truncated)");
  hash_.eat(positions.data(), static_cast<size_t>(n));
  ++read_;
  return true;
}

bool FramesPartReader::checksum_ok() {
  std::uint64_t stored = 0;
  return read_ == header_.count && in_.read(reinterpret_cast<char*>(&stored), sizeof stored) && stored == hash_.value &&
         in_.peek() == std::char_traits<char>::eof();
}

} // namespace curvenet::detail
