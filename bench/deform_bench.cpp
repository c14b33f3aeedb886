// Binding and per-frame cost of each deformation mode, against plain linear
// blend skinning and dual-quaternion skinning (4 influences, the library's
// own skin_positions), on capped tubes of about 5k, 50k and 500k vertices
// with a 5-joint skeleton and a 13-ring net. One run; medians of 21 frames,
// and of three binds (one above 200k vertices).
//
//   build/bin/deform_bench [max_vertices]
//
// "1 thread" runs with TBB limited to one thread; "2 threads" with two.
// The layer's rows (docs/deform.md, "A layer over the skin"): over the LBS
// skin above with envelope 1, and over the net's own deformation with one
// node of the middle ring pulled by 2 % of the diagonal. Set CURVENET_ONLY_LAYER
// to skip the modes, CURVENET_ONLY_DQ to keep only the default mode, and
// CURVENET_BIND_STAGES to print the bind's stages (of its last run, on two
// threads).

#include "curvenet/bake.hpp"
#include "curvenet/deform.hpp"
#include "curvenet/layer.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/weights.hpp"
#include "generate/tube.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <string>
#include <sys/resource.h>
#include <vector>

using namespace curvenet;

namespace {
double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
long peak_mb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024;
}

std::vector<std::vector<Mat4>> frames_of(const std::vector<Joint>& joints) {
  std::vector<std::vector<Mat4>> out;
  for (int f = 0; f < 21; ++f) {
    Pose pose;
    for (int j = 1; j < 5; ++j)
      pose["j" + std::to_string(j)].rotation =
          Eigen::Quaterniond(Eigen::AngleAxisd((10 + f) * std::numbers::pi / 180, Eigen::Vector3d::UnitZ()));
    out.push_back(skinning_matrices(joints, pose));
  }
  return out;
}

template <class F> double median_ms(int threads, const std::vector<std::vector<Mat4>>& frames, F&& frame) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  std::vector<double> t;
  for (const auto& M : frames) {
    const double s = now_ms();
    frame(M);
    t.push_back(now_ms() - s);
  }
  return median(t);
}
/// A bind's wall time on one thread and on two: medians of three runs each
/// (one each above 200k vertices).
template <class F> std::pair<double, double> bind_ms(int vertices, F&& run) {
  const int reps = vertices > 200000 ? 1 : 3;
  double out[2];
  for (const int threads : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    std::vector<double> t;
    for (int r = 0; r < reps; ++r) {
      const double s = now_ms();
      run();
      t.push_back(now_ms() - s);
    }
    out[threads - 1] = median(t);
  }
  return {out[0], out[1]};
}
} // namespace

