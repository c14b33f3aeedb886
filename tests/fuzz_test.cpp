// A seeded mutation fuzzer over the readers: every mesh format but FBX
// (read by assimp, whose binary form is not hardened), the rig and
// pose parsers, and the skin and clip reader. Each seed file (the corpus in
// tests/data, and a few made here) is mutated a few thousand times, with
// byte flips, insertions, deletions, repeats, truncation and numbers
// replaced by hostile ones; every result must read or be refused with a
// curvenet::Error, never crash, hang or throw anything else. Under the
// sanitizer build it runs under ASan and UBSan. The input being read is
// written to fuzz_current.* in the temporary folder first, so that a crash
// leaves it behind: add it to tests/data/bad.
//
//   CURVENET_FUZZ_ITERATIONS (default 3000 per reader) and
//   CURVENET_FUZZ_SECONDS (default 60 in all) bound the run;
//   CURVENET_FUZZ_SEED picks another sequence of mutations.

#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>

using namespace curvenet;
namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

long env_or(const char* name, long fallback) {
  const char* v = std::getenv(name);
  return v ? std::strtol(v, nullptr, 10) : fallback;
}

/// One mutation of `s`, chosen by `rng`.
void mutate(std::string& s, std::mt19937_64& rng) {
  static const char* hostile[] = {"nan",    "-nan",      "inf",         "1e999",      "-1",
                                  "0",      "-0",        "2147483648",  "4294967297", "18446744073709551617",
                                  "1e-320", "999999999", "-2147483649", "3.5",        "",
                                  "abc"};
  auto pick = [&](size_t n) { return n == 0 ? size_t{0} : static_cast<size_t>(rng() % n); };
  switch (rng() % 7) {
  case 0: // flip a bit
    if (!s.empty())
      s[pick(s.size())] ^= static_cast<char>(1u << (rng() % 8));
    break;
  case 1: // a random byte
    if (!s.empty())
      s[pick(s.size())] = static_cast<char>(rng() % 256);
    break;
  case 2: { // insert random bytes
    std::string b(1 + pick(8), '\0');
    for (char& c : b)
      c = static_cast<char>(rng() % 256);
    s.insert(pick(s.size() + 1), b);
    break;
  }
  case 3: // delete a range
    if (!s.empty()) {
      const size_t at = pick(s.size());
      s.erase(at, 1 + pick(std::min<size_t>(64, s.size() - at)));
    }
    break;
  case 4: // repeat a range
    if (!s.empty() && s.size() < (1u << 20)) {
      const size_t at = pick(s.size()), n = 1 + pick(std::min<size_t>(256, s.size() - at));
      s.insert(pick(s.size() + 1), s.substr(at, n));
    }
    break;
  case 5: { // a number replaced by a hostile one
    std::vector<std::pair<size_t, size_t>> numbers;
    for (size_t i = 0; i < s.size();) {
      if (std::isdigit(static_cast<unsigned char>(s[i]))) {
        size_t j = i;
        while (j < s.size() && (std::isdigit(static_cast<unsigned char>(s[j])) || s[j] == '.' || s[j] == 'e' ||
                                s[j] == 'E' || s[j] == '-' || s[j] == '+'))
          ++j;
        numbers.emplace_back(i, j - i);
        i = j;
      } else {
        ++i;
      }
    }
    if (!numbers.empty()) {
      const auto [at, n] = numbers[pick(numbers.size())];
      s.replace(at, n, hostile[pick(std::size(hostile))]);
    }
    break;
  }
  default: // truncate
    if (!s.empty())
      s.resize(pick(s.size()));
  }
}

struct Reader {
  std::string name;
  std::vector<fs::path> seeds;
  std::string extension;
  std::function<void(const std::string& path)> read;
};

} // namespace

