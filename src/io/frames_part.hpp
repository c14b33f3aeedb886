#pragma once
// A farm task's frames (docs/farm.md): a 40-byte header (the magic
// `CNFRAMES1`, the first frame, the frame count, the vertex count, the
// bytes per coordinate, the farm job's key), each frame's positions as
// little-endian floats (4 bytes: what a PC2 cache keeps, converted as
// Pc2Sink converts them) or doubles (8: what an OBJ sequence prints), and
// a 64-bit FNV-1a checksum of everything before it. Merged, the parts give
// the same PC2 or OBJ files, bit for bit, as one `animate` of the range.

#include "core/fnv1a.hpp"
#include "curvenet/jobs.hpp"

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

namespace curvenet::detail {

constexpr char kFramesMagic[16] = "CNFRAMES1";

struct FramesPartHeader {
  char magic[16];
  std::int32_t first, count, vertices, precision; ///< precision: 4 (float) or 8 (double) bytes a coordinate
  std::uint64_t key;
};
static_assert(sizeof(FramesPartHeader) == 40);

class FramesPartSink : public FrameSink {
public:
  /// `precision` 4 or 8; a coordinate past single precision is refused
  /// naming `blame`, as Pc2Sink refuses it.
  FramesPartSink(OutputFiles& files, const std::string& path, int vertices, const FrameRange& range, std::uint64_t key,
                 int precision, std::string blame);
  void write(int frame, std::span<const Vec3> positions) override;
  /// Writes the checksum: call after the last frame, before the commit.
  void finish();

private:
  std::ostream* out_;
  Fnv1a hash_;
  int precision_;
  std::string blame_;
  std::vector<float> buffer_;
};

/// A part file read frame by frame, its header checked on opening.
class FramesPartReader {
public:
  /// \throw InputError naming the file: missing, too short, or not a part file.
  explicit FramesPartReader(const std::string& path);
  [[nodiscard]] const FramesPartHeader& header() const { return header_; }
  /// The file's size is what the header says.
  [[nodiscard]] bool complete() const;
  /// The next frame's positions; false past the last.
  /// \throw InputError naming the file and the frame when it is short.
  bool next(std::span<Vec3> positions);
  /// After the last frame: whether the checksum matches.
  [[nodiscard]] bool checksum_ok();

private:
  std::string path_;
  std::ifstream in_;
  FramesPartHeader header_{};
  std::uintmax_t size_ = 0;
  std::vector<float> buffer_;
  int read_ = 0;
  Fnv1a hash_;
};

} // namespace curvenet::detail
