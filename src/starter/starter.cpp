// The starter Curvenet (docs/starter.md): the stages in src/starter/stages.hpp
// run in order, then the net is embedded, and on a failure what failed is
// moved or dropped, and the net built again.

#include "curvenet/starter.hpp"

#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "starter/stages.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace curvenet {

using namespace detail;

namespace {

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

/// The skeleton the net is made for (docs/starter.md, "Joints that
/// deform"). When the skin's weights are known: the joints that carry
/// weight, and the tips that end a weighted bone inside the mesh; otherwise
/// the joints inside the mesh (their origin, or the middle of their bone)
/// and those with descendants in the net. A joint on its parent (a bone of
/// no length: a twist helper) goes too, its children under the parent. Each goes under its nearest ancestor in the net,
/// parents first; a second root (an IK chain of its own, a foot) under the
/// joint of the rest it lies nearest to. The joints left out come with the
/// reason.
std::vector<Joint> working_skeleton(const SurfaceMesh& mesh, const std::vector<Joint>& joints,
                                    const StarterOptions& opt,
                                    std::vector<std::pair<std::string, std::string>>& skipped) {
  const Skeleton sk(joints);
  const int n = static_cast<int>(joints.size());
  const bool known = !opt.deforming.empty();
  auto weighted = [&](int j) { return j >= 0 && opt.deforming.count(joints[j].name) > 0; };
  std::vector<char> inside(n, 0), rigged(n, 0);
  for (int j = 0; j < n; ++j) {
    const int p = sk.parent[j];
    inside[j] = mesh.winding_number(sk.origin[j]) >= 0.5 ||
                (p >= 0 && mesh.winding_number((sk.origin[p] + sk.origin[j]) / 2) >= 0.5);
  }
  for (int pass = 0; pass <= n; ++pass) { // from the leaves up, until nothing changes
    bool changed = false;
    for (int j = n - 1; j >= 0; --j) {
      if (rigged[j])
        continue;
      const bool below = std::any_of(sk.kids[j].begin(), sk.kids[j].end(), [&](int k) { return rigged[k] != 0; });
      const bool tip = sk.kids[j].empty() && inside[j] && weighted(sk.parent[j]);
      const bool keep = known ? weighted(j) || tip : inside[j] || below;
      if (keep)
        rigged[j] = changed = 1;
    }
    if (!changed)
      break;
  }
  std::vector<std::string> why(n);
  for (int j = 0; j < n; ++j)
    why[j] = known && !weighted(j)
                 ? (inside[j] ? "carries no skin weight" : "carries no skin weight and lies outside the mesh")
                 : "lies outside the mesh";
  for (int j = 0; j < n; ++j) {
    int a = sk.parent[j];
    while (a >= 0 && !rigged[a])
      a = sk.parent[a];
    if (rigged[j] && a >= 0 && sk.origin[j] == sk.origin[a]) {
      rigged[j] = 0;
      why[j] = "sits on '" + joints[a].name + "' (a bone of no length)";
    }
  }
  std::vector<int> parent(n, -1);
  for (int j = 0; j < n; ++j) {
    int a = sk.parent[j];
    while (a >= 0 && !rigged[a])
      a = sk.parent[a];
    parent[j] = a;
  }
  // A bone that runs outside the body (a foot parented to a root on the
  // floor, as IK rigs do) does not hold its joint: the joint goes where a
  // second root goes.
  auto through_body = [&](const Vec3& a, const Vec3& b) { return mesh.winding_number((a + b) / 2) >= 0.5; };
  for (int j = 0; j < n; ++j)
    if (rigged[j] && parent[j] >= 0 && !through_body(sk.origin[parent[j]], sk.origin[j]))
      parent[j] = -1;
  // Roots of what is left: the one with the most joints below it keeps its
  // place; each other goes under the joint nearest to it.
  std::vector<int> size(n, 0), roots;
  for (int j = 0; j < n; ++j)
    if (rigged[j]) {
      int r = j;
      while (parent[r] >= 0)
        r = parent[r];
      ++size[r];
      if (r == j)
        roots.push_back(j);
    }
  if (roots.empty())
    return joints; // nothing deforms inside the mesh: the stages say so
  const int main_root = *std::max_element(roots.begin(), roots.end(), [&](int a, int b) { return size[a] < size[b]; });
  std::vector<char> placed(n, 0);
  auto mark = [&](int root) {
    for (int j = 0; j < n; ++j) {
      int r = j;
      while (r >= 0 && r != root)
        r = parent[r];
      if (rigged[j] && r == root)
        placed[j] = 1;
    }
  };
  mark(main_root);
  // Under the nearest joint it reaches through the body (the middle of the
  // segment between them inside the mesh: a hoof's chain goes under its
  // leg, not under the other hoof); or the nearest at all.
  std::vector<int> order = roots;
  std::sort(order.begin(), order.end(), [&](int a, int b) {
    return (sk.origin[a] - sk.origin[main_root]).norm() < (sk.origin[b] - sk.origin[main_root]).norm();
  });
  for (int r : order) {
    if (r == main_root)
      continue;
    int best = -1, any = -1;
    for (int j = 0; j < n; ++j) {
      if (!placed[j])
        continue;
      const double d = (sk.origin[j] - sk.origin[r]).norm();
      if (any < 0 || d < (sk.origin[any] - sk.origin[r]).norm())
        any = j;
      if ((best < 0 || d < (sk.origin[best] - sk.origin[r]).norm()) && through_body(sk.origin[j], sk.origin[r]))
        best = j;
    }
    parent[r] = best >= 0 ? best : any;
    mark(r);
  }
  // Parents first.
  std::vector<Joint> out;
  std::vector<char> done(n, 0);
  for (int pass = 0; pass <= n && out.size() < static_cast<size_t>(std::count(rigged.begin(), rigged.end(), 1)); ++pass)
    for (int j = 0; j < n; ++j)
      if (rigged[j] && !done[j] && (parent[j] < 0 || done[parent[j]])) {
        Joint jt = joints[j];
        jt.parent = parent[j] >= 0 ? std::optional<std::string>(joints[parent[j]].name) : std::nullopt;
        out.push_back(jt);
        done[j] = 1;
      }
  for (int j = 0; j < n; ++j)
    if (!rigged[j])
      skipped.emplace_back(joints[j].name, "left out of the net: it " + why[j]);
  return out;
}

/// The result of a net that embeds: its rig, counts, joints without a
/// ring, and the record of what was made (`x_starter`).
void finish(const StarterContext& c, const std::vector<Ring>& rings, const std::vector<int>& active, NetResult& net,
            const NetRepairs& st, const std::map<int, std::string>& ringless,
            const std::vector<std::pair<std::string, std::string>>& skipped, int components,
            const std::vector<Joint>& all_joints, StarterResult& result) {
  const std::vector<Joint>& joints = c.joints;
  result.rig = std::move(net.rig);
  result.rig.joints = all_joints; // the rig drives the whole skeleton; the net was made for the part that deforms
  result.rings = static_cast<int>(active.size());
  result.joins = net.joins;
  result.unjoined = static_cast<int>(net.unjoined.size());
  result.net_components = components;
  for (int ch : net.unjoined)
    c.say("ring '" + rings[ch].id + "' is not joined to ring '" + rings[st.effective_parent(ch)].id +
          "': " + (st.join_failure.count(ch) ? st.join_failure.at(ch) : std::string()));
  if (!net.unjoined.empty())
    c.say(std::to_string(net.unjoined.size()) + " chain(s) could not be joined to their parent ring; the net has " +
          std::to_string(result.net_components) + " components, and the expected region count accounts for them");
  std::set<int> ringed;
  for (int i : active)
    if (rings[i].frac > 0 && rings[i].frac <= 1) // a trunk's ring is not a joint's own, nor one out beyond it
      ringed.insert(rings[i].joint);
  for (int j = 0; j < static_cast<int>(joints.size()); ++j)
    if (!ringed.count(j))
      result.ringless.emplace_back(joints[j].name, ringless.count(j) ? ringless.at(j) : "its ring was dropped");
  for (const auto& entry : skipped)
    result.ringless.push_back(entry);
  result.rig.extensions["x_starter"] = starter_extension(rings, active, net.unjoined, result);
}

} // namespace

