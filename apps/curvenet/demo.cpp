// `curvenet demo`: the whole pipeline on generated tubes, for a newcomer's
// first run (no data files needed).

#include "commands.hpp"
#include "print.hpp"

#include "curvenet/bake.hpp"
#include "curvenet/embed.hpp"
#include "curvenet/io.hpp"
#include "curvenet/jobs.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/transfer.hpp"
#include "generate/tube.hpp"

#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

namespace curvenet::cli {

int run_demo(const DemoArgs& a) {
  namespace fs = std::filesystem;
  const fs::path out(a.out);
  fs::create_directories(out);
  std::cout << "curvenet demo: the thesis's tube net on two tessellations of a capped tube\n";
  const Rig rig = make_tube_net();
  write_rig(rig, (out / "tube.cnrig.json").string());
  struct Case {
    const char* name;
    TubeSpec spec;
  };
  TubeSpec quads;
  TubeSpec tris;
  tris.around = 24;
  tris.along = 20;
  tris.cap_rings = 6;
  tris.triangulate = true;
  const Case cases[] = {{"tube_quads", quads}, {"tube_tris", tris}};
  std::vector<std::string> lines;
  bool all_ok = true;
  for (const auto& c : cases) {
    const RawMesh raw = make_capped_tube(c.spec);
    const std::string mesh_path = (out / (std::string(c.name) + ".obj")).string();
    write_file_atomic(mesh_path, mesh_to_obj(raw.positions, raw.face_offsets, raw.face_vertices));
    const SurfaceMesh mesh = make_surface_mesh(raw, mesh_path);
    const Embedding emb = embed(mesh, rig);
    write_file_atomic((out / (std::string(c.name) + ".report.json")).string(), report_to_json(emb.report()));
    write_file_atomic((out / (std::string(c.name) + ".regions.ply")).string(), emb.regions_ply());
    write_file_atomic((out / (std::string(c.name) + ".cut.obj")).string(), emb.cut_mesh_obj());
    std::cout << "\n";
    print_embed(std::cout, fs::path(mesh_path).filename().string(), emb.report());
    const auto& r = emb.report();
    all_ok = all_ok && r.ok;
    std::ostringstream s;
    s << c.name << ": " << (r.ok ? "SUCCESS" : "FAILED") << ", " << r.input_faces << " faces, " << r.regions << "/"
      << (r.expected_regions ? std::to_string(*r.expected_regions) : "?") << " regions";
    lines.push_back(s.str());
  }
  // A starter net from a skeleton along the tube, made on the quad tube and
  // embedded on both.
  {
    StarterOptions so;
    const SurfaceMesh quad_mesh = make_surface_mesh(make_capped_tube(quads), "tube_quads");
    const StarterResult st = make_starter(quad_mesh, make_tube_skeleton({0.3, 1.2, 2.1, 3.0, 3.7}), so);
    write_rig(st.rig, (out / "tube_starter.cnrig.json").string());
    int ok = 0;
    for (const auto& c : cases) {
      const Embedding emb = embed(make_surface_mesh(make_capped_tube(c.spec), c.name), st.rig);
      ok += emb.report().ok;
      all_ok = all_ok && emb.report().ok;
    }
    std::ostringstream s;
    s << "starter: " << st.rings << " rings, " << st.rig.nodes.size() << " nodes, " << st.rig.profiles.size()
      << " profiles from a 5-joint skeleton; embeds on " << ok << "/2 tessellations";
    lines.push_back(s.str());
  }
  // Transfer the net from the quad tube to the triangle tube, by ids only.
  {
    const SurfaceMesh from = make_surface_mesh(make_capped_tube(quads), "tube_quads");
    const SurfaceMesh to = make_surface_mesh(make_capped_tube(tris), "tube_tris");
    const TransferResult tr = transfer(rig, from, to);
    write_rig(tr.rig, (out / "tube_tris.transferred.cnrig.json").string());
    write_file_atomic((out / "transfer.report.json").string(), transfer_report_json(tr.report));
    all_ok = all_ok && tr.report.ok;
    std::ostringstream s;
    s << "transfer tube_quads -> tube_tris: " << (tr.report.ok ? "SUCCESS" : "FAILED") << ", "
      << tr.report.target.regions << "/" << tr.report.source.regions << " regions, " << std::fixed
      << std::setprecision(2) << 100 * tr.report.agreement << "% of the area in the region of the same identity"
      << std::defaultfloat << std::setprecision(6);
    lines.push_back(s.str());
  }
  // Bend the tube's two joints over 24 frames, through the tube net, on both
  // tessellations: a PC2 cache each, and the last frame as OBJ.
  {
    for (const auto& c : cases) {
      const SurfaceMesh mesh = make_surface_mesh(make_capped_tube(c.spec), c.name);
      const Binding b = bind(mesh, rig);
      const int nv = b.num_input_vertices();
      const FrameRange range{0, 23, 24};
      auto pose = [&](int f) {
        const double s = static_cast<double>(f) / range.last;
        Pose p;
        p["mid"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.8 * s, Eigen::Vector3d::UnitZ()));
        p["tip"].rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.6 * s, Eigen::Vector3d::UnitZ()));
        return skinning_matrices(b.joints(), p);
      };
      const std::string base = (out / c.name).string();
      const InputTopology topology = read_input_topology(base + ".obj");
      OutputFiles files;
      Pc2Sink cache(files, base + ".bend.pc2", nv, range);
      FunctionSink last([&](int f, std::span<const Vec3> p) {
        if (f == range.last)
          files.add(base + ".bent.obj", posed_obj(topology, p));
      });
      FrameSink* sinks[] = {&cache, &last};
      animate(b, pose, range, sinks, c.name);
      files.commit();
      std::ostringstream line;
      line << "bend " << c.name << ": " << range.count() << " frames, " << std::fixed << std::setprecision(2)
           << b.report().mean_influences << " influences per vertex" << std::defaultfloat << std::setprecision(6);
      lines.push_back(line.str());
      // The same binding baked to an ordinary skin: a skinned glTF any engine
      // reads (the tube stands along Z: turned to glTF's Y-up).
      GltfBakeOptions bake;
      bake.up = GltfBakeOptions::Up::Z;
      const SkinWeights w = bake_weights(b, 4);
      write_file_atomic(base + ".baked.glb", skinned_glb(base + ".obj", b.joints(), w, nullptr, bake));
      lines.push_back(std::string("bake ") + c.name + ": " + c.name + ".baked.glb, a skin of " +
                      std::to_string(w.joints.size()) + " joints, 4 influences at most");
    }
  }
  std::cout << "\nsummary:\n";
  for (const auto& l : lines)
    std::cout << "  " << l << "\n";
  std::cout << "outputs in " << out.string()
            << "/ (meshes, rigs, reports, region previews, cut meshes, bend caches: Mesh Cache, forward +Y, up +Z, on "
               "the OBJ; baked skins as glTF)\n";
  return all_ok ? 0 : 1;
}

} // namespace curvenet::cli
