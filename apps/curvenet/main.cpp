// curvenet: the command-line front end. A thin layer over the library: it
// parses arguments, calls one library function per command, prints a
// summary, and turns exceptions into one line on stderr and an exit code.
//
// Exit codes: 0 success, 1 the embedding completed but is not ok, 2 bad
// input or any other error.

#include "commands.hpp"

#include "core/numbers.hpp"
#include "curvenet/errors.hpp"

#include <CLI/CLI.hpp>

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <malloc.h>
#include <sstream>
#include <string>
#include <unistd.h>

namespace {

/// A whole, finite number in [lo, hi] (CLI11's own number checks let `nan`
/// through, and print the range of a double in 309 digits).
CLI::Validator finite_in(double lo, double hi, bool lo_open = false) {
  std::ostringstream range;
  range << (lo_open ? "(" : "[") << lo << ", " << hi << "]";
  return CLI::Validator(
      [lo, hi, lo_open, r = range.str()](std::string& text) -> std::string {
        double v = 0;
        if (!curvenet::detail::parse_finite(text, v))
          return "'" + text + "' is not a finite number";
        if (v < lo || v > hi || (lo_open && v == lo))
          return "'" + text + "' is outside " + r;
        return "";
      },
      "NUMBER in " + range.str());
}

} // namespace

