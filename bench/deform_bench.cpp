// Binding and per-frame cost against plain linear blend skinning (4
// influences), on capped tubes of about 5k, 50k and 500k vertices with a
// 5-joint skeleton and a 13-ring net. Prints medians from one run.
//
//   build/bin/deform_bench [max_vertices]

#include "curvenet/deform.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/weights.hpp"
#include "generate/tube.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
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
  std::printf("%9s %9s %10s %12s %10s %8s %12s %10s\n", "vertices", "faces", "bind_ms", "frame_ms", "lbs_ms", "ratio",
              "influences", "peak_MB");
  for (const int around : {64, 200, 640}) {
    TubeSpec ts;
    ts.around = around;
    ts.along = around;
    ts.cap_rings = around / 8;
    ts.triangulate = true;
    const SurfaceMesh mesh = make_surface_mesh(make_capped_tube(ts), "tube");
    if (mesh.num_vertices() > max_vertices)
      break;
    const double t0 = now_ms();
    const Binding b = bind(mesh, rig);
    const double bind_ms = now_ms() - t0;
    // LBS with 4 influences from the same skeleton.
    const int nv = mesh.num_vertices();
    std::vector<std::array<int, 4>> lj(nv);
    std::vector<std::array<double, 4>> lw(nv);
    for (int v = 0; v < nv; ++v) {
      auto w = auto_weights(joints, mesh.positions[v]);
      w.resize(std::min<size_t>(w.size(), 4));
      double sum = 0;
      for (auto& [j, x] : w)
        sum += x;
      for (int k = 0; k < 4; ++k) {
        lj[v][k] = k < static_cast<int>(w.size()) ? w[k].first : 0;
        lw[v][k] = k < static_cast<int>(w.size()) ? w[k].second / sum : 0;
      }
    }
    std::vector<Vec3> out(b.num_input_vertices()), lbs(nv);
    std::vector<double> ours, plain;
    for (int f = 0; f < 21; ++f) {
      Pose pose;
      for (int j = 1; j < 5; ++j)
        pose["j" + std::to_string(j)].rotation =
            Eigen::Quaterniond(Eigen::AngleAxisd((10 + f) * std::numbers::pi / 180, Eigen::Vector3d::UnitZ()));
      const auto M = skinning_matrices(b.joints(), pose);
      double s = now_ms();
      b.deform(M, out);
      ours.push_back(now_ms() - s);
      s = now_ms();
      for (int v = 0; v < nv; ++v) {
        Vec3 x = Vec3::Zero();
        for (int k = 0; k < 4; ++k)
          x.noalias() += lw[v][k] * (M[lj[v][k]].topLeftCorner<3, 3>() * mesh.positions[v] + M[lj[v][k]].block<3, 1>(0, 3));
        lbs[v] = x;
      }
      plain.push_back(now_ms() - s);
    }
    const double fo = median(ours), fl = median(plain);
    std::printf("%9d %9d %10.1f %12.3f %10.3f %8.2f %12.2f %10ld\n", nv, mesh.num_faces(), bind_ms, fo, fl, fo / fl,
                b.report().mean_influences, peak_mb());
    std::fflush(stdout);
  }
  return 0;
}
