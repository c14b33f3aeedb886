#pragma once
// The CLI's summaries: what each command prints on standard output.

#include "curvenet/embed.hpp"
#include "curvenet/jobs.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/transfer.hpp"

#include <ostream>
#include <string>

namespace curvenet::cli {

void print_embed(std::ostream& out, const std::string& mesh_name, const EmbedReport& r);
void print_bind(std::ostream& out, const JobSummary& j);
/// A job's first lines: the repairs made on loading, SUCCESS, the binding.
void print_job(std::ostream& out, const char* command, const JobSummary& j);
/// The baked skin against the rig, per clip (worst first): mean and worst vertex, with its place.
/// `helpers`: the skin has helper joints, so the floor (of the rig's joints) is not its floor.
void print_bake_fidelity(std::ostream& out, const std::vector<BakeClipFidelity>& clips, bool helpers = false);
void print_transfer(std::ostream& out, const std::string& from, int from_faces, const std::string& to, int to_faces,
                    const TransferReport& rep, const std::string& rig_out);
void print_starter(std::ostream& out, const std::string& mesh_path, const SurfaceMesh& mesh, size_t joints,
                   const StarterResult& r, const StarterOptions& options);

} // namespace curvenet::cli
