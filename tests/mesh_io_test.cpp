// Mesh readers against damaged files: every fault is refused with the file,
// the line or element, and what is wrong; valid but unusual files read.
// The damaged files live in tests/data/bad/, one fault each.

#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "curvenet/mesh_output.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/rig.hpp"
#include "curvenet/skin.hpp"
#include "helpers.hpp"
#include "io/gltf_scene.hpp"
#include "io/obj_read.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

using namespace curvenet;
namespace fs = std::filesystem;

namespace {
std::string corpus(const std::string& name) {
  return std::string(CURVENET_SOURCE_DIR) + "/tests/data/" + name;
}

/// Loading refuses the file with an InputError naming the file and the
/// element, whose message holds `says`.
void expect_refused(const std::string& name, const std::string& element, const std::string& says) {
  const std::string path = corpus(name);
  try {
    load_mesh(path);
    ADD_FAILURE() << name << " was read";
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.element(), element) << e.what();
    EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  }
}
} // namespace

TEST(MeshIo, ObjCoordinatesMustBeFiniteNumbers) {
  expect_refused("bad/obj_nan.obj", "line 1", "'nan' is not a finite number");
  expect_refused("bad/obj_inf.obj", "line 1", "'inf' is not a finite number");
  expect_refused("bad/obj_word.obj", "line 1", "'abc' is not a finite number");
  expect_refused("bad/obj_comma.obj", "line 1", "'1,5' is not a finite number");
  expect_refused("bad/obj_hex.obj", "line 1", "'0x10' is not a finite number");
  expect_refused("bad/obj_overflow.obj", "line 1", "'1e999' is not a finite number");
  expect_refused("bad/obj_missing_z.obj", "line 1", "vertex has 2 coordinates, needs 3");
  expect_refused("bad/obj_normal_nan.obj", "line 4", "normal coordinate 'nan'");
}

TEST(MeshIo, ObjIndicesMustReferToElementsThatExist) {
  expect_refused("bad/obj_vertex_out_of_range.obj", "line 4", "refers to vertex 99, and the file has 3");
  expect_refused("bad/obj_normal_out_of_range.obj", "line 5", "refers to normal 99999, and the file has 1");
  expect_refused("bad/obj_texcoord_out_of_range.obj", "line 5", "refers to texture coordinate 7");
  expect_refused("bad/obj_zero_index.obj", "line 4", "index 0");
  expect_refused("bad/obj_negative_out_of_range.obj", "line 4", "refers to vertex -4, and there are 3 before it");
  expect_refused("bad/obj_four_indices.obj", "line 4", "more than three indices");
}

TEST(MeshIo, ObjFacesNeedThreeCorners) {
  expect_refused("bad/obj_two_corners.obj", "line 5", "face has 2 corners, needs at least 3");
}

TEST(MeshIo, ObjWithRelativeIndicesCommentsAndColoursReads) {
  const SurfaceMesh m = load_mesh(corpus("good/obj_relative.obj"));
  EXPECT_EQ(m.num_vertices(), 4);
  EXPECT_EQ(m.num_faces(), 4);
}

TEST(MeshIo, AnObjLineEndingInABackslashGoesOnOnTheNext) {
  // The OBJ format's line continuation was refused ("'\' is not an index").
  // Joined lines read as one; an error on a later line keeps its number.
  const std::string plain = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n";
  const std::string continued = "v 0 0 0\nv 1 \\\n0 0\nv 0 1 0\nv 0 0 1\nf 1 2 \\\r\n 3\nf 1 \\\n3 \\\n4\n";
  const detail::ObjData a = detail::read_obj_bytes("plain.obj", plain);
  const detail::ObjData b = detail::read_obj_bytes("continued.obj", continued);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.face_offsets, b.face_offsets);
  EXPECT_EQ(a.corner_vertex, b.corner_vertex);
  // A last line that ends in a backslash goes on to nothing (the joined
  // line was read past its end: AddressSanitizer found it).
  EXPECT_EQ(detail::read_obj_bytes("last.obj", plain + "v 1 1 1 \\").positions.size(), 5u);
  // A comment that ends in a backslash (a Windows path) goes on nowhere.
  const detail::ObjData c = detail::read_obj_bytes("comment.obj", "# from C:\\models\\\n" + plain);
  EXPECT_EQ(c.positions, a.positions);
  try {
    (void)detail::read_obj_bytes("late.obj", continued + "v 1 x 0\n");
    ADD_FAILURE() << "a bad coordinate was read";
  } catch (const InputError& e) {
    EXPECT_EQ(e.element(), "line 11") << e.what();
  }
}