int main(int argc, char** argv) {
  const long max_vertices = argc > 1 ? std::atol(argv[1]) : 600000;
  const std::vector<Joint> joints = make_tube_skeleton({0.2, 1.1, 2.0, 2.9, 3.8});
  TubeNetSpec ns;
  ns.ring_heights.clear();
  for (int i = 0; i < 13; ++i)
    ns.ring_heights.push_back(0.3 + 3.4 * i / 12);
  ns.nodes_per_ring = 8;
  Rig rig = make_tube_net(ns);
  rig.joints = joints;
  rig.has_skeleton = true;
  std::printf("| vertices | faces | mode | bind ms, 1 thread | bind ms, 2 threads | frame ms, 1 thread | frame ms, 2 threads | "
              "influences per vertex | peak MB |\n|---|---|---|---|---|---|---|---|---|\n");
  for (const int around : {64, 200, 640}) {
    TubeSpec ts;
    ts.around = around;
    ts.along = around;
    ts.cap_rings = around / 8;
    ts.triangulate = true;
    const RawMesh raw = make_capped_tube(ts);
    if (static_cast<long>(raw.positions.size()) > max_vertices)
      break;
    const SurfaceMesh mesh = make_surface_mesh(raw, "tube");
    const auto frames = frames_of(joints);
    const std::vector<Vec3> rest(mesh.positions.begin(), mesh.positions.end());
    std::vector<Vec3> out(mesh.input_to_welded.size());
    SkinWeights skin; // the skins: the blend-zone rule's weights, 4 influences
    for (const auto& j : joints)
      skin.joints.push_back(j.name);
    for (const auto& p : rest) {
      auto w = auto_weights(joints, p);
      w.resize(std::min<size_t>(w.size(), 4));
      double sum = 0;
      for (auto& [j, x] : w)
        sum += x;
      for (int k = 0; k < 4; ++k) {
        skin.joint.push_back(k < static_cast<int>(w.size()) ? w[k].first : -1);
        skin.weight.push_back(k < static_cast<int>(w.size()) ? w[k].second / sum : 0.0);
      }
    }
    for (const auto method : {Skinning::Linear, Skinning::DualQuaternion}) {
      std::vector<Vec3> posed;
      auto frame = [&](const std::vector<Mat4>& M) { posed = skin_positions(skin, rest, M, method); };
      std::printf("| %d | %d | %s | | | %.3f | %.3f | 4 | |\n", mesh.num_vertices(), mesh.num_faces(),
                  method == Skinning::Linear ? "LBS (baseline)" : "DQS (baseline)", median_ms(1, frames, frame),
                  median_ms(2, frames, frame));
    }
    {
      SkinnedMesh skinned; // the same skin, as a file's skin is read
      skinned.source = "tube skin";
      for (const auto& j : joints) {
        skinned.joints.push_back(j);
        skinned.inverse_bind.push_back(j.bind.inverse());
      }
      for (size_t v = 0; v < rest.size(); ++v) {
        std::array<int, 4> jv{};
        std::array<double, 4> wv{};
        for (int k = 0; k < 4; ++k) {
          jv[k] = skin.joint[4 * v + k];
          wv[k] = skin.weight[4 * v + k];
        }
        skinned.vertex_joint.push_back(jv);
        skinned.vertex_weight.push_back(wv);
      }
      const double diagonal = mesh.bbox_diagonal();
      const NodeOffsets pulled{{rig.nodes[6 * ns.nodes_per_ring].id, Vec3(0.02 * diagonal, 0, 0)}};
      // Over LBS with dq curves (the default), with harmonic curves (the
      // precomputed sum) and the same solved every frame; over the net.
      for (const int row : {0, 1, 2, 3}) {
        const bool over_skin = row < 3;
        LayerOptions lo;
        if (row == 1 || row == 2)
          lo.bind.method = DeformMethod::Harmonic;
        lo.precompute_linear = row != 2;
        std::unique_ptr<CurveLayer> layer;
        auto [bind1, bind2] = bind_ms(mesh.num_vertices(), [&] {
          layer = std::make_unique<CurveLayer>(bind_layer(mesh, rig, over_skin ? &skinned : nullptr, lo));
        });
        auto frame = [&](const std::vector<Mat4>& M) { layer->deform(M, out, 1, over_skin ? nullptr : &pulled); };
        const char* name[] = {"layer over LBS (dq curves)", "layer over LBS (harmonic curves, precomputed sum)",
                              "layer over LBS (harmonic curves, solved each frame)", "layer over dq, one node pulled"};
        std::printf("| %d | %d | %s | %.1f | %.1f | %.3f | %.3f | | %ld |\n", mesh.num_vertices(), mesh.num_faces(),
                    name[row], bind1, bind2, median_ms(1, frames, frame), median_ms(2, frames, frame), peak_mb());
        std::fflush(stdout);
      }
    }
    for (const auto m : {DeformMethod::DualQuaternion, DeformMethod::Harmonic, DeformMethod::Gradient}) {
      if (std::getenv("CURVENET_ONLY_LAYER"))
        continue;
      if (std::getenv("CURVENET_ONLY_DQ") && m != DeformMethod::DualQuaternion)
        continue;
      BindOptions o;
      o.method = m;
      std::unique_ptr<Binding> b;
      auto [bind1, bind2] = bind_ms(mesh.num_vertices(), [&] { b = std::make_unique<Binding>(bind(mesh, rig, o)); });
      auto frame = [&](const std::vector<Mat4>& M) { b->deform(M, out); };
      const double one = median_ms(1, frames, frame), two = median_ms(2, frames, frame);
      std::printf("| %d | %d | %s%s | %.1f | %.1f | %.3f | %.3f | %.2f | %ld |\n", mesh.num_vertices(),
                  mesh.num_faces(), to_string(m), m == DeformMethod::DualQuaternion ? " (default)" : "", bind1, bind2,
                  one, two,
                  b->report().mean_influences, peak_mb());
      if (std::getenv("CURVENET_BIND_STAGES"))
      {
        for (const auto& [stage, ms] : b->report().timings_ms)
          std::printf("    %s %.1f ms\n", stage.c_str(), ms);
        for (const auto& [stage, ms] : b->embedding().report().timings_ms)
          std::printf("      embed: %s %.1f ms\n", stage.c_str(), ms);
      }
      std::fflush(stdout);
    }
  }
  return 0;
}
