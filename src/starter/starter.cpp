// The starter Curvenet (docs/starter.md): the stages in src/starter/stages.hpp
// run in order, then the net is embedded, and on a failure what failed is
// moved or dropped, and the net built again.

#include "curvenet/starter.hpp"

#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "starter/stages.hpp"

#include <algorithm>
#include <regex>

namespace curvenet {

using namespace detail;

namespace {

std::vector<std::string> quoted(const std::string& text) {
  std::vector<std::string> out;
  static const std::regex re("'([^']+)'");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator(); ++it)
    out.push_back((*it)[1]);
  return out;
}

std::string json_quote(const std::string& t) {
  std::string q = "\"";
  for (char ch : t) {
    if (ch == '"' || ch == '\\')
      q += '\\';
    if (static_cast<unsigned char>(ch) >= 0x20)
      q += ch;
  }
  return q + "\"";
}

/// The rig's x_starter extension: what the starter made, and why.
std::string starter_extension(const std::vector<Ring>& rings, const std::vector<int>& active,
                              const std::vector<int>& unjoined, const StarterResult& result) {
  std::string ext = "{\"rings\": [";
  for (size_t k = 0; k < active.size(); ++k)
    ext += (k ? ", " : "") + json_quote(rings[active[k]].id);
  ext += "], \"unjoined\": [";
  for (size_t k = 0; k < unjoined.size(); ++k)
    ext += (k ? ", " : "") + json_quote(rings[unjoined[k]].id);
  ext += "], \"ringless\": {";
  for (size_t k = 0; k < result.ringless.size(); ++k)
    ext += (k ? ", " : "") + json_quote(result.ringless[k].first) + ": " + json_quote(result.ringless[k].second);
  ext += "}, \"net_components\": " + std::to_string(result.net_components) + ", \"notes\": [";
  for (size_t k = 0; k < result.messages.size(); ++k)
    ext += (k ? ", " : "") + json_quote(result.messages[k]);
  return ext + "]}";
}

} // namespace