TEST(MeshIo, ObjReadsEveryElementWithItsIndicesInFileOrder) {
  // Windows line ends, tabs, comments after data, groups, materials, a
  // vertex with colours, a texture coordinate with u alone, every corner
  // form, negative indices that count back from the face, and a positive
  // index that refers further down the file.
  const std::string text = "# a comment\r\n"
                           "mtllib m.mtl\r\n"
                           "o first\r\n"
                           "v 0 0 0 1 0.5 0.25\r\n"
                           "v\t1 0 0 # a comment after data\r\n"
                           "v +1 1 0\r\n"
                           "vt 0.5\r\n"
                           "vt 0 1 0\r\n"
                           "vn 0 0 1\r\n"
                           "usemtl red\r\n"
                           "f 1/1/1 2/2/1 3//1\r\n"
                           "g second\r\n"
                           "s 1\r\n"
                           "f -3 -1 4\r\n"
                           "v 0 1e0 0\r\n"
                           "l 1 2\r\n";
  const detail::ObjData d = detail::read_obj_bytes("inline.obj", text);
  ASSERT_EQ(d.positions.size(), 4u);
  EXPECT_EQ(d.positions[0], Vec3(0, 0, 0));
  EXPECT_EQ(d.positions[2], Vec3(1, 1, 0));
  EXPECT_EQ(d.positions[3], Vec3(0, 1, 0));
  ASSERT_EQ(d.texcoords.size(), 2u);
  EXPECT_EQ(d.texcoords[0], Eigen::Vector2d(0.5, 0));
  EXPECT_EQ(d.texcoords[1], Eigen::Vector2d(0, 1));
  ASSERT_EQ(d.normals.size(), 1u);
  EXPECT_EQ(d.face_offsets, (std::vector<int>{0, 3, 6}));
  EXPECT_EQ(d.corner_vertex, (std::vector<int>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(d.corner_texcoord, (std::vector<int>{0, 1, -1, -1, -1, -1}));
  EXPECT_EQ(d.corner_normal, (std::vector<int>{0, 0, 0, -1, -1, -1}));
  // Each number as written, to the last bit (17 significant digits).
  const double x = 0.1234567890123456789, y = -9.87654321e-30, z = 1e300;
  std::ostringstream exact;
  exact.precision(17);
  exact << "v " << x << ' ' << y << ' ' << z << "\nv 0 0 0\nv 1 0 0\nf 1 2 3";
  EXPECT_EQ(detail::read_obj_bytes("exact.obj", exact.str()).positions[0], Vec3(x, y, z));
  // A UTF-8 byte order mark before the first line is not part of it.
  EXPECT_EQ(detail::read_obj_bytes("bom.obj", "\xEF\xBB\xBFv 1 2 3\nv 0 0 0\nv 1 0 0\nf 1 2 3\n").positions[0],
            Vec3(1, 2, 3));
}

TEST(MeshIo, ObjNormalsThatSomeFacesDoNotUseGiveEveryCornerAnExistingSlot) {
  // Two faces use the file's two normals; the other two have none, so their
  // four vertices get slots of their own after the file's.
  const InputTopology t = read_input_topology(corpus("good/obj_some_normals.obj"));
  EXPECT_EQ(t.num_normals, 2 + 4);
  for (int slot : t.corner_normal) {
    EXPECT_GE(slot, 0);
    EXPECT_LT(slot, t.num_normals);
  }
  const std::string text = posed_obj(t, t.faces.positions);
  const fs::path out = fs::temp_directory_path() / "curvenet_mesh_io_normals.obj";
  write_file_atomic(out.string(), text);
  EXPECT_EQ(load_mesh(out.string()).num_faces(), 4);
  fs::remove(out);
}

TEST(MeshIo, PlyAndOffReadTheirVerticesInFileOrder) {
  // The same tetrahedron as ASCII PLY, binary PLY of both byte orders (with
  // extra properties and an extra element to read past) and COFF with
  // vertex and face colours.
  for (const char* name : {"good/ply_ascii.ply", "good/ply_binary_big_endian.ply", "good/ply_binary_little_endian.ply",
                           "good/off_colours.off"}) {
    SCOPED_TRACE(name);
    const RawMesh raw = read_raw_mesh(corpus(name));
    ASSERT_EQ(raw.positions.size(), 4u);
    EXPECT_EQ(raw.positions[1], Eigen::Vector3d(1, 0, 0));
    EXPECT_EQ(raw.positions[3], Eigen::Vector3d(0, 0, 1));
    ASSERT_EQ(raw.face_offsets.size(), 5u);
    EXPECT_EQ(raw.face_vertices[1], 2);
    EXPECT_EQ(raw.face_vertices.back(), 3);
    EXPECT_EQ(load_mesh(corpus(name)).num_faces(), 4);
  }
}

TEST(MeshIo, PlyHeadersAndCountsAreCheckedBeforeTheData) {
  expect_refused("bad/ply_no_end_header.ply", "header", "no 'end_header' line");
  expect_refused("bad/ply_huge_count.ply", "element vertex", "declares 2147483648 records");
  expect_refused("bad/ply_truncated_binary.ply", "face 3", "truncated");
  expect_refused("bad/ply_index_out_of_range.ply", "face 3", "refers to vertex 9, and there are 4");
  expect_refused("bad/ply_negative_index.ply", "face 2", "refers to vertex -2");
  expect_refused("bad/ply_nan.ply", "vertex 1", "'nan' is not a finite number");
  expect_refused("bad/ply_two_corners.ply", "face 3", "a face has 2 corners");
}

TEST(MeshIo, OffCountsAndIndicesAreChecked) {
  expect_refused("bad/off_not_off.off", "header", "not an OFF file");
  expect_refused("bad/off_huge_count.off", "header", "declares 2147483648 vertices");
  expect_refused("bad/off_index_out_of_range.off", "face 3", "refers to vertex 4, and there are 4");
  expect_refused("bad/off_nan.off", "vertex 2", "'inf' is not a finite number");
  // Too short for its counts: found from the header alone.
  expect_refused("bad/off_truncated.off", "header", "more than the file's 64 bytes can hold");
}

TEST(MeshIo, GltfIndicesBoundsAndHierarchyAreCheckedBeforeAnythingReadsThem) {
  EXPECT_EQ(load_mesh(corpus("good/gltf_triangle.gltf")).num_faces(), 1);
  expect_refused("bad/gltf_scene_out_of_range.gltf", "scene", "the default scene 7 does not exist");
  expect_refused("bad/gltf_count_overflow.gltf", "mesh 0 primitive 0 POSITION",
                 "accessor of 1152921504606846977 elements reads past the end of its buffer view");
  expect_refused("bad/gltf_view_past_buffer.gltf", "mesh 0 primitive 0 POSITION", "reaches past the end of buffer 0");
  expect_refused("bad/gltf_node_cycle.gltf", "node 0", "the node hierarchy has a cycle");
  expect_refused("bad/gltf_own_child.gltf", "node 1", "is its own child");
  expect_refused("bad/gltf_mesh_out_of_range.gltf", "node 0", "refers to mesh 5, and there are 1");
  expect_refused("bad/gltf_position_vec2.gltf", "mesh 0 primitive 0 POSITION", "wrong type");
  expect_refused("bad/gltf_indices_vec3.gltf", "mesh 0 primitive 0 indices", "wrong type");
  // A texture coordinate is written out again (OBJ vt, a bake's TEXCOORD_0): never a non-finite one.
  expect_refused("bad/gltf_nan_texcoord.gltf", "mesh 0 primitive 0 TEXCOORD_0 2", "is not a finite number");
}

TEST(MeshIo, GltfAnimationsAreCheckedOnLoad) {
  expect_refused("bad/gltf_rotation_vec3.gltf", "animation 0 'spin' channel 0", "a rotation output must be VEC4");
  expect_refused("bad/gltf_times_not_increasing.gltf", "animation 0 'spin' sampler 0 input",
                 "key times do not increase at key 1");
  expect_refused("bad/gltf_bad_interpolation.gltf", "animation 0 'spin' sampler 0", "unknown interpolation 'SMOOTH'");
  expect_refused("bad/gltf_sampler_out_of_range.gltf", "animation 0 'spin' channel 0", "refers to sampler 3");
  expect_refused("bad/gltf_bad_path.gltf", "animation 0 'spin' channel 0", "unknown target path 'colour'");
  expect_refused("bad/gltf_nan_translation.gltf", "", "number overflow");
}

TEST(MeshIo, AFolderOrAnEmptyFileIsSaidToBeOne) {
  const std::string folder = corpus("bad");
  try {
    load_mesh(folder);
    ADD_FAILURE() << "a folder was read";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), folder + ": is a folder, not a mesh file");
  }
  const fs::path empty = fs::temp_directory_path() / "curvenet_mesh_io_empty.obj";
  { std::ofstream out(empty); }
  EXPECT_THROW(load_mesh(empty.string()), InputError);
  EXPECT_THROW(read_rig(folder), InputError);
  fs::remove(empty);
}

