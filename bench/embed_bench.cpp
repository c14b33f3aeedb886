// Embedding time against face count (the tube net, 28 profiles, on capped
// tubes from about 1k to 1M faces), then against profile count (denser tube
// nets on one tube of about 55k faces). Prints two tables of medians.
//
//   build/bin/embed_bench [max_faces]

#include "curvenet/embed.hpp"
#include "generate/tube.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <utility>
#include <vector>

using namespace curvenet;

namespace {

struct Timing {
  double median_ms = 0;
  EmbedReport report;
  std::string error;
};

Timing time_embed(const SurfaceMesh& mesh, const Rig& rig) {
  Timing t;
  std::vector<double> ms;
  try {
    for (int rep = 0; rep < 5; ++rep) {
      const auto t0 = std::chrono::steady_clock::now();
      const Embedding e = embed(mesh, rig);
      ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      t.report = e.report();
    }
  } catch (const std::exception& err) {
    t.error = err.what();
    return t;
  }
  std::sort(ms.begin(), ms.end());
  t.median_ms = ms[ms.size() / 2];
  return t;
}

SurfaceMesh bench_tube(int around) {
  TubeSpec spec;
  spec.around = around;
  spec.along = around / 2;
  spec.cap_rings = std::max(2, around / 8);
  spec.triangulate = true;
  return make_surface_mesh(make_capped_tube(spec), "tube");
}

} // namespace

int main(int argc, char** argv) {
  const long max_faces = argc > 1 ? std::atol(argv[1]) : 1300000;
  const Rig rig = make_tube_net();
  std::printf("%10s %10s %10s %12s %12s %8s\n", "faces", "crossings", "regions", "median_ms", "ms/kface", "ok");
  for (const int around : {24, 48, 96, 192, 384, 832}) {
    const SurfaceMesh mesh = bench_tube(around);
    if (mesh.num_faces() > max_faces)
      break;
    const Timing t = time_embed(mesh, rig);
    if (!t.error.empty()) {
      std::printf("%10d  embedding failed: %s\n", mesh.num_faces(), t.error.c_str());
      continue;
    }
    std::printf("%10d %10d %10d %12.2f %12.4f %8s\n", mesh.num_faces(), t.report.crossings, t.report.regions,
                t.median_ms, t.median_ms / (mesh.num_faces() / 1000.0), t.report.ok ? "yes" : "NO");
    std::fflush(stdout);
  }

  // Profile count, on one mesh of about 55k faces.
  const SurfaceMesh mesh = bench_tube(192);
  std::printf("\n%10s %10s %10s %10s %12s %12s %8s\n", "faces", "profiles", "crossings", "regions", "median_ms",
              "ms/profile", "ok");
  for (const auto& [rings, per_ring] : std::vector<std::pair<int, int>>{{3, 4}, {6, 8}, {12, 8}, {12, 16}, {24, 16}}) {
    TubeNetSpec spec;
    spec.ring_heights.clear();
    for (int i = 0; i < rings; ++i)
      spec.ring_heights.push_back(0.3 + 3.4 * i / (rings - 1));
    spec.nodes_per_ring = per_ring;
    const Rig net = make_tube_net(spec);
    const Timing t = time_embed(mesh, net);
    if (!t.error.empty()) {
      std::printf("%10d %10zu  embedding failed: %s\n", mesh.num_faces(), net.profiles.size(), t.error.c_str());
      continue;
    }
    std::printf("%10d %10d %10d %10d %12.2f %12.4f %8s\n", mesh.num_faces(), t.report.profiles, t.report.crossings,
                t.report.regions, t.median_ms, t.median_ms / t.report.profiles, t.report.ok ? "yes" : "NO");
    std::fflush(stdout);
  }

  // The target: about 100 profiles on about 150k faces. Where the
  // time goes, stage by stage (medians of 5), and what the cut costs.
  {
    const SurfaceMesh big = bench_tube(320);
    TubeNetSpec spec;
    spec.ring_heights.clear();
    for (int i = 0; i < 12; ++i)
      spec.ring_heights.push_back(0.3 + 3.4 * i / 11);
    spec.nodes_per_ring = 4;
    const Rig net = make_tube_net(spec);
    std::vector<std::vector<std::pair<std::string, double>>> runs;
    std::vector<double> total;
    EmbedReport rep;
    for (int r = 0; r < 5; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      const Embedding e = embed(big, net);
      total.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
      runs.push_back(e.report().timings_ms);
      rep = e.report();
    }
    std::sort(total.begin(), total.end());
    std::printf("\n%d faces, %d profiles: median %.1f ms; input %d vertices, cut mesh %d vertices (%+.2f%%), "
                "%d samples, %d refinements, fidelity %.3g of the tolerance\n",
                big.num_faces(), rep.profiles, total[2], rep.input_vertices, rep.cut_vertices,
                100.0 * (rep.cut_vertices - rep.input_vertices) / rep.input_vertices, rep.samples, rep.refinements,
                rep.fidelity_max / rep.fidelity_tolerance);
    for (size_t k = 0; k < runs[0].size(); ++k) {
      std::vector<double> ms;
      for (const auto& run : runs)
        ms.push_back(run[k].second);
      std::sort(ms.begin(), ms.end());
      std::printf("  %-10s %8.1f ms\n", runs[0][k].first.c_str(), ms[2]);
    }
  }
  return 0;
}
