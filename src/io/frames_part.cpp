#include "io/frames_part.hpp"

#include "curvenet/errors.hpp"

#include <cmath>
#include <cstring>
#include <filesystem>

namespace curvenet::detail {

FramesPartSink::FramesPartSink(OutputFiles& files, const std::string& path, int vertices, const FrameRange& range,
                               std::uint64_t key, int precision, std::string blame)
    : out_(&files.stream(path)), precision_(precision), blame_(std::move(blame)) {
  if (precision != 4 && precision != 8)
    throw Error(path + ": a part file keeps 4 or 8 bytes a coordinate");
  FramesPartHeader h{};
  std::memcpy(h.magic, kFramesMagic, sizeof kFramesMagic);
  h.first = range.first;
  h.count = range.count();
  h.vertices = vertices;
  h.precision = precision;
  h.key = key;
  hash_.eat(&h, sizeof h);
  out_->write(reinterpret_cast<const char*>(&h), sizeof h);
}

void FramesPartSink::write(int frame, std::span<const Vec3> positions) {
  static_assert(sizeof(Vec3) == 3 * sizeof(double));
  const char* bytes = reinterpret_cast<const char*>(positions.data());
  size_t n = positions.size() * sizeof(Vec3);
  if (precision_ == 4) {
    buffer_.resize(3 * positions.size());
    for (size_t i = 0; i < positions.size(); ++i)
      for (int c = 0; c < 3; ++c) {
        buffer_[3 * i + c] = static_cast<float>(positions[i][c]); // as Pc2Sink converts it
        if (!std::isfinite(buffer_[3 * i + c]))
          throw InputError(blame_, "frame " + std::to_string(frame) + " vertex " + std::to_string(i),
                           "the pose moves it out of the range of a PC2 cache (single precision); nothing was written");
      }
    bytes = reinterpret_cast<const char*>(buffer_.data());
    n = buffer_.size() * sizeof(float);
  }
  hash_.eat(bytes, n);
  out_->write(bytes, static_cast<std::streamsize>(n));
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
  if (header_.precision != 4 && header_.precision != 8)
    throw InputError(path, "header", "neither 4 nor 8 bytes a coordinate");
  hash_.eat(&header_, sizeof header_);
}

bool FramesPartReader::complete() const {
  const auto expected = sizeof(FramesPartHeader) +
                        static_cast<std::uintmax_t>(header_.count) * header_.vertices * 3 * header_.precision + 8;
  return size_ == expected;
}

bool FramesPartReader::next(std::span<Vec3> positions) {
  if (read_ >= header_.count)
    return false;
  char* bytes = reinterpret_cast<char*>(positions.data());
  if (header_.precision == 4) {
    buffer_.resize(3 * positions.size());
    bytes = reinterpret_cast<char*>(buffer_.data());
  }
  const auto n = static_cast<std::streamsize>(positions.size() * 3 * header_.precision);
  if (!in_.read(bytes, n))
    throw InputError(path_, "frame " + std::to_string(header_.first + read_),
                     "the file ends inside this frame (truncated)");
  hash_.eat(bytes, static_cast<size_t>(n));
  if (header_.precision == 4)
    for (size_t i = 0; i < positions.size(); ++i)
      positions[i] = Vec3(buffer_[3 * i], buffer_[3 * i + 1], buffer_[3 * i + 2]);
  ++read_;
  return true;
}

bool FramesPartReader::checksum_ok() {
  std::uint64_t stored = 0;
  return read_ == header_.count && in_.read(reinterpret_cast<char*>(&stored), sizeof stored) && stored == hash_.value &&
         in_.peek() == std::char_traits<char>::eof();
}

} // namespace curvenet::detail