TEST(MeshIo, AGltfBufferThatIsAFolderOrAFifoIsRefusedNotReadOrWaitedOn) {
  // A buffer URI naming a folder ended in std::bad_alloc; one naming a FIFO
  // that no one writes blocked for ever (tinygltf opens a file to see that
  // it is there). Both are refused in one line that names the glTF file.
  expect_refused("bad/gltf_buffer_uri_folder.gltf", "", "is not a regular file");
  const fs::path dir = fs::temp_directory_path() / "curvenet_mesh_io_fifo";
  fs::remove_all(dir);
  fs::create_directories(dir);
  ASSERT_EQ(::mkfifo((dir / "buffer.bin").c_str(), 0600), 0);
  std::string text = test::file_bytes(corpus("bad/gltf_buffer_uri_folder.gltf"));
  const std::string folder_uri = "\"uri\": \".\"";
  text.replace(text.find(folder_uri), folder_uri.size(), "\"uri\": \"buffer.bin\"");
  { std::ofstream(dir / "fifo.gltf") << text; }
  try {
    load_mesh((dir / "fifo.gltf").string());
    ADD_FAILURE() << "a FIFO was read as a buffer";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'" + (dir / "buffer.bin").string() + "' is not a regular file"),
              std::string::npos)
        << e.what();
  }
  fs::remove_all(dir);
}

