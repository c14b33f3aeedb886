// Stage 7 of the starter: when the net fails its check or its embedding,
// give up what the failure names, cheapest first.

#include "core/quoted.hpp"
#include "curvenet/errors.hpp"
#include "starter/stages.hpp"

#include <algorithm>
#include <cmath>

namespace curvenet::detail {

std::vector<int> NetRepairs::active() const {
  std::vector<int> out;
  for (int i : kept)
    if (!dropped.count(i))
      out.push_back(i);
  return out;
}

int NetRepairs::effective_parent(int i) const {
  const auto o = parent_override.find(i);
  int p = o != parent_override.end() ? o->second : parent_ring.at(i);
  while (p >= 0 && dropped.count(p)) // a dropped ring's children go up its own chain
    p = parent_ring.at(p);
  return p;
}

namespace {

/// Where the mesh is in several open parts, said after a refusal: a net's
/// curves cannot cross from one part to another (a mesh decimated or
/// exported without welding falls apart at its seams).
std::string in_pieces(const SurfaceMesh& mesh) {
  const auto parts = mesh_components(mesh);
  const auto open = std::count_if(parts.begin(), parts.end(), [](const ComponentInfo& p) { return !p.closed; });
  if (open < 2)
    return "";
  return "; the mesh is in " + std::to_string(parts.size()) + " parts, " + std::to_string(open) +
         " of them open, and no curve crosses from one part to another: weld it (Blender's Merge by Distance) if "
         "its parts were one surface";
}


/// A join given up once more; with both of a chain's joins given up, the
/// chain joins the nearest other ring up its chain or hanging from one (the
/// trunk it hangs from, the limb beside it; never further down another
/// limb), a few times over.
void give_up_join(const StarterContext& c, const std::vector<Ring>& rings, int slot, const std::string& failure,
                  NetRepairs& st) {
  const int m = ++st.join_attempt[slot];
  const int ch = slot / 2;
  c.say("join " + std::string(slot % 2 ? "1 " : "") + "of ring '" + rings[ch].id + "' " +
        (m >= kJoinTries ? "abandoned"
         : m == 1        ? "moved to an existing node"
                         : "moved to the middle of an arc") +
        ": " + failure);
  if (m >= kJoinTries)
    st.join_failure[ch] = failure;
  if (st.join_attempt[2 * ch] < kJoinTries || st.join_attempt[2 * ch + 1] < kJoinTries || st.tried[ch].size() >= 3)
    return;
  st.tried[ch].insert(st.effective_parent(ch));
  std::set<int> up;
  for (int i = st.parent_ring.at(ch); i >= 0 && up.size() <= rings.size(); i = st.parent_ring.at(i))
    up.insert(i);
  int best = -1;
  double best_d = INFINITY;
  for (int i : st.active()) {
    if (i == ch || st.tried[ch].count(i) || !(up.count(i) || up.count(st.parent_ring.at(i))))
      continue;
    const double d = polyline_distance(rings[ch].loop, true, rings[i].loop, true);
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  if (best >= 0) {
    st.parent_override[ch] = best;
    st.join_attempt[2 * ch] = st.join_attempt[2 * ch + 1] = 0;
    c.say("ring '" + rings[ch].id + "' joins ring '" + rings[best].id + "' instead");
  }
}

/// Rings that `moved` had displaced (dropped for coming too close to it)
/// come back where they now keep clear of every ring in play, now that it
/// has moved or been dropped; then the chains and nodes are made again over
/// the rings in play. True when one came back.
bool readmit_displaced(const StarterContext& c, const RingOptions& ro, std::vector<Ring>& rings,
                       std::map<int, std::string>& ringless, int moved, const std::string& how, NetRepairs& st) {
  std::vector<int> left = st.active();
  bool back = false;
  for (size_t i = 0; i < rings.size(); ++i) {
    Ring& q = rings[i];
    if (q.active || q.replaced_by != moved || st.dropped.count(static_cast<int>(i)) ||
        ring_conflict(c, ro, q, rings, left, static_cast<int>(i)) >= 0)
      continue;
    q.active = true;
    q.replaced_by = -1;
    left.push_back(static_cast<int>(i));
    back = true;
    c.say("ring '" + q.id + "' comes back: ring '" + rings[moved].id + "', which it came too close to, " + how);
    if (q.frac == 1)
      ringless.erase(q.joint);
  }
  if (back) { // chains and nodes again, over the rings left
    for (int i : st.dropped)
      rings[i].active = false;
    st.kept = left;
    st.dropped.clear();
    st.parent_ring = chain_rings(c, ro, rings, st.kept);
    st.join_attempt.clear();
    st.parent_override.clear();
    st.tried.clear();
  }
  return back;
}

/// A ring moved along its bone where it keeps clear of the others, or
/// dropped; rings it had displaced come back where they now keep clear.
void move_or_drop(const StarterContext& c, const RingOptions& ro, std::vector<Ring>& rings,
                  std::map<int, std::string>& ringless, int culprit, const std::string& failure, NetRepairs& st) {
  st.path_skip.clear(); // the rings change: every path is found again
  Ring& r = rings[culprit];
  std::vector<int> others;
  for (int i : st.active())
    if (i != culprit)
      others.push_back(i);
  const double t0 = r.t;
  const Ring before = r;
  while (move_ring_on(c, ro, r))
    if (ring_conflict(c, ro, r, rings, others, culprit) < 0) {
      place_nodes(r, ro.nodes_per_ring, ro.first_angle_deg);
      c.say("ring '" + r.id + "' moved along its bone (" + percent(t0) + " to " + percent(r.t) + "): " + failure);
      readmit_displaced(c, ro, rings, ringless, culprit, "moved", st);
      return;
    }
  r = before;
  st.dropped.insert(culprit);
  const std::string m = "ring '" + r.id + "' dropped: " + failure;
  c.say(m);
  if (r.frac == 1)
    ringless[r.joint] = m;
  if (st.dropped.size() == st.kept.size())
    throw EmbedError("starter: could not make a net that embeds: " + failure + in_pieces(c.mesh));
  readmit_displaced(c, ro, rings, ringless, culprit, "is dropped", st);
}

} // namespace

void repair_net(const StarterContext& c, const RingOptions& ro, std::vector<Ring>& rings,
                std::map<int, std::string>& ringless, const NetResult& net, const std::string& failure,
                NetRepairs& st) {
  // Two profiles along one chain that come too close: first another path
  // for one of them (another plane section between its nodes). These tries
  // have their own budget, so that they never use up the rings' repairs.
  if (failure.find("come closer than") != std::string::npos &&
      st.path_retries < 2 * static_cast<int>(rings.size()) + 9) {
    std::vector<std::string> along;
    for (const std::string& id : quoted(failure))
      if (const auto it = net.owner.find(id); it != net.owner.end() && it->second.first == 'l')
        along.push_back(id);
    if (along.size() == 2 && net.owner.at(along[0]).second == net.owner.at(along[1]).second)
      for (const std::string& id : {along[1], along[0]})
        if (st.path_skip[id] < kPathTries) {
          ++st.path_skip[id];
          ++st.path_retries;
          c.say("profile '" + id + "' takes another path along the surface: " + failure);
          return;
        }
  }
  if (++st.attempts > 6 * static_cast<int>(rings.size()) + 9)
    throw EmbedError("starter: could not make a net that embeds: " + failure + in_pieces(c.mesh));
  // What the failure names: a join first, then the child ring of a
  // longitudinal, then the ring of an arc; a trunk's ring last of all.
  int culprit = -1, best_rank = 4;
  char kind = 0;
  for (const std::string& id : quoted(failure)) {
    const auto it = net.owner.find(id);
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
  if (culprit < 0) { // no profile named (a wrong region count, say): the largest ring
    for (int i : st.active())
      if (culprit < 0 || rings[i].perimeter > rings[culprit].perimeter)
        culprit = i;
    kind = 'a';
  }
  if (kind == 'j')
    give_up_join(c, rings, culprit, failure, st);
  else
    move_or_drop(c, ro, rings, ringless, culprit, failure, st);
}

} // namespace curvenet::detail
