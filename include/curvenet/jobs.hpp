#pragma once
/// \file jobs.hpp
/// The work a front end asks for, done once in the library: frames of a
/// clip as a checked range, deformed in parallel blocks of bounded memory
/// and streamed, in order, to any number of sinks (a PC2 cache, an OBJ
/// sequence, a caller's own). The CLI's `animate`, the Python module and
/// the Blender add-on all compute frames through Binding::deform_frames,
/// block by block, so they agree bit for bit.

#include "curvenet/deform.hpp"
#include "curvenet/io.hpp"
#include "curvenet/mesh_output.hpp"
#include "curvenet/skin.hpp"

#include <functional>
#include <span>
#include <string>
#include <vector>

namespace curvenet {

/// Frames first..last (inclusive) of a clip, sampled at fps.
struct FrameRange {
  int first = 0, last = -1;
  double fps = 24;
  [[nodiscard]] int count() const { return last - first + 1; }
  /// The clip time of frame `frame`.
  [[nodiscard]] double time(int frame) const { return frame / fps; }
};

/// The frames of clip `clip`, or those `frames` names ("A:B", two whole
/// numbers; empty for the clip's own range).
/// \throw InputError naming `--frames` for a malformed or reversed range,
///   or one of more than `max_frames` frames.
FrameRange frame_range(const SkinnedMesh& clips, int clip, double fps, const std::string& frames = "",
                       long long max_frames = 100000);

/// Where frames go: write() is called once per frame, in frame order, with
/// one position per vertex of the binding's input.
class FrameSink {
public:
  virtual ~FrameSink() = default;
  virtual void write(int frame, std::span<const Vec3> positions) = 0;
};

/// A PC2 point cache, streamed into `files` (written when they are
/// committed). A position past single precision is refused naming `blame`
/// (the clip file, say; the path by default).
class Pc2Sink : public FrameSink {
public:
  Pc2Sink(OutputFiles& files, const std::string& path, int vertices, const FrameRange& range, std::string blame = "");
  void write(int frame, std::span<const Vec3> positions) override;

private:
  std::ostream* out_;
  std::string blame_;
  std::vector<float> buffer_;
};

/// One OBJ per frame, `DIR/PREFIX_NNNN.obj`, on the input's own topology.
class ObjSequenceSink : public FrameSink {
public:
  ObjSequenceSink(OutputFiles& files, std::string dir, const InputTopology& topology, std::string prefix = "frame");
  void write(int frame, std::span<const Vec3> positions) override;

private:
  OutputFiles& files_;
  std::string dir_, prefix_;
  const InputTopology& topology_;
};

/// A sink of the caller's: a function of the frame and its positions.
class FunctionSink : public FrameSink {
public:
  explicit FunctionSink(std::function<void(int, std::span<const Vec3>)> f) : f_(std::move(f)) {}
  void write(int frame, std::span<const Vec3> positions) override { f_(frame, positions); }

private:
  std::function<void(int, std::span<const Vec3>)> f_;
};

/// The name of frame `frame` in a sequence: PREFIX_NNNN.obj.
std::string sequence_name(const std::string& prefix, int frame);

/// Deforms every frame of `range` of clip `clip` through `binding` and
/// hands each to every sink, in frame order. Frames are computed in blocks
/// (about 64 MB of positions at a time) by Binding::deform_frames, in
/// parallel within a block, so memory does not grow with the frame count
/// and the result does not depend on the thread count.
/// \throw InputError naming the clip file, the frame and the vertex when a
///   position is not finite.
void animate(const Binding& binding, const SkinnedMesh& clips, int clip, const FrameRange& range,
             std::span<FrameSink* const> sinks);

} // namespace curvenet
