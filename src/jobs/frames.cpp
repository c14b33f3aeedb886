// Frames of a clip as a job: the range checked up front, deformed block by
// block through Binding::deform_frames, and streamed to sinks in order.

#include "curvenet/jobs.hpp"

#include "core/numbers.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/layer.hpp"
#include "curvenet/pose.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <map>
#include <sstream>

#include <tbb/parallel_for.h>

namespace curvenet {

FrameRange frame_range(const SkinnedMesh& clips, int clip, double fps, const std::string& frames,
                       long long max_frames) {
  FrameRange r;
  r.fps = fps;
  std::tie(r.first, r.last) = clip_frames(clips, clip, fps);
  if (!frames.empty()) {
    // Exactly two whole numbers around one colon: "1.5:3y", "1:2:3" and
    // "0:1e3" are refused.
    const auto colon = frames.find(':');
    const std::string_view text = frames;
    if (colon == std::string::npos || !detail::parse_whole(text.substr(0, colon), r.first) ||
        !detail::parse_whole(text.substr(colon + 1), r.last))
      throw InputError("--frames", frames, "expected A:B, two whole frame numbers");
    if (r.last < r.first)
      throw InputError("--frames", frames, "the last frame comes before the first");
  }
  const long long count = static_cast<long long>(r.last) - r.first + 1;
  if (count > max_frames)
    throw InputError("--frames", std::to_string(r.first) + ":" + std::to_string(r.last),
                     std::to_string(count) + " frames is more than --max-frames (" + std::to_string(max_frames) + ")");
  return r;
}

Pc2Sink::Pc2Sink(OutputFiles& files, const std::string& path, int vertices, const FrameRange& range, std::string blame)
    : out_(&files.stream(path)), blame_(blame.empty() ? path : std::move(blame)),
      buffer_(3 * static_cast<size_t>(vertices)) {
  *out_ << pc2_header(vertices, range.count(), static_cast<float>(range.first));
}

void Pc2Sink::write(int frame, std::span<const Vec3> positions) {
  for (size_t i = 0; i < positions.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      buffer_[3 * i + c] = static_cast<float>(positions[i][c]);
      if (!std::isfinite(buffer_[3 * i + c]))
        throw InputError(blame_, "frame " + std::to_string(frame) + " vertex " + std::to_string(i),
                         "the pose moves it out of the range of a PC2 cache (single precision); nothing was written");
    }
  out_->write(reinterpret_cast<const char*>(buffer_.data()),
              static_cast<std::streamsize>(buffer_.size() * sizeof(float)));
}

std::string sequence_name(const std::string& prefix, int frame) {
  std::ostringstream name;
  name << prefix << "_" << std::setw(4) << std::setfill('0') << frame << ".obj";
  return name.str();
}

ObjSequenceSink::ObjSequenceSink(OutputFiles& files, std::string dir, const InputTopology& topology, std::string prefix)
    : files_(files), dir_(std::move(dir)), prefix_(std::move(prefix)), topology_(topology) {}

void ObjSequenceSink::write(int frame, std::span<const Vec3> positions) {
  files_.add((std::filesystem::path(dir_) / sequence_name(prefix_, frame)).string(), posed_obj(topology_, positions));
}

void animate(const Binding& binding, const SkinnedMesh& clips, int clip, const FrameRange& range,
             std::span<FrameSink* const> sinks) {
  const ClipPoser poser(binding.joints(), clips);
  animate(
      binding, [&](int frame) { return poser(clip, range.time(frame)); }, range, sinks, clips.source);
}

void animate(const Binding& binding, const std::function<std::vector<Mat4>(int frame)>& pose, const FrameRange& range,
             std::span<FrameSink* const> sinks, const std::string& source) {
  animate(
      binding.num_input_vertices(),
      [&](int, std::span<const Mat4> M, std::span<Vec3> out) { binding.deform_frames(M, out); }, pose, range, sinks,
      source);
}

void animate(int vertices, const std::function<void(int, std::span<const Mat4>, std::span<Vec3>)>& deform_frames,
             const std::function<std::vector<Mat4>(int frame)>& pose, const FrameRange& range,
             std::span<FrameSink* const> sinks, const std::string& source) {
  const int frames = range.count(), nv = vertices;
  // About 64 MB of positions a block, from 1 to 256 frames.
  const int block = static_cast<int>(std::clamp<long long>((64ll << 20) / (24ll * std::max(nv, 1)), 1, 256));
  std::vector<Mat4> M;
  std::vector<Vec3> out;
  for (int b0 = 0; b0 < frames; b0 += block) {
    const int b1 = std::min(frames, b0 + block);
    M.clear();
    for (int f = b0; f < b1; ++f) {
      const auto m = pose(range.first + f);
      M.insert(M.end(), m.begin(), m.end());
    }
    out.resize(static_cast<size_t>(b1 - b0) * nv);
    deform_frames(range.first + b0, M, out);
    for (int f = b0; f < b1; ++f) {
      const std::span<const Vec3> positions(out.data() + static_cast<size_t>(f - b0) * nv, static_cast<size_t>(nv));
      for (int i = 0; i < nv; ++i)
        if (!positions[i].allFinite())
          throw InputError(source, "frame " + std::to_string(range.first + f) + " vertex " + std::to_string(i),
                           "the pose moves it out of range (not a finite number); nothing was written");
      for (FrameSink* s : sinks)
        s->write(range.first + f, positions);
    }
  }
}

void animate(const CurveLayer& layer, const std::function<LayerFrame(int frame)>& pose, const FrameRange& range,
             std::span<FrameSink* const> sinks, const std::string& source) {
  const size_t nj = layer.joints().size();
  const int nv = layer.num_input_vertices();
  // The envelope and the offsets of each frame of a block, kept until the
  // block is deformed (the frame job asks for a block's poses first).
  std::map<int, std::pair<double, NodeOffsets>> block;
  auto matrices = [&](int frame) {
    LayerFrame f = pose(frame);
    if (!(f.envelope >= 0 && f.envelope <= 1))
      throw InputError(source, "frame " + std::to_string(frame), "the envelope is not a number from 0 to 1");
    block[frame] = {f.envelope, std::move(f.offsets)};
    return std::move(f.skinning);
  };
  auto deform_block = [&](int first, std::span<const Mat4> M, std::span<Vec3> out) {
    const size_t frames = nj ? M.size() / nj : 0;
    tbb::parallel_for(size_t{0}, frames, [&](size_t f) {
      const auto& [envelope, offsets] = block.at(first + static_cast<int>(f));
      layer.deform(M.subspan(f * nj, nj), out.subspan(f * nv, nv), envelope, &offsets);
    });
    block.clear();
  };
  animate(nv, deform_block, matrices, range, sinks, source);
}

} // namespace curvenet
