// The transfer end-to-end table: one rig, authored on one mesh with the
// starter net, transferred to the other tessellations of the same shape,
// posed by the same clips; each posed mesh is compared with the posed
// source. Prints (pair, clip, rest distance, posed distance) as % of the
// source's diagonal, mean and max (Hausdorff).
//
//   build/bin/transfer_table hand|spot|blub|penguin [--markdown] [clips...]

#include "transfer_check.hpp"

#include <cstdio>
#include <string>

int main(int argc, char** argv) {
  const std::string family = argc > 1 ? argv[1] : "hand";
  std::vector<std::string> clips;
  bool markdown = false;
  for (int i = 2; i < argc; ++i) {
    if (std::string(argv[i]) == "--markdown")
      markdown = true;
    else
      clips.push_back(argv[i]);
  }
  std::vector<std::string> refusals;
  const auto rows = curvenet::check::run_family(family, std::string(CURVENET_DATA_DIR), clips, &refusals);
  curvenet::check::print_table(rows, stdout, markdown);
  for (const auto& r : refusals)
    std::printf("refused: %s\n", r.c_str());
  return 0;
}
