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

#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"
#include "generate/tube.hpp"
#include "helpers.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <stdexcept>

using namespace curvenet;
namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
  return test::file_bytes(p);
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
         for (const auto& way : s.scene_placings()) // where its scene places its joints: finite, one per joint
           for (const Mat4& m : way)
             if (way.size() != s.joints.size() || !m.allFinite())
               throw std::logic_error("a scene placing that is not finite or not one per joint");
         for (int c = 0; c < s.num_clips(); ++c) {
           const auto [t0, t1] = s.clip_range(c);
           (void)s.joint_world(c, (t0 + t1) / 2);
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

// --- generators of the classes a structural fuzzer found --------------------
//
// Where byte mutations rarely reach a fault, these build it: JSON nested
// deep, profiles of too many points or going out and back, skinned glTF
// files with damaged matrices, joints, keys and versions, and meshes at
// scales far from 1 with their rig scaled alike. Each input is read (and
// embedded where it is a rig on a mesh); it must work or be refused with a
// one-line curvenet::Error, never crash, hang or throw anything else.

namespace {

std::string base64(const std::string& bytes) {
  static const char* digits = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const auto byte = [&](size_t k) { return k < bytes.size() ? static_cast<unsigned char>(bytes[k]) : 0u; };
    const unsigned v = byte(i) << 16 | byte(i + 1) << 8 | byte(i + 2);
    out += digits[v >> 18 & 63];
    out += digits[v >> 12 & 63];
    out += i + 1 < bytes.size() ? digits[v >> 6 & 63] : '=';
    out += i + 2 < bytes.size() ? digits[v & 63] : '=';
  }
  return out;
}

template <class T> void append(std::string& out, const std::vector<T>& values) {
  out.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  out.resize((out.size() + 3) / 4 * 4, '\0');
}

/// A triangle skinned to one joint with a one-key rotation clip, from parts
/// a generator chose.
std::string skinned_triangle(const std::string& version, const std::vector<float>& inverse_bind,
                             const std::vector<unsigned char>& joints, const std::vector<float>& key,
                             const std::string& node_matrix) {
  std::string data;
  std::vector<size_t> offsets;
  auto part = [&](auto values) {
    offsets.push_back(data.size());
    append(data, values);
  };
  part(std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0});
  part(std::vector<unsigned short>{0, 1, 2});
  part(joints);
  part(std::vector<float>{1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0});
  part(inverse_bind);
  part(std::vector<float>{0});
  part(key);
  offsets.push_back(data.size());
  std::string views;
  for (size_t k = 0; k + 1 < offsets.size(); ++k)
    views += (k ? "," : "") + std::string(R"({"buffer":0,"byteOffset":)") + std::to_string(offsets[k]) +
             R"(,"byteLength":)" + std::to_string(offsets[k + 1] - offsets[k]) + "}";
  return R"({"asset":{"version":")" + version + R"("},"scene":0,"scenes":[{"nodes":[0,1]}],)" +
         R"("nodes":[{"mesh":0,"skin":0},{"name":"bone")" + node_matrix + R"(}],)" +
         R"("skins":[{"joints":[1],"inverseBindMatrices":4}],)" +
         R"("meshes":[{"primitives":[{"attributes":{"POSITION":0,"JOINTS_0":2,"WEIGHTS_0":3},"indices":1}]}],)" +
         R"("buffers":[{"byteLength":)" + std::to_string(data.size()) +
         R"(,"uri":"data:application/octet-stream;base64,)" + base64(data) + R"("}],"bufferViews":[)" + views +
         R"(],"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},)" +
         R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"},)" +
         R"({"bufferView":2,"componentType":5121,"count":3,"type":"VEC4"},)" +
         R"({"bufferView":3,"componentType":5126,"count":3,"type":"VEC4"},)" +
         R"({"bufferView":4,"componentType":5126,"count":1,"type":"MAT4"},)" +
         R"({"bufferView":5,"componentType":5126,"count":1,"type":"SCALAR","min":[0],"max":[0]},)" +
         R"({"bufferView":6,"componentType":5126,"count":1,"type":"VEC4"}],)" +
         R"("animations":[{"name":"turn","samplers":[{"input":5,"output":6,"interpolation":"LINEAR"}],)" +
         R"("channels":[{"sampler":0,"target":{"node":1,"path":"rotation"}}]}]})";
}

