// curvenet: the command-line front end. A thin layer over the library: it
// parses arguments, calls one library function per command, prints a
// summary, and turns exceptions into one line on stderr and an exit code.
//
// Exit codes: 0 success, 1 the embedding completed but is not ok, 2 bad
// input or any other error.

#include "commands.hpp"

#include "curvenet/errors.hpp"

#include <CLI/CLI.hpp>

#include <iostream>

int main(int argc, char** argv) {
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
  embed->add_option("--density", embed_args.density, "Profile samples per mean edge length (rho)")
      ->check(CLI::PositiveNumber);
  embed->add_flag("--progress,!--no-progress", embed_args.progress,
                  "Show progress on stderr (default: when stderr is a terminal)");

  curvenet::cli::StarterArgs starter_args;
  auto* starter = app.add_subcommand("starter", "Generate a starter Curvenet from a mesh and its skeleton");
  starter->add_option("MESH", starter_args.mesh, "Mesh file; its own skin gives the skeleton when it has one")->required();
  starter->add_option("--skeleton", starter_args.skeleton, "Skeleton: a rig file, or a glTF/GLB file with a skin");
  starter->add_option("-o,--output", starter_args.out, "Rig file to write (.cnrig.json)")->required();
  starter->add_option("--nodes-per-ring", starter_args.nodes_per_ring, "Nodes on each ring")
      ->capture_default_str()
      ->check(CLI::Range(2, 64));
  starter->add_option("--rings-per-bone", starter_args.rings_per_bone, "Rings per bone (one at its end joint)")
      ->capture_default_str()
      ->check(CLI::Range(1, 16));
  starter->add_option("--coverage", starter_args.coverage, "Coverage of the net")
      ->capture_default_str()
      ->check(CLI::IsMember({"full", "local"}));

  curvenet::cli::DemoArgs demo_args;
  auto* demo =
      app.add_subcommand("demo", "Run the demo pipeline on generated data (a capped tube and the thesis's tube net)");
  demo->add_option("--out", demo_args.out, "Output folder")->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    if (*embed)
      return curvenet::cli::run_embed(embed_args);
    if (*starter)
      return curvenet::cli::run_starter(starter_args);
    if (*demo)
      return curvenet::cli::run_demo(demo_args);
  } catch (const curvenet::Error& e) {
    std::cerr << "curvenet: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "curvenet: error: " << e.what() << "\n";
    return 2;
  }
  return 2;
}
