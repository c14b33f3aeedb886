#pragma once
// The CLI's commands: one function each, over the library.

#include <optional>
#include <string>

namespace curvenet::cli {

struct EmbedArgs {
  std::string mesh, rig, report, regions, cut_mesh, coverage;
  double density = 5.0;
  std::optional<bool> progress;
};
int run_embed(const EmbedArgs& args);

struct DemoArgs {
  std::string out = "out/demo";
};
int run_demo(const DemoArgs& args);

} // namespace curvenet::cli