/// Reads `text` as a file of `extension` with `read`: read, or refused in one line.
void expect_read_or_refused(const fs::path& dir, const std::string& text, const std::string& extension,
                            const std::function<void(const std::string&)>& read, const std::string& what,
                            int& refused) {
  const std::string path = (dir / ("generated" + extension)).string();
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << text;
  }
  try {
    read(path);
  } catch (const Error& e) {
    ++refused;
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << what << ": " << e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << what << ": not a curvenet error: " << e.what();
  }
}

} // namespace

TEST(Fuzz, GeneratedFaultsOfEveryClassAreReadOrRefusedInOneLine) {
  const auto dir = test::temp_dir("fuzz_generated");
  std::mt19937_64 rng(static_cast<std::uint64_t>(env_or("CURVENET_FUZZ_SEED", 20261202)));
  auto uniform = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  int cases = 0, refused = 0;
  const auto read_gltf = [](const std::string& p) {
    load_mesh(p);
    const SkinnedMesh s = load_skinned_mesh(p);
    for (int c = 0; c < s.num_clips(); ++c)
      (void)s.joint_world(c, 0);
  };
  // JSON nested from just under the bound to far past it, in each reader.
  for (const int depth : {8, 60, 65, 1000, 200000}) {
    const std::string nest = std::string(depth, '[') + std::string(depth, ']');
    expect_read_or_refused(
        dir, R"({"format":"curvenet-rig","version":1,"nodes":)" + nest + "}", ".cnrig.json",
        [](const std::string& p) { read_rig(p); }, "rig nested " + std::to_string(depth), refused);
    expect_read_or_refused(
        dir, R"({"format":"curvenet-pose","version":1,"joints":)" + nest + "}", ".pose.json",
        [](const std::string& p) { read_pose(p); }, "pose nested " + std::to_string(depth), refused);
    expect_read_or_refused(dir, R"({"asset":{"version":"2.0"},"extras":)" + nest + "}", ".gltf", read_gltf,
                           "glTF nested " + std::to_string(depth), refused);
    cases += 3;
  }
  // Skinned triangles with a damaged part each, chosen at random.
  const std::vector<std::string> versions{"2.0", "2.1", "1.0", "", "3.0", "two"};
  for (int k = 0; k < 200; ++k) {
    std::vector<float> ibm{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    std::vector<unsigned char> joints(12, 0);
    std::vector<float> key{0, 0, 0, 1};
    std::string matrix;
    switch (rng() % 5) {
    case 0: // a matrix entry anywhere, the last row included
      ibm[rng() % 16] =
          static_cast<float>(std::pow(10.0, uniform(-40, 38)) * (rng() % 2 ? 1 : -1)) * (rng() % 3 ? 1.0f : 0.0f);
      break;
    case 1: // a joint index past the skin
      joints[rng() % 12] = static_cast<unsigned char>(rng() % 256);
      break;
    case 2: // a rotation key, maybe zero, maybe huge
      for (float& q : key)
        q = rng() % 3 ? static_cast<float>(uniform(-1, 1)) : 0.0f;
      break;
    case 3: { // a node matrix, maybe projective or singular
      std::vector<double> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
      m[rng() % 16] = rng() % 2 ? 0.0 : uniform(-3, 3);
      matrix = R"(,"matrix":[)";
      for (int i = 0; i < 16; ++i)
        matrix += (i ? "," : "") + std::to_string(m[i]);
      matrix += "]";
      break;
    }
    default:
      break;
    }
    expect_read_or_refused(dir, skinned_triangle(versions[rng() % versions.size()], ibm, joints, key, matrix), ".gltf",
                           read_gltf, "skinned triangle " + std::to_string(k), refused);
    ++cases;
  }
  // Profiles: too many points, or a loop out and back along itself.
  for (const size_t n : {size_t{99999}, size_t{100001}, size_t{1000000}}) {
    std::string points;
    for (size_t i = 0; i < n; ++i)
      points += (i ? ",[" : "[") + std::to_string(static_cast<double>(i) / static_cast<double>(n)) + ",0.5,0]";
    expect_read_or_refused(
        dir,
        R"({"format":"curvenet-rig","version":1,"nodes":[{"id":"a","position":[0,0.5,0]},{"id":"b","position":[1,0.5,0]}],"profiles":[{"id":"p","from":"a","to":"b","points":[)" +
            points + "]}]}",
        ".cnrig.json", [](const std::string& p) { read_rig(p); }, std::to_string(n) + " points", refused);
    ++cases;
  }
  for (int k = 0; k < 20; ++k) {
    const double x = uniform(0.1, 1), y = uniform(0, 1);
    const std::string out_and_back = "[[0,0,0],[" + std::to_string(x) + "," + std::to_string(y) + ",0],[0,0,0]]";
    expect_read_or_refused(
        dir,
        R"({"format":"curvenet-rig","version":1,"nodes":[{"id":"a","position":[0,0,0]}],"profiles":[{"id":"p","from":"a","to":"a","points":)" +
            out_and_back + "}]}",
        ".cnrig.json", [](const std::string& p) { read_rig(p); }, "out and back", refused);
    ++cases;
  }
  // Work that grows faster than the file: a grid with loose vertices
  // beside it (no face uses them; each follows its nearest surface vertex).
  // A search of every vertex for each took 90 s for 60k of them (this
  // case: about 6e9 distances); surface_mesh_test checks the answer.
  {
    std::ostringstream obj;
    obj.precision(17);
    const int side = 200;
    for (int j = 0; j <= side; ++j)
      for (int i = 0; i <= side; ++i)
        obj << "v " << i << ' ' << j << " 0\n";
    for (int k = 0; k < 150000; ++k)
      obj << "v " << uniform(-10, side + 10) << ' ' << uniform(-10, side + 10) << ' ' << uniform(-5, 5) << '\n';
    for (int j = 0; j < side; ++j)
      for (int i = 0; i < side; ++i) {
        const int a = j * (side + 1) + i + 1;
        obj << "f " << a << ' ' << a + 1 << ' ' << a + side + 2 << ' ' << a + side + 1 << '\n';
      }
    expect_read_or_refused(
        dir, obj.str(), ".obj",
        [](const std::string& p) {
          if (load_mesh(p).input_to_welded.size() != 150000 + 201 * 201)
            throw std::runtime_error("the loose vertices were not all mapped");
        },
        "150k loose vertices", refused);
    ++cases;
  }
  // A tube and its net scaled alike by 10^k, k from -200 to 200: the same
  // embedding, or refused as out of range in one line.
  for (int k = 0; k < 24; ++k) {
    const double s = std::pow(10.0, std::round(uniform(-200, 200)));
    Mat4 m = Mat4::Identity();
    m.topLeftCorner<3, 3>() *= s;
    Rig rig = make_tube_net();
    rig.frame = m;
    try {
      const Embedding e = embed(test::tube(16, 12, 4, true, m), rig);
      EXPECT_TRUE(e.report().ok) << "scale " << s;
      EXPECT_EQ(e.report().regions, 16) << "scale " << s;
    } catch (const Error& e) {
      ++refused;
      EXPECT_NE(std::string(e.what()).find("within 1e-40 to 1e40"), std::string::npos)
          << "scale " << s << ": " << e.what();
    }
    ++cases;
  }
  std::printf("generated: %d cases, %d refused\n", cases, refused);
  EXPECT_GT(refused, 0);
}