StarterResult make_starter(const SurfaceMesh& mesh, const std::vector<Joint>& joints, const StarterOptions& opt) {
  if (joints.empty())
    throw InputError(mesh.source, "skeleton", "has no joints");
  if (opt.nodes_per_ring < 2)
    throw Error("starter: at least 2 nodes per ring are needed");
  if (opt.rings_per_bone < 1)
    throw Error("starter: at least 1 ring per bone is needed");
  if (joints.size() > 1 &&
      std::all_of(joints.begin(), joints.end(), [](const Joint& j) { return !j.parent.has_value(); }))
    throw InputError(mesh.source, "skeleton",
                     "its " + std::to_string(joints.size()) +
                         " joints are all roots (a flat hierarchy, as some XR hand assets have): the starter needs "
                         "bones from parent to child; give a skeleton with --skeleton");
  StarterResult result;
  const StarterContext c(mesh, joints, opt, [&](const std::string& m) {
    result.messages.push_back(m);
    if (opt.message)
      opt.message(m);
  });
  const int nj = static_cast<int>(joints.size());

  // 1 to 4: rings, trunks, clearance, chains.
  RingsResult found = candidate_rings(c);
  std::vector<Ring>& rings = found.rings;
  std::map<int, std::string>& ringless = found.ringless;
  trunk_rings(c, found.shared_start, rings);
  if (rings.empty())
    throw InputError(
        mesh.source, "skeleton",
        "lies outside the mesh: no plane through a joint cuts a loop around it (check the skeleton's space and units)");
  const std::vector<int> kept = keep_clear_rings(c, rings, ringless);
  const std::map<int, int> parent_ring = chain_rings(c, rings, kept);

  // 5 to 7: build the net, check it, embed it; on a failure move or drop
  // what failed, and repeat.
  std::set<int> dropped;
  JoinAttempts join_attempt;
  std::map<int, std::string> join_failure; // child ring -> why its last join was given up
  for (int attempt = 0;; ++attempt) {
    std::vector<int> active;
    for (int i : kept)
      if (!dropped.count(i))
        active.push_back(i);
    auto effective_parent = [&](int i) {
      int p = parent_ring.at(i);
      while (p >= 0 && dropped.count(p))
        p = parent_ring.at(p);
      return p;
    };
    NetResult net = build_net(c, rings, active, effective_parent, join_attempt);
    std::string failure = net.failure.empty() ? check_net(c, net) : net.failure;
    try {
      const Embedding e = failure.empty() ? embed(mesh, net.rig) : Embedding(nullptr);
      if (failure.empty() && e.report().ok) {
        // 8: weights.
        for (const Node& n : net.rig.nodes)
          for (const auto& [j, w] : auto_weights(joints, n.position, opt.weights))
            net.rig.weights[n.id][joints[j].name] = w;
        result.rig = std::move(net.rig);
        result.rings = static_cast<int>(active.size());
        result.joins = net.joins;
        result.unjoined = static_cast<int>(net.unjoined.size());
        result.net_components = e.report().components;
        for (int ch : net.unjoined)
          c.say("ring '" + rings[ch].id + "' is not joined to ring '" + rings[effective_parent(ch)].id +
                "': " + join_failure[ch]);
        if (!net.unjoined.empty())
          c.say(std::to_string(net.unjoined.size()) +
                " chain(s) could not be joined to their parent ring; the net has " +
                std::to_string(result.net_components) + " components, and the expected region count accounts for them");
        std::set<int> ringed;
        for (int i : active)
          if (rings[i].frac > 0) // a trunk's ring is not a joint's own
            ringed.insert(rings[i].joint);
        for (int j = 0; j < nj; ++j)
          if (!ringed.count(j))
            result.ringless.emplace_back(joints[j].name, ringless.count(j) ? ringless[j] : "its ring was dropped");
        result.rig.extensions["x_starter"] = starter_extension(rings, active, net.unjoined, result);
        return result;
      }
      if (failure.empty())
        failure = e.report().problems.empty() ? "not ok" : e.report().problems[0];
    } catch (const EmbedError& e) {
      failure = e.what();
    }
    if (attempt > 6 * static_cast<int>(rings.size()) + 8)
      throw EmbedError("starter: could not make a net that embeds: " + failure);
    // Find what to give up, of what the failure names: a join first, then
    // the child ring of a longitudinal, then the ring of an arc; a trunk's
    // ring last of all.
    int culprit = -1, best_rank = 4;
    char kind = 0;
    for (const std::string& id : quoted(failure)) {
      auto it = net.owner.find(id);
      if (it == net.owner.end())
        continue;
      const auto [k, who] = it->second;
      const int rank = k == 'j' ? 0 : rings[who].frac == 0 ? 3 : k == 'l' ? 1 : 2;
      if (rank < best_rank) {
        best_rank = rank;
        kind = k;
        culprit = who;
      }
    }
    if (culprit < 0) {
      // No profile named (for example a wrong region count): drop the largest ring.
      for (int i : active)
        if (culprit < 0 || rings[i].perimeter > rings[culprit].perimeter)
          culprit = i;
      kind = 'a';
    }
    if (kind == 'j') {
      const int m = ++join_attempt[culprit];
      const std::string& child = rings[culprit / 2].id;
      c.say("join " + std::string(culprit % 2 ? "1 " : "") + "of ring '" + child + "' " +
            (m >= 2 ? "abandoned" : "moved to an existing node") + ": " + failure);
      if (m >= 2)
        join_failure[culprit / 2] = failure;
      continue;
    }
    Ring& r = rings[culprit];
    std::vector<int> others;
    for (int i : active)
      if (i != culprit)
        others.push_back(i);
    const double t0 = r.t;
    const Ring before = r;
    bool moved = false;
    while (move_ring_on(c, r))
      if (ring_conflict(c, r, rings, others, culprit) < 0) {
        moved = true;
        break;
      }
    if (moved) {
      place_nodes(r, c.N, opt.first_angle_deg);
      c.say("ring '" + r.id + "' moved along its bone (" + percent(t0) + " to " + percent(r.t) + "): " + failure);
      continue;
    }
    r = before;
    dropped.insert(culprit);
    const std::string m = "ring '" + r.id + "' dropped: " + failure;
    c.say(m);
    if (r.frac == 1)
      ringless[r.joint] = m;
    if (dropped.size() == kept.size())
      throw EmbedError("starter: could not make a net that embeds: " + failure);
  }
}

} // namespace curvenet