StarterResult make_starter(const SurfaceMesh& mesh, const std::vector<Joint>& all_joints, const StarterOptions& opt) {
  if (all_joints.empty())
    throw InputError(mesh.source, "skeleton", "has no joints");
  if (opt.nodes_per_ring < 2)
    throw Error("starter: at least 2 nodes per ring are needed");
  if (opt.rings_per_bone < 1)
    throw Error("starter: at least 1 ring per bone is needed");
  if (all_joints.size() > 1 &&
      std::all_of(all_joints.begin(), all_joints.end(), [](const Joint& j) { return !j.parent.has_value(); }))
    throw InputError(mesh.source, "skeleton",
                     "its " + std::to_string(all_joints.size()) +
                         " joints are all roots (a flat hierarchy, as some XR hand assets have): the starter needs "
                         "bones from parent to child; give a skeleton with --skeleton");
  if (opt.skin && opt.skin->vertex_joint.size() != mesh.input_to_welded.size())
    throw InputError(opt.skin->source, "skin",
                     "weights " + std::to_string(opt.skin->vertex_joint.size()) + " vertices, but " + mesh.source +
                         " has " + std::to_string(mesh.input_to_welded.size()) + ": it is another mesh's skin");
  StarterResult result;
  std::vector<std::pair<std::string, std::string>> skipped;
  const std::vector<Joint> work = working_skeleton(mesh, all_joints, opt, skipped);
  for (const auto& [name, reason] : skipped) {
    result.messages.push_back("joint '" + name + "' " + reason);
    if (opt.message)
      opt.message(result.messages.back());
  }
  const std::vector<Joint>& joints = work;
  const RingOptions ring_options = RingOptions::from(opt);
  NetOptions net_options = NetOptions::from(opt);
  const StarterContext c(mesh, joints, [&](const std::string& m) {
    result.messages.push_back(m);
    if (opt.message)
      opt.message(m);
  });
  if (net_options.coverage == Coverage::Auto) {
    // Full on a closed mesh; on an open one (a scan, a mesh with holes, a
    // LOD simplified part by part) a full net cannot embed, and a local
    // one deforms what the net covers.
    const std::string open = open_parts_words(mesh);
    net_options.coverage = open.empty() ? Coverage::Full : Coverage::Local;
    if (!open.empty())
      c.say("the mesh is open (" + open + "): the net's coverage is local, as the mesh is");
  }

  // 1 to 4: rings, trunks, clearance, chains.
  RingsResult found = candidate_rings(c, ring_options);
  std::vector<Ring>& rings = found.rings;
  std::map<int, std::string>& ringless = found.ringless;
  trunk_rings(c, ring_options, found.shared_start, rings);
  if (rings.empty())
    throw InputError(
        mesh.source, "skeleton",
        "lies outside the mesh: no plane through a joint cuts a loop around it (check the skeleton's space and units)");
  NetRepairs st;
  st.kept = keep_clear_rings(c, ring_options, rings, ringless);
  st.parent_ring = chain_rings(c, ring_options, rings, st.kept);

  // 5 to 8: build the net, check it, embed it; on a failure give up what
  // failed (7), and repeat; then the weights.
  for (;;) {
    const std::vector<int> active = st.active();
    if (active.empty()) {
      // Nothing to write: an empty net would embed, bind and pose nothing.
      std::string why = ringless.empty() ? std::string("every ring was dropped") : ringless.begin()->second;
      throw InputError(mesh.source, "skeleton",
                       "no joint gets a ring, so there is no net to make (joint '" +
                           joints[ringless.empty() ? 0 : ringless.begin()->first].name + "': " + why + ")");
    }
    const auto parent_of = [&](int i) { return st.effective_parent(i); };
    NetResult net = build_net(c, net_options, rings, active, parent_of, st.join_attempt, st.path_skip);
    std::string failure = net.failure.empty() ? check_net(c, net_options, net) : net.failure;
    // With the middle nodes, the net split by them, and then the whole net
    // (which passed the same checks) if the split one does not embed.
    std::vector<NetResult> tries{net};
    if (failure.empty() && net_options.middle_nodes && opt.skin != nullptr) {
      split_profiles_at_middle(c, net_options, net);
      tries.insert(tries.begin(), std::move(net));
    }
    std::string split_failure;
    for (size_t k = 0; failure.empty() && k < tries.size(); ++k) {
      std::string why;
      try {
        const Embedding e = embed(mesh, tries[k].rig);
        if (e.report().ok) {
          if (k > 0)
            c.say("the net is kept without its middle nodes: the net split by them does not embed: " + split_failure);
          node_weights(c, NodeWeightOptions::from(opt), rings, active, e, all_joints, tries[k]);
          finish(c, rings, active, tries[k], st, ringless, skipped, e.report().components, all_joints, result);
          return result;
        }
        why = e.report().problems.empty() ? "not ok" : e.report().problems[0];
      } catch (const EmbedError& e) {
        why = e.what();
      }
      if (k + 1 < tries.size())
        split_failure = why;
      else
        failure = why; // the whole net's: what the repairs act on
    }
    net = std::move(tries.back());
    repair_net(c, ring_options, rings, ringless, net, failure, st);
  }
}

} // namespace curvenet