TEST(MeshIo, ARigOrPoseFromAFifoIsReadWhenWrittenAndRefusedWhenNoOneWrites) {
  // Opening a FIFO that no one writes blocks for ever: a rig, a pose or a
  // clip named so hung. A FIFO that is written (a shell's <(...)) is read; one
  // that no one writes within 5 s is refused, and a mesh, which is read more
  // than once, is refused as not a regular file rather than as missing.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const fs::path dir = fs::temp_directory_path() / "curvenet_rig_fifo";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path fifo = dir / "rig.cnrig.json";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string rig_text = test::file_bytes(test::data("xr_tools_hand/example/hand_l.cnrig.json"));
  std::thread writer([&] { std::ofstream(fifo) << rig_text; });
  EXPECT_EQ(read_rig(fifo.string()).profiles.size(), parse_rig(rig_text, "tube").profiles.size());
  writer.join();
  for (const bool pose : {false, true})
    try {
      if (pose)
        (void)read_pose(fifo.string());
      else
        (void)read_rig(fifo.string());
      ADD_FAILURE() << "a FIFO no one writes was read";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("a FIFO that no one wrote to"), std::string::npos) << e.what();
    }
  try {
    (void)load_mesh(fifo.string());
    ADD_FAILURE() << "a FIFO was read as a mesh";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(MeshIo, AsciiFbxArraysTheFileCannotHoldAreRefusedBeforeAssimpAllocatesThem) {
  EXPECT_EQ(load_mesh(corpus("good/fbx_ascii.fbx")).num_faces(), 4);
  expect_refused("bad/fbx_huge_array.fbx", "line 11", "an array declares 2147483648 values");
}

// --- outputs, all or nothing ------------------------------------------------

namespace {
std::string slurp(const fs::path& p) {
  return test::file_bytes(p);
}
} // namespace

TEST(OutputFiles, AFailedSetLeavesNeitherFilesNorTheFoldersItMade) {
  const fs::path dir = fs::temp_directory_path() / "curvenet_output_files_folders";
  fs::remove_all(dir);
  fs::create_directories(dir / "kept");
  {
    OutputFiles out;
    out.add((dir / "kept" / "a.txt").string(), "a");
    out.add((dir / "new" / "deeper" / "b.txt").string(), "b");
    EXPECT_TRUE(fs::exists(dir / "new" / "deeper"));
    // No commit: as when a later frame fails or the disk fills.
  }
  EXPECT_TRUE(fs::exists(dir / "kept")); // there before: stays
  EXPECT_TRUE(fs::is_empty(dir / "kept"));
  EXPECT_FALSE(fs::exists(dir / "new"));
  {
    OutputFiles out;
    out.add((dir / "new" / "deeper" / "b.txt").string(), "b");
    out.commit();
  }
  EXPECT_EQ(slurp(dir / "new" / "deeper" / "b.txt"), "b");
  // A file where a folder should be is named as such (an OBJ sequence given
  // a file's name), the set and the file left as they were.
  std::ofstream(dir / "a_file") << "mine";
  for (const fs::path& into : {dir / "a_file" / "frame_0000.obj", dir / "a_file" / "sub" / "frame_0000.obj"}) {
    OutputFiles out;
    out.add((dir / "kept" / "c.txt").string(), "c");
    try {
      out.add(into.string(), "v 0 0 0\n");
      ADD_FAILURE() << into << " was opened";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find((dir / "a_file").string() + " is a file, not a folder"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_EQ(slurp(dir / "a_file"), "mine");
  EXPECT_FALSE(fs::exists(dir / "kept" / "c.txt"));
  fs::remove_all(dir);
}

TEST(OutputFiles, ADeviceOrAFifoIsWrittenInPlaceNeverReplaced) {
  // A device node of the test's own (the null device's numbers), never the
  // machine's /dev/null. Making one needs root; without it only the FIFO runs.
  const fs::path dir = fs::temp_directory_path() / "curvenet_output_files_devices";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path null = dir / "null";
  if (::mknod(null.c_str(), S_IFCHR | 0666, makedev(1, 3)) == 0) {
    write_file_atomic(null.string(), "thrown away");
    OutputFiles out;
    out.add(null.string(), "twice");
    out.add((dir / "beside.txt").string(), "kept");
    out.commit();
    EXPECT_TRUE(fs::is_character_file(null));
    EXPECT_EQ(slurp(dir / "beside.txt"), "kept");
    for (const auto& e : fs::directory_iterator(dir))
      EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
  }
  const fs::path fifo = dir / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0666), 0);
  std::string got;
  std::thread reader([&] { got = slurp(fifo); });
  write_file_atomic(fifo.string(), "through the pipe");
  reader.join();
  EXPECT_EQ(got, "through the pipe");
  EXPECT_TRUE(fs::is_fifo(fifo));
  fs::remove_all(dir);
}

TEST(OutputFiles, TwoOutputsGivenOneFileAreRefusedAndTheFileIsLeftAsItWas) {
  const fs::path dir = fs::temp_directory_path() / "curvenet_output_files_twice";
  fs::remove_all(dir);
  fs::create_directories(dir / "sub");
  std::ofstream(dir / "old.glb") << "OLD";
  fs::create_symlink(dir / "old.glb", dir / "link.glb");
  // The same file however it is spelled: as given, through "sub/..", through a link.
  for (const fs::path& again : {dir / "old.glb", dir / "sub" / ".." / "old.glb", dir / "link.glb"}) {
    SCOPED_TRACE(again.string());
    OutputFiles out;
    out.add((dir / "old.glb").string(), "the mesh");
    try {
      out.add(again.string(), "the weights");
      ADD_FAILURE() << "not refused";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("two outputs"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(slurp(dir / "old.glb"), "OLD");
  // Two files, or a device given twice (written in place, both times), are fine.
  {
    OutputFiles out;
    out.add((dir / "a.txt").string(), "a");
    out.add((dir / "sub" / "a.txt").string(), "b");
    out.commit();
  }
  EXPECT_EQ(slurp(dir / "sub" / "a.txt"), "b");
  const fs::path null = dir / "null";
  if (::mknod(null.c_str(), S_IFCHR | 0666, makedev(1, 3)) == 0) {
    OutputFiles out;
    out.add(null.string(), "one");
    out.add(null.string(), "two");
    out.commit();
    EXPECT_TRUE(fs::is_character_file(null));
  }
  fs::remove_all(dir);
}

TEST(OutputFiles, ASymbolicLinkKeepsItsPlaceAndTheFileItNamesIsReplaced) {
  const fs::path dir = fs::temp_directory_path() / "curvenet_output_files_link";
  fs::remove_all(dir);
  fs::create_directories(dir / "real");
  std::ofstream(dir / "real" / "r.json") << "old";
  fs::create_symlink(dir / "real" / "r.json", dir / "link.json");
  write_file_atomic((dir / "link.json").string(), "new");
  EXPECT_TRUE(fs::is_symlink(dir / "link.json"));
  EXPECT_EQ(slurp(dir / "real" / "r.json"), "new");
  // A folder is not a file to write.
  EXPECT_THROW(write_file_atomic((dir / "real").string(), "x"), Error);
  fs::remove_all(dir);
}

TEST(OutputFiles, ASequenceOfMoreFilesThanTheProcessMayOpenIsWrittenAndItsStaleTemporariesGo) {
  // An OBJ sequence of thousands of frames is one set of outputs: each file
  // is closed once written (1,020 frames had failed under the usual limit
  // of 1,024 open files), and a killed run's temporaries beside any of them
  // go, the folder read once.
  const fs::path dir = fs::temp_directory_path() / "curvenet_output_files_many";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path stale = dir / "f_0150.obj.tmp-curvenet-2147483646", live = dir / "f_0151.obj.tmp-curvenet-1";
  std::ofstream(stale) << "half a frame";
  std::ofstream(live) << "another run's";
  rlimit before{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &before), 0);
  rlimit low = before;
  low.rlim_cur = std::min<rlim_t>(before.rlim_cur, 64);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &low), 0);
  bool written = false;
  std::string why;
  try {
    OutputFiles files;
    for (int k = 0; k < 300; ++k)
      files.add((dir / ("f_" +
                        std::string(k < 10    ? "000"
                                    : k < 100 ? "00"
                                              : "0") +
                        std::to_string(k) + ".obj"))
                    .string(),
                "v " + std::to_string(k) + " 0 0\n");
    files.commit();
    written = true;
  } catch (const Error& e) {
    why = e.what();
  }
  ::setrlimit(RLIMIT_NOFILE, &before);
  ASSERT_TRUE(written) << why;
  EXPECT_EQ(slurp(dir / "f_0299.obj"), "v 299 0 0\n");
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(live)); // pid 1 is alive
  int left = 0;
  for (const auto& e : fs::directory_iterator(dir))
    left += e.path().filename().string().find(".tmp-curvenet-") != std::string::npos;
  EXPECT_EQ(left, 1);
  fs::remove_all(dir);
}

TEST(MeshIo, AGltfFileIsParsedOnceForItsSurfaceTopologyAndSkin) {
  // What a command takes from one glTF file (pose: the surface, the input
  // topology, the skin) comes from one parse; a file changed since is
  // parsed again.
  if (!test::have_data())
    GTEST_SKIP() << "no shared data";
  const fs::path dir = fs::temp_directory_path() / "curvenet_gltf_once";
  fs::create_directories(dir);
  const fs::path copy = dir / "rs.gltf";
  fs::copy_file(test::data("rigged_simple/RiggedSimple.gltf"), copy, fs::copy_options::overwrite_existing);
  const long before = detail::gltf_parses();
  const SurfaceMesh mesh = load_mesh(copy.string());
  const InputTopology topology = read_input_topology(copy.string());
  const SkinnedMesh skin = load_skinned_mesh(copy.string());
  EXPECT_EQ(detail::gltf_parses() - before, 1);
  EXPECT_EQ(topology.faces.positions.size(), mesh.input_to_welded.size());
  EXPECT_EQ(skin.vertex_joint.size(), topology.faces.positions.size());
  // Rewritten (another size): read again, and what it now holds.
  std::string text = slurp(copy);
  text += "\n";
  std::ofstream(copy, std::ios::binary | std::ios::trunc) << text;
  (void)load_mesh(copy.string());
  EXPECT_EQ(detail::gltf_parses() - before, 2);
  fs::remove_all(dir);
}

TEST(MeshIo, AnObjFileIsParsedOnceForItsSurfaceAndTopology) {
  // pose reads an OBJ's surface (load_mesh) and its topology (UVs and
  // normals, read_input_topology): one parse; a changed file is parsed again.
  const fs::path dir = fs::temp_directory_path() / "curvenet_obj_once";
  fs::create_directories(dir);
  const fs::path obj = dir / "quad.obj";
  std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";
  const long before = detail::obj_parses();
  const SurfaceMesh mesh = load_mesh(obj.string());
  const InputTopology topology = read_input_topology(obj.string());
  EXPECT_EQ(detail::obj_parses() - before, 1);
  EXPECT_EQ(mesh.num_faces(), 1);
  EXPECT_EQ(topology.uv.size(), 4u);
  std::ofstream(obj, std::ios::app) << "v 2 2 0\nf 2 5 3\n";
  EXPECT_EQ(load_mesh(obj.string()).num_faces(), 2);
  EXPECT_EQ(detail::obj_parses() - before, 2);
  fs::remove_all(dir);
}

TEST(MeshIo, AGltfpackQuantizedFileReadsAsItsSourceWhereItsSkinPutsIt) {
  // gltfpack's default output (KHR_mesh_quantization): positions stored as
  // 16-bit integers and normals as bytes, the scale and offset that undo
  // it folded into the skin's inverse bind matrices. The skin puts each
  // vertex where the source's skin puts it, at rest and in a clip, to the
  // quantization's precision; the surface has the source's size in faces.
  const std::string d = std::string(CURVENET_SOURCE_DIR) + "/tests/data/quaternius/";
  const std::string source = d + "Wolf_decimated_20.glb", packed = d + "Wolf_decimated_20_gltfpack.glb";
  const SkinnedMesh a = load_skinned_mesh(source), b = load_skinned_mesh(packed);
  const RawMesh ra = read_raw_mesh(source), rb = read_raw_mesh(packed);
  const SurfaceMesh sa = load_mesh(source), sb = load_mesh(packed);
  EXPECT_EQ(sb.num_faces(), sa.num_faces());
  EXPECT_EQ(sb.num_vertices(), sa.num_vertices());
  const int wa = a.find_clip("Walk"), wb = b.find_clip("Walk");
  ASSERT_GE(wa, 0);
  ASSERT_GE(wb, 0);
  for (const double t : {-1.0, 0.0, 0.4}) {
    SCOPED_TRACE(t < 0 ? "rest" : "Walk at " + std::to_string(t) + " s");
    const auto pa = skin_positions(a, ra.positions, a.skinning_matrices(t < 0 ? -1 : wa, std::max(t, 0.0)));
    const auto pb = skin_positions(b, rb.positions, b.skinning_matrices(t < 0 ? -1 : wb, std::max(t, 0.0)));
    Eigen::AlignedBox3d box;
    for (const auto& p : pa)
      box.extend(p);
    const double diagonal = box.diagonal().norm();
    double worst = 0;
    for (const auto& q : pb) { // each packed vertex on a source vertex (gltfpack reorders them)
      double nearest = std::numeric_limits<double>::infinity();
      for (const auto& p : pa)
        nearest = std::min(nearest, (p - q).norm());
      worst = std::max(worst, nearest);
    }
    // (gltfpack also resamples the clip and stores its rotations in 16 bits.)
    EXPECT_LT(worst, (t < 0 ? 1e-4 : 1e-3) * diagonal);
  }
  // The stored positions are integers: read as they are, they lie far from the source's.
  double stored = 0;
  for (const auto& p : rb.positions)
    stored = std::max(stored, p.cwiseAbs().maxCoeff());
  EXPECT_GT(stored, 1000.0);
}
