// The CLI's summaries.

#include "print.hpp"

#include <filesystem>
#include <iomanip>

namespace curvenet::cli {

void print_embed(std::ostream& out, const std::string& mesh_name, const EmbedReport& r) {
  out << "Curvenet embedding: " << (r.ok ? "SUCCESS" : "FAILED") << "\n";
  out << "mesh: " << mesh_name << " (" << r.input_vertices << " vertices, " << r.input_faces << " faces)\n";
  out << "coverage: " << to_string(r.coverage) << "\n";
  out << "logical nodes: " << r.logical_nodes << "\n";
  out << "physical nodes: " << r.physical_nodes << "\n";
  out << "profiles: " << r.profiles << "\n";
  out << "components: " << r.components << "\n";
  out << "regions: " << r.regions << "\n";
  out << "expected regions: " << (r.expected_regions ? std::to_string(*r.expected_regions) : "not determined") << "\n";
  out << "mapped faces: " << r.mapped_faces << "\n";
  out << "unmapped faces: " << r.unmapped_faces << "\n";
  if (r.outside_faces)
    out << "outside faces: " << r.outside_faces << "\n";
  out << "cut mesh: " << r.cut_vertices << " vertices, " << r.cut_faces << " faces\n";
  {
    // The profile that strays most from its curve, and by how much.
    std::string worst;
    for (const auto& [id, d] : r.fidelity)
      if (d == r.fidelity_max)
        worst = id;
    const double diag = r.diagonal > 0 ? r.diagonal : 1.0;
    out << "chain fidelity: " << std::setprecision(3) << r.fidelity_max << " (" << r.fidelity_max / diag
        << " of the diagonal" << (worst.empty() ? "" : ", profile '" + worst + "'") << "), tolerance "
        << r.fidelity_tolerance << (r.fidelity_enforced ? "" : " (a cage: not enforced)") << "\n"
        << std::setprecision(6);
  }
  double total = 0;
  for (const auto& [s, ms] : r.timings_ms)
    total += ms;
  out << "time: " << std::fixed << std::setprecision(1) << total << " ms\n" << std::defaultfloat;
  for (const auto& p : r.problems)
    out << "problem: " << p << "\n";
  for (const auto& n : r.notes)
    out << "note: " << n << "\n";
}

void print_bind(std::ostream& out, const JobSummary& j) {
  const BindReport& r = j.bind;
  out << "binding: " << r.vertices << " mesh vertices; on the cut mesh, " << r.constrained << " on the curves, "
      << r.free << " solved for, " << r.rigid << " rigid\n";
  out << "influences per vertex: " << std::fixed << std::setprecision(2) << r.mean_influences << std::defaultfloat
      << std::setprecision(6) << "\n";
  out << "negative Laplacian weights: " << r.negative_weights_before << " before, " << r.negative_weights_after
      << " after " << r.flips << " intrinsic flips (" << r.negative_weights_solved
      << " at a vertex solved for; the others lie along the curves, outside the solve)\n";
  double total = 0;
  for (const auto& [s, ms] : r.timings_ms)
    total += ms;
  out << "bind time: " << std::fixed << std::setprecision(1) << total << " ms\n"
      << std::defaultfloat << std::setprecision(6);
  for (const auto& n : r.notes)
    out << "note: " << n << "\n";
}

void print_bake_fidelity(std::ostream& out, const std::vector<BakeClipFidelity>& clips, bool helpers) {
  if (clips.empty())
    return;
  double mean = 0;
  for (const auto& c : clips)
    mean += c.mean;
  mean /= static_cast<double>(clips.size());
  const auto& worst = clips.front();
  const auto flags = out.flags();
  const auto precision = out.precision();
  out << std::fixed << std::setprecision(2);
  // A clip without a name is called by its index in the clip file.
  auto name = [](const BakeClipFidelity& c) {
    return c.clip.empty() ? "clip " + std::to_string(c.index) + " (unnamed)" : "clip '" + c.clip + "'";
  };
  out << "fidelity: the skin against the rig, % of the diagonal: mean " << 100 * mean << ", worst vertex "
      << 100 * worst.max << " (" << name(worst) << ")\n";
  for (const auto& c : clips) {
    out << "  " << name(c) << ": " << c.frames << " frames, mean " << 100 * c.mean << ", max " << 100 * c.max
        << " at vertex " << c.worst_vertex << " (" << std::setprecision(4) << c.worst_rest.x() << ", "
        << c.worst_rest.y() << ", " << c.worst_rest.z() << std::setprecision(2) << "; " << c.worst_joint << "), "
        << std::setprecision(3) << c.worst_time << std::setprecision(2) << " s in";
    if (c.worst_joints > 0) // the floor: see docs/bake.md, "What bake reports"
      out << "; floor " << 100 * c.worst_floor << " (no linear skin of the " << c.worst_joints << " rig "
          << (c.worst_joints == 1 ? "joint" : "joints") << (helpers ? " alone" : "")
          << " there comes closer, whatever its weights)";
    out << "\n";
  }
  out.flags(flags);
  out.precision(precision);
}

void print_job(std::ostream& out, const char* command, const JobSummary& j) {
  for (const auto& n : j.notes)
    out << "note: " << n << "\n";
  out << "Curvenet " << command << ": SUCCESS\n";
  print_bind(out, j);
}

void print_transfer(std::ostream& out, const std::string& from, int from_faces, const std::string& to, int to_faces,
                    const TransferReport& rep, const std::string& rig_out) {
  out << "Curvenet transfer: " << (rep.ok ? "SUCCESS" : "FAILED") << "\n";
  out << "source: " << std::filesystem::path(from).filename().string() << " (" << from_faces << " faces), "
      << rep.source.regions << " regions\n";
  out << "target: " << std::filesystem::path(to).filename().string() << " (" << to_faces << " faces), "
      << rep.target.regions << " regions, expected "
      << (rep.target.expected_regions ? std::to_string(*rep.target.expected_regions) : "not determined") << "\n";
  out << "logical nodes: " << rep.target.logical_nodes << "\nprofiles: " << rep.target.profiles << "\n";
  out << "unmapped faces: " << rep.target.unmapped_faces << "\n";
  out << "lined up by: " << rep.alignment << "\n";
  out << std::fixed << std::setprecision(2) << "region agreement: " << 100 * rep.agreement << "% of the area\n";
  const RegionAgreement* worst = nullptr;
  for (const auto& g : rep.regions)
    if (!worst || g.agree < worst->agree)
      worst = &g;
  if (worst)
    out << "least agreeing region: " << 100 * worst->agree << "% (" << worst->key << ")\n";
  out << "surfaces apart before the transfer: " << rep.shape.percent(rep.shape.mean) << "% of the diagonal on average, "
      << rep.shape.percent(rep.shape.max) << "% at most\n";
  out << "largest node move onto the target: " << rep.max_node_offset << "% of the diagonal\n"
      << std::defaultfloat << std::setprecision(6);
  for (const auto& p : rep.problems)
    out << "problem: " << p << "\n";
  if (rep.ok)
    out << "rig: " << rig_out << "\n";
}

void print_starter(std::ostream& out, const std::string& mesh_path, const SurfaceMesh& mesh, size_t joints,
                   const StarterResult& r, const StarterOptions& options) {
  const int V = static_cast<int>(r.rig.nodes.size()), E = static_cast<int>(r.rig.profiles.size());
  out << "Curvenet starter: SUCCESS\n";
  out << "mesh: " << std::filesystem::path(mesh_path).filename().string() << " (" << mesh.num_vertices()
      << " vertices, " << mesh.num_faces() << " faces)\n";
  out << "joints: " << joints << "\n";
  out << "rings: " << r.rings << "\n";
  out << "nodes: " << V << "\n";
  out << "profiles: " << E << "\n";
  out << "components: " << r.net_components << "\n";
  out << "joins: " << r.joins << "\n";
  out << "unjoined chains: " << r.unjoined << "\n";
  const AutoWeightOptions& weights = options.weights;
  const std::string rule = weights.rule == WeightRule::Segment
                               ? std::string("segment")
                               : "blend-zone " + std::to_string(weights.blend).substr(0, 4);
  out << "weights: "
      << (options.skin ? "skin (the mesh's own, where each node lies; " + rule + " where it has none)" : rule) << "\n";
  out << "joints without a ring: " << r.ringless.size() << "\n";
  for (const auto& [joint, why] : r.ringless)
    out << "  " << joint << ": " << why << "\n";
}

} // namespace curvenet::cli
