// Loading at the speed of the parse, and the whole process as a user runs
// it. On the shared hand refined by midpoint subdivision (the same surface,
// 146,496 quads as a 13 MB OBJ of 17-digit numbers, and as 9 MB of 6-digit
// ones, as most exporters write) and a 1M-face capped tube: the OBJ parse
// alone (read_raw_mesh), the load with its validation and welding
// (load_mesh), and `curvenet embed` as a process, on all cores and on one
// (taskset), with the hand's starter net (~160 profiles) or the tube's
// net. Prints one table: the parse and the load as medians of 15 pairs
// (a parse, then a load), their ratio as the median of the pairs' ratios,
// and the processes as medians of 9.
//
//   build/bin/load_bench [CURVENET_CLI]

#include "curvenet/io.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/subdivide.hpp"
#include "generate/tube.hpp"
#include "io/obj_read.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <malloc.h>
#include <string>
#include <vector>

using namespace curvenet;
namespace fs = std::filesystem;

namespace {

template <class F> double median_ms(F&& f, int reps = 9) {
  std::vector<double> ms;
  for (int r = 0; r < reps; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

double process_ms(const std::string& command) {
  return median_ms([&] {
    if (std::system((command + " > /dev/null 2>&1").c_str()) != 0)
      std::fprintf(stderr, "failed: %s\n", command.c_str());
  });
}

void write_obj(const SurfaceMesh& m, const std::string& path) {
  write_file_atomic(path, mesh_to_obj(m.positions, m.face_offsets, m.face_vertices));
}

/// The same mesh with six significant digits, as most exporters write.
void write_short_obj(const SurfaceMesh& m, const std::string& path) {
  std::string text;
  char line[128];
  for (const Vec3& p : m.positions) {
    std::snprintf(line, sizeof line, "v %.6g %.6g %.6g\n", p.x(), p.y(), p.z());
    text += line;
  }
  for (int f = 0; f < m.num_faces(); ++f) {
    text += 'f';
    for (const int v : m.face(f))
      text += ' ' + std::to_string(v + 1);
    text += '\n';
  }
  write_file_atomic(path, text);
}

} // namespace

int main(int argc, char** argv) {
  // The heap as the CLI keeps it (apps/curvenet/main.cpp): freed memory
  // stays for the next repetition, as it does for the next stage there.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  mallopt(M_TOP_PAD, 64 << 20);
  const std::string cli = argc > 1 ? argv[1] : CURVENET_CLI;
  const fs::path dir = fs::temp_directory_path() / "curvenet_load_bench";
  fs::create_directories(dir);
  const std::string data = CURVENET_DATA_DIR;
  // The hand, refined three times (its own surface), and its starter net.
  const std::string hand_gltf = data + "/xr_tools_hand/hand_l.gltf";
  const SurfaceMesh hand = load_mesh(hand_gltf);
  const std::string hand_obj = (dir / "hand_146k.obj").string(), hand_rig = (dir / "hand.cnrig.json").string();
  const std::string hand_short_obj = (dir / "hand_146k_6_digits.obj").string();
  const SurfaceMesh refined = midpoint_subdivide(hand, 3);
  write_obj(refined, hand_obj);
  write_short_obj(refined, hand_short_obj);
  write_rig(make_starter(hand, load_skinned_mesh(hand_gltf).joints).rig, hand_rig);
  // A capped tube of about 1M triangles and the tube net.
  TubeSpec spec;
  spec.around = 600;
  spec.along = 830;
  spec.triangulate = true;
  const std::string tube_obj = (dir / "tube_1m.obj").string(), tube_rig = (dir / "tube.cnrig.json").string();
  const RawMesh tube = make_capped_tube(spec);
  write_file_atomic(tube_obj, mesh_to_obj(tube.positions, tube.face_offsets, tube.face_vertices));
  write_rig(make_tube_net(), tube_rig);

  std::printf("| mesh | faces | file | parse (read_raw_mesh) | load (load_mesh) | load / parse | curvenet embed, "
              "process, all cores | one core | profiles |\n|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& [obj, rig] :
       {std::pair{hand_obj, hand_rig}, std::pair{hand_short_obj, hand_rig}, std::pair{tube_obj, tube_rig}}) {
    int faces = 0;
    // Each repetition parses: the process keeps its last parse, which a
    // second read of the file would reuse. Parse and load alternate, so
    // that both meet the same moments of a shared machine.
    constexpr int kPairs = 15;
    std::vector<double> parse_ms, load_ms, ratio;
    for (int r = 0; r < kPairs; ++r) {
      parse_ms.push_back(median_ms(
          [&] {
            detail::forget_obj_parse();
            faces = static_cast<int>(read_raw_mesh(obj).face_offsets.size()) - 1;
          },
          1));
      load_ms.push_back(median_ms(
          [&] {
            detail::forget_obj_parse();
            (void)load_mesh(obj);
          },
          1));
      ratio.push_back(load_ms.back() / parse_ms.back());
    }
    // The ratio is the median of each pair's: a pair is measured within a
    // few tens of milliseconds, so a shared machine's slower moments, which
    // last longer, slow both of it alike.
    for (auto* v : {&parse_ms, &load_ms, &ratio})
      std::sort(v->begin(), v->end());
    const double parse = parse_ms[kPairs / 2], load = load_ms[kPairs / 2];
    const std::string embed = cli + " embed " + obj + " " + rig;
    const double all = process_ms(embed), one = process_ms("taskset -c 0 " + embed);
    std::printf("| %s | %d | %.1f MB | %.0f ms | %.0f ms | %.2f | %.0f ms | %.0f ms | %zu |\n",
                fs::path(obj).filename().c_str(), faces, static_cast<double>(fs::file_size(obj)) / (1 << 20), parse,
                load, ratio[kPairs / 2], all, one, read_rig(rig).profiles.size());
  }
  return 0;
}