TEST(Fuzz, ReadersReadOrRefuseEveryMutatedFile) {
  const auto dir = test::temp_dir("fuzz");
  const fs::path corpus = fs::path(CURVENET_SOURCE_DIR) / "tests" / "data";
  // Seeds made here: a small tube, its net, a pose.
  {
    TubeSpec ts;
    ts.around = 6;
    ts.along = 2;
    ts.cap_rings = 2;
    const RawMesh tube = make_capped_tube(ts);
    write_file_atomic((dir / "seed_tube.obj").string(),
                      mesh_to_obj(tube.positions, tube.face_offsets, tube.face_vertices));
    TubeNetSpec ns;
    ns.points_per_profile = 3;
    write_rig(make_tube_net(ns), (dir / "seed_net.cnrig.json").string());
    write_file_atomic(
        (dir / "seed.pose.json").string(),
        R"({"format":"curvenet-pose","version":1,"joints":{"j1":{"rotation":[0,0,0.38,0.92],"translation":[0,1,0],"scale":[1,1,1]}}})");
  }
  auto seeds_of = [&](const std::string& suffix, std::vector<fs::path> extra) {
    for (const char* sub : {"good", "bad"})
      for (const auto& e : fs::directory_iterator(corpus / sub))
        if (e.path().string().ends_with(suffix))
          extra.push_back(e.path());
    return extra;
  };
  auto shared = [](std::vector<std::string> names) {
    std::vector<fs::path> out;
    if (test::have_data())
      for (const auto& n : names)
        if (fs::exists(test::data(n)))
          out.emplace_back(test::data(n));
    return out;
  };
  std::vector<Reader> readers = {
      {"OBJ", seeds_of(".obj", {dir / "seed_tube.obj"}), ".obj", [](const std::string& p) { load_mesh(p); }},
      {"PLY", seeds_of(".ply", {}), ".ply", [](const std::string& p) { load_mesh(p); }},
      {"GLB", shared({"rigged_simple/RiggedSimple.glb"}), ".glb",
       [](const std::string& p) {
         load_mesh(p);
         load_skinned_mesh(p);
       }},
      {"OFF", seeds_of(".off", {}), ".off", [](const std::string& p) { load_mesh(p); }},
      {"glTF", seeds_of(".gltf", shared({"rigged_simple/RiggedSimple.gltf", "simple_skin/SimpleSkin.gltf"})), ".gltf",
       [](const std::string& p) {
         load_mesh(p);
         const SkinnedMesh s = load_skinned_mesh(p);
         for (int c = 0; c < s.num_clips(); ++c) {
           const auto [t0, t1] = s.clip_range(c);
           s.joint_world(c, (t0 + t1) / 2);
         }
       }},
      {"rig", seeds_of(".cnrig.json", {dir / "seed_net.cnrig.json"}), ".cnrig.json",
       [](const std::string& p) { read_rig(p); }},
      {"pose", seeds_of(".pose.json", {dir / "seed.pose.json"}), ".pose.json",
       [](const std::string& p) { read_pose(p); }},
  };
  const long iterations = env_or("CURVENET_FUZZ_ITERATIONS", 3000);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(env_or("CURVENET_FUZZ_SECONDS", 60));
  std::mt19937_64 rng(static_cast<std::uint64_t>(env_or("CURVENET_FUZZ_SEED", 20261201)));
  long runs = 0, refused = 0;
  for (const Reader& r : readers) {
    if (r.seeds.empty())
      continue; // the shared data is not there

    std::vector<std::string> seeds;
    for (const auto& p : r.seeds)
      seeds.push_back(slurp(p));
    const std::string path = (dir / ("fuzz_current" + r.extension)).string();
    for (long i = 0; i < iterations && std::chrono::steady_clock::now() < deadline; ++i) {
      std::string input = seeds[rng() % seeds.size()];
      const int n = 1 + static_cast<int>(rng() % 4);
      for (int k = 0; k < n; ++k)
        mutate(input, rng);
      {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out.write(input.data(), static_cast<std::streamsize>(input.size()));
      }
      ++runs;
      try {
        r.read(path);
      } catch (const Error& e) {
        ++refused;
        EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << r.name << ": " << e.what();
      } catch (const std::exception& e) {
        const fs::path kept = dir / ("fuzz_failure_" + std::to_string(runs) + r.extension);
        fs::copy_file(path, kept, fs::copy_options::overwrite_existing);
        ADD_FAILURE() << r.name << ": not a curvenet error: " << e.what() << " (input kept as " << kept << ")";
      }
    }
  }
  std::printf("fuzz: %ld mutated files read, %ld refused\n", runs, refused);
  EXPECT_GT(runs, 0);
}