namespace {

/// glibc reads its malloc tunables once, at start: the first time, the CLI
/// starts itself again (the same pid, arguments and descriptors) asking
/// glibc for transparent huge pages for its heap. An embed of a 150k-face
/// mesh touches 120 MB in 4 kB pages: 31k page faults, and an eighth of its
/// time (374 to 326 ms, the median of 20 runs on one core); with 2 MB
/// pages, 2k faults. Skipped where it cannot
/// help: the kernel's huge pages turned off, a user's own choice in
/// GLIBC_TUNABLES, or a sanitizer's allocator in place of glibc's. Skipped
/// too for the commands that bind, where it costs more than it saves: the
/// kernel clears each 2 MB page the factorisations touch, a third of a
/// bind's time in perf. On the 146k-face hand, interleaved runs on two
/// cores: `embed` 297 ms with huge pages against 330 ms without, `bind`
/// 1.99 s against 1.79 s, `pose` 2.45-2.79 s against 2.01-2.26 s.
void start_again_with_huge_pages(int argc, char** argv) {
#if defined(__SANITIZE_ADDRESS__)
  (void)argc;
  (void)argv;
#else
  if (std::getenv("CURVENET_HEAP") != nullptr)
    return; // this is the second start, or the user turned it off
  for (const char* binds : {"bind", "pose", "animate", "bake", "farm"})
    if (argc > 1 && std::strcmp(argv[1], binds) == 0)
      return;
  std::ifstream thp("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string modes;
  std::getline(thp, modes);
  if (modes.find("[never]") != std::string::npos || modes.empty())
    return;
  const char* given = std::getenv("GLIBC_TUNABLES");
  std::string tunables = given ? given : "";
  if (tunables.find("glibc.malloc.hugetlb") != std::string::npos)
    return;
  tunables += (tunables.empty() ? "" : ":") + std::string("glibc.malloc.hugetlb=1");
  if (::setenv("GLIBC_TUNABLES", tunables.c_str(), 1) != 0 || ::setenv("CURVENET_HEAP", "huge-pages", 1) != 0)
    return;
  ::execv("/proc/self/exe", argv);
  // No exec (no /proc): go on as started, without the tunable.
  if (given)
    ::setenv("GLIBC_TUNABLES", given, 1);
  else
    ::unsetenv("GLIBC_TUNABLES");
#endif
}

} // namespace

int main(int argc, char** argv) {
  start_again_with_huge_pages(argc, argv);
  // One process, one job, in stages that each free large arrays the next
  // allocates again: keep freed memory in the heap (no mmap for big blocks,
  // no trimming back to the kernel), so a stage reuses pages the last one
  // touched instead of faulting in fresh ones.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  mallopt(M_TOP_PAD, 64 << 20);
  CLI::App app{"curvenet: topology-independent character deformation with curve networks"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "Help for every command");

  curvenet::cli::EmbedArgs embed_args;
  auto* embed = app.add_subcommand("embed", "Embed a rig's Curvenet in a mesh: trace, cut, and partition into regions");
  embed->add_option("MESH", embed_args.mesh, "Mesh file (.obj, .ply, .off, .gltf, .glb, .fbx)")->required();
  embed->add_option("RIG", embed_args.rig, "Rig file (.cnrig.json)")->required();
  embed->add_option("--report", embed_args.report, "Write the embedding report as JSON");
  embed->add_option("--regions", embed_args.regions, "Write the region preview as PLY with per-face colours");
  embed->add_option("--cut-mesh", embed_args.cut_mesh, "Write the cut mesh as OBJ (with one polyline per CutChain)");
  embed->add_option("--coverage", embed_args.coverage, "Override the rig's coverage")
      ->check(CLI::IsMember({"full", "local", "auto"}));
  embed->add_option("--density", embed_args.density, "Profile samples per local edge length (rho), at most 1000")
      ->check(finite_in(0, 1000, true));
  embed->add_option("--max-samples", embed_args.max_samples, "Refuse an embedding estimated to need more samples")
      ->capture_default_str()
      ->check(CLI::Range(1ll, 1'000'000'000ll));
  embed->add_flag("--progress,!--no-progress", embed_args.progress,
                  "Show progress on stderr (default: when stderr is a terminal)");

  curvenet::cli::StarterArgs starter_args;
  auto* starter = app.add_subcommand("starter", "Generate a starter Curvenet from a mesh and its skeleton");
  starter->add_option("MESH", starter_args.mesh, "Mesh file; its own skin gives the skeleton when it has one")
      ->required();
  starter->add_option("--skeleton", starter_args.skeleton, "Skeleton: a rig file, or a glTF/GLB file with a skin");
  starter->add_option("-o,--output", starter_args.out, "Rig file to write (.cnrig.json)")->required();
  starter->add_option("--nodes-per-ring", starter_args.nodes_per_ring, "Nodes on each ring")
      ->capture_default_str()
      ->check(CLI::Range(2, 64));
  starter->add_option("--rings-per-bone", starter_args.rings_per_bone, "Rings per bone (one at its end joint)")
      ->capture_default_str()
      ->check(CLI::Range(1, 16));
  starter->add_flag("!--no-middle-nodes", starter_args.middle_nodes,
                    "Leave out the nodes that, with the mesh's skin, split each profile along a bone and each ring's "
                    "arc at its middle (docs/starter.md)");
  starter
      ->add_option("--first-angle", starter_args.first_angle,
                   "Angle of node 0 from each chain's reference direction (its root joint's local X), in degrees")
      ->capture_default_str()
      ->check(finite_in(-360, 360));
  starter
      ->add_option("--weight-rule", starter_args.weight_rule,
                   "Node weights (docs/starter.md): skin (the mesh's own skin weights where each node lies), "
                   "blend-zone (bones rigid, blended around joints) or segment (blended along each bone); auto: "
                   "skin when the mesh has a skin, else blend-zone")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "skin", "blend-zone", "segment"}));
  starter->add_option("--blend", starter_args.blend, "The blend zone's half-width, as a fraction of each bone")
      ->capture_default_str()
      ->check(finite_in(0, 0.5, true));
  starter->add_option("--coverage", starter_args.coverage,
                      "Coverage of the net: auto is full on a closed mesh and local on an open one")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "full", "local"}));

  auto deform_options = [](CLI::App* cmd, curvenet::cli::DeformArgs& a) {
    cmd->add_option("MESH", a.mesh, "Mesh file")->required();
    cmd->add_option("RIG", a.rig, "Rig file (.cnrig.json)")->required();
    cmd->add_option("--skeleton", a.skeleton,
                    "Take the skeleton from this rig file or skinned glTF, joints matched by name");
    cmd->add_option("--laplacian", a.laplacian, "Laplacian of the cut mesh")
        ->capture_default_str()
        ->check(CLI::IsMember({"intrinsic", "uniform"}));
    cmd->add_option("--binding-cache", a.binding_cache,
                    "Reuse the binding stored in this file when it was made for the same mesh, rig and options; "
                    "otherwise bind and store it there");
    cmd->add_option("--rigid", a.rigid, "How each vertex's detail follows the joints")
        ->capture_default_str()
        ->check(CLI::IsMember({"per-vertex", "horn"}));
    cmd->add_option("--method", a.method,
                    "dq: blend the joints' rigid motions per vertex as dual quaternions, with the net's weights; "
                    "harmonic: blend the joints' matrices linearly; gradient: per-face gradients and a "
                    "Poisson solve")
        ->capture_default_str()
        ->check(CLI::IsMember({"dq", "harmonic", "gradient"}));
    cmd->add_option("--interior", a.interior,
                    "The dq mode's weights inside the regions: bone-heat (the bones inside, corrected to the curves' "
                    "weights on them) or harmonic (the harmonic extension of the curves' weights)")
        ->capture_default_str()
        ->check(CLI::IsMember({"bone-heat", "harmonic"}));
    cmd->add_option("--rotation", a.rotation, "Gradient mode: a face's rotation from its joints'")
        ->capture_default_str()
        ->check(CLI::IsMember({"polar", "quaternion"}));
    cmd->add_flag("--curve-frames", a.curve_frames,
                  "Gradient mode: turn each curve side's frame to follow its posed curve (about twice the frame time)");
  };
  auto layer_options = [&](CLI::App* cmd, curvenet::cli::DeformArgs& a) {
    cmd->add_flag("--over-skin", a.over_skin,
                  "Layer the net over the mesh file's own skin: the skin moves the mesh, and the net corrects it so "
                  "that its curves follow the rig (docs/deform.md)");
    cmd->add_option("--skinning", a.skinning, "With --over-skin: the skin's blend, linear (as glTF plays it) or dq")
        ->capture_default_str()
        ->check(CLI::IsMember({"linear", "dq"}));
    cmd->add_option("--envelope", a.envelope, "How much of the layer's correction to apply, from 0 (the base) to 1")
        ->capture_default_str()
        ->check(finite_in(0, 1));
    cmd->add_option("--mask", a.mask,
                    "How much of the correction each vertex takes: a text file of one number from 0 to 1 per vertex "
                    "of the mesh file, or a JSON file {\"regions\": {region key: 0 to 1}, \"others\": 0 to 1} "
                    "(the keys as embed --report lists them)");
  };
  curvenet::cli::BindArgs bind_args;
  auto* bind = app.add_subcommand("bind", "Bind a rig to a mesh and write the rig with every node's weights filled in");
  deform_options(bind, bind_args);
  bind->add_option("-o,--output", bind_args.out, "Rig file to write")->required();

  curvenet::cli::PoseArgs pose_args;
  auto* pose =
      app.add_subcommand("pose", "Deform a mesh through its rig into one pose, written as OBJ on the input's topology");
  deform_options(pose, pose_args);
  pose->add_option("POSE", pose_args.pose, "Pose file (.pose.json)")->required();
  pose->add_option("-o,--output", pose_args.out, "OBJ file to write")->required();
  pose->add_option("--cut-mesh", pose_args.cut_mesh,
                   "Also write the posed cut mesh as OBJ: the curves' own shape between a coarse mesh's vertices");
  layer_options(pose, pose_args);

  auto animate_options = [&](CLI::App* cmd, curvenet::cli::AnimateArgs& a) {
    deform_options(cmd, a);
    cmd->add_option("CLIP", a.clip_file, "glTF or GLB file with skins and animations")->required();
    cmd->add_option("--clip", a.clip, "Clip name or index (default: the first)");
    cmd->add_option("--fps", a.fps, "Frames per second")->capture_default_str()->check(finite_in(0, 10000, true));
    cmd->add_option("--frames", a.frames, "Frames A:B, inclusive (default: the clip's range)");
    cmd->add_option("--max-frames", a.max_frames, "Refuse more frames than this")
        ->capture_default_str()
        ->check(CLI::Range(1ll, 100000000ll));
    auto* out_opt = cmd->add_option("-o,--output", a.out, "PC2 file to write");
    auto* seq_opt =
        cmd->add_option("--obj-sequence", a.obj_sequence, "Write one OBJ per frame into this folder instead");
    out_opt->excludes(seq_opt);
  };
  curvenet::cli::AnimateArgs anim_args;
  auto* animate = app.add_subcommand("animate", "Deform a mesh through its rig by a glTF clip, into a PC2 point cache");
  animate_options(animate, anim_args);
  animate->add_option("--cut-mesh-sequence", anim_args.cut_mesh_sequence,
                      "Also write the posed cut mesh of every frame as OBJ into this folder");
  layer_options(animate, anim_args);
  animate->add_option("--node-keys", anim_args.node_keys,
                      "Node offsets keyed over the frames (docs/rig-format.md): the curves follow them, and the mesh "
                      "inside the regions they bound");

  auto* farm = app.add_subcommand("farm", "Run animate on a Slurm cluster in shards, and merge them (docs/farm.md)");
  farm->require_subcommand(1);
  curvenet::cli::FarmSubmitArgs farm_args;
  auto* farm_submit = farm->add_subcommand(
      "submit", "Write a job folder (manifest, Slurm array script) for animate's inputs, and submit it with sbatch");
  animate_options(farm_submit, farm_args);
  farm_submit->add_option("--folder", farm_args.folder, "The job folder to write (new or empty)")->required();
  farm_submit->add_option("--shard-frames", farm_args.shard_frames, "Frames per array task")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000000));
  farm_submit->add_flag("--dry-run", farm_args.dry_run, "Only write the job folder, and print the sbatch line");
  farm_submit->add_option("--sbatch-option", farm_args.sbatch_options,
                          "Pass this option to every sbatch line, e.g. --sbatch-option=--partition=anim (repeatable)");
  farm_submit
      ->add_option("--lock-timeout", farm_args.lock_timeout,
                   "Seconds after which a binding-cache lock counts as its owner's death (a task on another host)")
      ->capture_default_str()
      ->check(finite_in(0, 1e7, true));
  std::string farm_folder;
  int farm_index = 0;
  auto* farm_task = farm->add_subcommand("task", "Run one array task of a job folder (what task.sbatch runs)");
  farm_task->add_option("FOLDER", farm_folder, "The job folder")->required();
  farm_task->add_option("INDEX", farm_index, "The array task index")->required()->check(CLI::Range(0, 100000000));
  auto* farm_merge = farm->add_subcommand("merge", "Check every part of a job folder and write its output");
  farm_merge->add_option("FOLDER", farm_folder, "The job folder")->required();
  auto* farm_status = farm->add_subcommand("status", "Each task's state, from squeue and sacct or the part files");
  farm_status->add_option("FOLDER", farm_folder, "The job folder")->required();

  curvenet::cli::BakeArgs bake_args;
  auto* bake = app.add_subcommand(
      "bake", "Bake the rig to an ordinary linear-blend skin: a skinned glTF binary, and the weights as CSV");
  deform_options(bake, bake_args);
  auto* bake_out = bake->add_option("-o,--output", bake_args.out, "Skinned glTF binary (.glb) to write");
  auto* bake_csv = bake->add_option("--weights-csv", bake_args.weights_csv, "Write the weights as CSV");
  bake->add_option("--max-influences", bake_args.max_influences, "Joints per vertex (4 or fewer: JOINTS_0; up to 8)")
      ->capture_default_str()
      ->check(CLI::Range(1, 8));
  bake->add_option("--helpers", bake_args.helpers,
                   "Up to this many helper joints, each keyed half way between two joints (their dual-quaternion "
                   "mean), where they bring the fitted skin closest to the rig; needs fitted weights")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000));
  bake->add_option("--clip", bake_args.clip_file, "Add the animations of this glTF/GLB, retargeted by joint name");
  bake->add_option("--clip-name", bake_args.clip_names, "Only these clips of --clip (repeatable)");
  bake->add_option("--fps", bake_args.fps, "Keys per second for the clips")
      ->capture_default_str()
      ->check(finite_in(0, 1000, true));
  bake->add_option("--max-frames", bake_args.max_frames,
                   "Refuse clips (--clip, --fit) that come to more frames than this at --fps")
      ->capture_default_str()
      ->check(CLI::Range(1ll, 100000000ll));
  bake->add_option("--up", bake_args.up, "The source's up axis; glTF is Y-up, a Z-up source is turned")
      ->capture_default_str()
      ->check(CLI::IsMember({"y", "z"}));
  bake->add_option("--weights", bake_args.weights,
                   "fitted: fit the weights to the rig over poses of the skeleton itself (each joint bent and "
                   "twisted, and random poses of all), and the --fit clips; harmonic: the top harmonic weights "
                   "(fitted over the --fit clips alone when given)")
      ->capture_default_str()
      ->check(CLI::IsMember({"fitted", "harmonic"}));
  bake->add_option("--fit", bake_args.fit,
                   "Fit the weights to the full deformation over every frame of this glTF/GLB's clips too "
                   "(least squares per vertex, non-negative, on the harmonic influences)");
  layer_options(bake, bake_args);
  (void)bake_out;
  (void)bake_csv;

  curvenet::cli::TransferArgs transfer_args;
  auto* transfer =
      app.add_subcommand("transfer", "Transfer a rig to another mesh of the same character, by logical ids only");
  transfer->add_option("RIG", transfer_args.rig, "Rig authored on the source mesh")->required();
  transfer->add_option("--from", transfer_args.from, "Source mesh")->required();
  transfer->add_option("--to", transfer_args.to, "Target mesh")->required();
  transfer->add_option("-o,--output", transfer_args.out, "Rig file to write for the target")->required();
  transfer->add_option("--report", transfer_args.report, "Write the transfer report as JSON");
  transfer->add_option("--source-frame", transfer_args.source_frame,
                       "4x4 matrix (16 numbers, row by row) from the source mesh's space to the world");
  transfer
      ->add_option("--align", transfer_args.align,
                   "How the meshes line up: skeletons (the similarity that carries the source skin's joints onto "
                   "the target's, by name), frames (the frame options, or none), or auto: skeletons when both files "
                   "have skins that fit and no frame is given, else frames")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "skeletons", "frames"}));
  transfer
      ->add_option("--from-cage", transfer_args.from_cage,
                   "The source is a Catmull-Clark cage: carry the rig through its limit surface (refinement levels)")
      ->check(CLI::Range(1, 6));
  transfer
      ->add_option("--to-cage", transfer_args.to_cage,
                   "The target is a Catmull-Clark cage: place the rig on its limit surface (refinement levels) and "
                   "carry it down to the cage")
      ->check(CLI::Range(1, 6));
  transfer->add_option("--max-faces", transfer_args.max_faces, "Refuse refining a cage into more faces")
      ->capture_default_str()
      ->check(CLI::Range(1ll, 1'000'000'000ll));
  transfer->add_option("--target-frame", transfer_args.target_frame,
                       "4x4 matrix (16 numbers, row by row) from the target mesh's space to the world");

  curvenet::cli::CompareArgs compare_args;
  auto* compare =
      app.add_subcommand("compare", "Symmetric surface distance between two meshes (mean, RMS, max), point to surface");
  compare->add_option("A", compare_args.a, "First mesh (percentages are of its bounding-box diagonal)")->required();
  compare->add_option("B", compare_args.b, "Second mesh")->required();
  compare->add_flag("--json", compare_args.json, "Print JSON instead of text");

  curvenet::cli::SubdivideArgs subdivide_args;
  auto* subdivide = app.add_subcommand(
      "subdivide", "Refine a control cage by Catmull-Clark into a mesh of its limit surface, as OBJ");
  subdivide->add_option("CAGE", subdivide_args.cage, "Cage mesh file")->required();
  subdivide->add_option("-o,--output", subdivide_args.out, "OBJ file to write")->required();
  subdivide->add_option("--levels", subdivide_args.levels, "Refinement levels")
      ->capture_default_str()
      ->check(CLI::Range(1, 6));
  subdivide->add_option("--max-faces", subdivide_args.max_faces, "Refuse a refinement into more faces")
      ->capture_default_str()
      ->check(CLI::Range(1ll, 1'000'000'000ll));

  curvenet::cli::DemoArgs demo_args;
  auto* demo =
      app.add_subcommand("demo", "Run the demo pipeline on generated data (a capped tube and the thesis's tube net)");
  demo->add_option("--out", demo_args.out, "Output folder")->capture_default_str();

  // A word where the command goes that names no command: say which word.
  if (argc > 1 && argv[1][0] != '-') {
    std::string names;
    bool known = false;
    for (const auto* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
      names += (names.empty() ? "" : ", ") + sub->get_name();
      known = known || sub->get_name() == argv[1];
    }
    if (!known) {
      std::cerr << "curvenet: error: unknown command '" << argv[1] << "' (the commands are " << names << ")\n";
      return 2;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line, like every other failure.
    std::string what = e.what();
    what = what.substr(0, what.find('\n'));
    std::cerr << "curvenet: error: " << what << "\n";
    return 2;
  }
  try {
    if (*embed)
      return curvenet::cli::run_embed(embed_args);
    if (*bind)
      return curvenet::cli::run_bind(bind_args);
    if (*pose)
      return curvenet::cli::run_pose(pose_args);
    if (*animate) {
      if (anim_args.out.empty() && anim_args.obj_sequence.empty())
        throw curvenet::Error("animate: give -o OUT.pc2 or --obj-sequence DIR");
      return curvenet::cli::run_animate(anim_args);
    }
    if (*farm_submit) {
      if (farm_args.out.empty() && farm_args.obj_sequence.empty())
        throw curvenet::Error("farm submit: give -o OUT.pc2 or --obj-sequence DIR");
      return curvenet::cli::run_farm_submit(farm_args);
    }
    if (*farm_task)
      return curvenet::cli::run_farm_task(farm_folder, farm_index);
    if (*farm_merge)
      return curvenet::cli::run_farm_merge(farm_folder);
    if (*farm_status)
      return curvenet::cli::run_farm_status(farm_folder);
    if (*bake) {
      if (bake_args.out.empty() && bake_args.weights_csv.empty())
        throw curvenet::Error("bake: give -o OUT.glb, --weights-csv OUT.csv, or both");
      return curvenet::cli::run_bake(bake_args);
    }
    if (*transfer)
      return curvenet::cli::run_transfer(transfer_args);
    if (*compare)
      return curvenet::cli::run_compare(compare_args);
    if (*starter)
      return curvenet::cli::run_starter(starter_args);
    if (*subdivide)
      return curvenet::cli::run_subdivide(subdivide_args);
    if (*demo)
      return curvenet::cli::run_demo(demo_args);
  } catch (const std::exception& e) {
    // One line, whatever the message holds.
    std::string what = e.what();
    for (char& c : what)
      if (c == '\n' || c == '\r')
        c = ' ';
    std::cerr << "curvenet: error: " << what << "\n";
    return 2;
  }
  return 2;
}
