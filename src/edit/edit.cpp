// The net editor's operations (include/curvenet/edit.hpp): each edits a copy
// of the rig and checks it with the rig format's own validation.

#include "curvenet/edit.hpp"

#include "curvenet/deform.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/io.hpp"
#include "sample/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>

namespace curvenet {
namespace {

using Vec3 = Eigen::Vector3d;

const Node& node_of(const Rig& rig, const std::string& id, const std::string& source) {
  const int i = rig.node_index(id);
  if (i < 0)
    throw InputError(source, id, "the net has no node of this id");
  return rig.nodes[static_cast<size_t>(i)];
}

size_t profile_index(const Rig& rig, const std::string& id, const std::string& source) {
  for (size_t i = 0; i < rig.profiles.size(); ++i)
    if (rig.profiles[i].id == id)
      return i;
  throw InputError(source, id, "the net has no profile of this id");
}

std::string fresh_id(const std::string& prefix, const std::set<std::string>& taken) {
  for (size_t i = 0;; ++i) {
    std::string id = prefix + std::to_string(i);
    if (!taken.count(id))
      return id;
  }
}

std::set<std::string> profile_ids(const Rig& rig) {
  std::set<std::string> out;
  for (const auto& p : rig.profiles)
    out.insert(p.id);
  return out;
}

/// The profile's curve with its ends on its nodes, as the engine reads it.
detail::ProfileCurve curve_on_nodes(const Rig& rig, const Profile& p) {
  return detail::ProfileCurve(p.curve, rig.nodes[static_cast<size_t>(rig.node_index(p.from))].position,
                              rig.nodes[static_cast<size_t>(rig.node_index(p.to))].position);
}

/// Writes the profiles' curves as the engine reads them with their ends on
/// the rig's nodes: a polyline keeps its points (the ends' displacement
/// faded along it), a Bezier or NURBS curve becomes its dense sampling.
void settle_curves(Rig& rig, const std::set<std::string>& profiles) {
  for (auto& p : rig.profiles) {
    if (!profiles.count(p.id))
      continue;
    Curve c;
    c.points = curve_on_nodes(rig, p).points();
    p.curve = std::move(c);
  }
}

std::set<std::string> profiles_at(const Rig& rig, const std::string& node) {
  std::set<std::string> out;
  for (const auto& p : rig.profiles)
    if (p.from == node || p.to == node)
      out.insert(p.id);
  return out;
}

Rig checked(Rig rig, const std::string& source) {
  validate_rig(rig, source);
  return rig;
}

} // namespace

Rig remove_nodes(const Rig& rig, const std::vector<std::string>& nodes, const std::string& source) {
  std::set<std::string> gone;
  for (const auto& id : nodes)
    gone.insert(node_of(rig, id, source).id);
  Rig out = rig;
  std::erase_if(out.nodes, [&](const Node& n) { return gone.count(n.id) > 0; });
  std::erase_if(out.profiles, [&](const Profile& p) { return gone.count(p.from) || gone.count(p.to); });
  for (const auto& id : gone)
    out.weights.erase(id);
  return checked(std::move(out), source);
}

Rig remove_profiles(const Rig& rig, const std::vector<std::string>& profiles, const std::string& source) {
  std::set<std::string> gone, ends;
  for (const auto& id : profiles) {
    const Profile& p = rig.profiles[profile_index(rig, id, source)];
    gone.insert(p.id);
    ends.insert(p.from);
    ends.insert(p.to);
  }
  Rig out = rig;
  std::erase_if(out.profiles, [&](const Profile& p) { return gone.count(p.id) > 0; });
  for (const auto& p : out.profiles) {
    ends.erase(p.from);
    ends.erase(p.to);
  }
  std::erase_if(out.nodes, [&](const Node& n) { return ends.count(n.id) > 0; });
  for (const auto& id : ends)
    out.weights.erase(id);
  return checked(std::move(out), source);
}

Rig move_node(const Rig& rig, const std::string& node, const Vec3& position, const std::string& source) {
  node_of(rig, node, source);
  if (!position.allFinite())
    throw InputError(source, node, "the new position is not a finite point");
  Rig out = rig;
  out.nodes[static_cast<size_t>(out.node_index(node))].position = position;
  settle_curves(out, profiles_at(out, node));
  return checked(std::move(out), source);
}

double nearest_parameter(const Rig& rig, const std::string& profile, const Vec3& point, const std::string& source) {
  const Profile& p = rig.profiles[profile_index(rig, profile, source)];
  if (!point.allFinite())
    throw InputError(source, "profile '" + profile + "'", "the point to find on it is not finite");
  const auto curve = curve_on_nodes(rig, p);
  const auto& pts = curve.points();
  const auto& arc = curve.arc();
  const double total = curve.length();
  double best = std::numeric_limits<double>::infinity(), best_t = 0.5;
  for (size_t i = 0; i + 1 < pts.size(); ++i) {
    const Vec3 d = pts[i + 1] - pts[i];
    const double len2 = d.squaredNorm();
    const double a = len2 > 0 ? std::clamp((point - pts[i]).dot(d) / len2, 0.0, 1.0) : 0.0;
    const double dist = (pts[i] + a * d - point).squaredNorm();
    if (dist < best) {
      best = dist;
      best_t = total > 0 ? (arc[i] + a * (arc[i + 1] - arc[i])) / total : 0.5;
    }
  }
  return best_t;
}

SplitResult split_profile(const Rig& rig, const std::string& profile, double t, const std::string& source) {
  const size_t index = profile_index(rig, profile, source);
  if (!(t > 0.0 && t < 1.0))
    throw InputError(source, profile, "a split must lie inside the profile: t in (0, 1), not " + std::to_string(t));
  const Profile old = rig.profiles[index];
  const auto curve = curve_on_nodes(rig, old);
  const double total = curve.length();
  if (!(total > 0))
    throw InputError(source, profile, "the profile has no length to split");
  const auto& pts = curve.points();
  const auto& arc = curve.arc();
  const double cut = t * total;
  const Vec3 at = curve.at(t);
  std::vector<Vec3> first{pts.front()}, second{at};
  for (size_t i = 1; i + 1 < pts.size(); ++i)
    (arc[i] < cut ? first : second).push_back(pts[i]);
  first.push_back(at);
  second.push_back(pts.back());

  SplitResult out{rig, {}, {}};
  std::set<std::string> node_ids;
  for (const auto& n : rig.nodes)
    node_ids.insert(n.id);
  out.node = fresh_id("n", node_ids);
  out.profile = fresh_id("p", profile_ids(rig));
  out.rig.nodes.push_back({out.node, at});
  Profile& head = out.rig.profiles[index];
  head.to = out.node;
  head.curve = Curve{};
  head.curve.points = std::move(first);
  Profile tail{out.profile, out.node, old.to, {}};
  tail.curve.points = std::move(second);
  out.rig.profiles.insert(out.rig.profiles.begin() + static_cast<std::ptrdiff_t>(index) + 1, std::move(tail));

  if (rig.has_skeleton && (rig.weights.count(old.from) || rig.weights.count(old.to))) {
    const Rig complete = complete_weights(rig);
    auto weights_of = [&](const std::string& id) {
      auto it = complete.weights.find(id);
      return it == complete.weights.end() ? std::map<std::string, double>{} : it->second;
    };
    std::map<std::string, double> w;
    for (const auto& [j, x] : weights_of(old.from))
      w[j] += (1 - t) * x;
    for (const auto& [j, x] : weights_of(old.to))
      w[j] += t * x;
    std::erase_if(w, [](const auto& kv) { return !(kv.second > 0); });
    if (!w.empty())
      out.rig.weights[out.node] = std::move(w);
  }
  validate_rig(out.rig, source);
  return out;
}

Rig merge_nodes(const Rig& rig, const std::string& kept, const std::string& merged, const std::string& source) {
  node_of(rig, kept, source);
  node_of(rig, merged, source);
  if (kept == merged)
    throw InputError(source, kept, "a node cannot be merged with itself");
  Rig out = rig;
  auto joins = [&](const Profile& p) {
    return (p.from == kept && p.to == merged) || (p.from == merged && p.to == kept);
  };
  std::erase_if(out.profiles, joins);
  const std::set<std::string> moved = profiles_at(out, merged);
  for (auto& p : out.profiles) {
    if (p.from == merged)
      p.from = kept;
    if (p.to == merged)
      p.to = kept;
  }
  out.nodes.erase(out.nodes.begin() + out.node_index(merged));
  out.weights.erase(merged);
  settle_curves(out, moved);
  return checked(std::move(out), source);
}

Rig reroute_profile(const Rig& rig, const std::string& profile, const std::vector<Vec3>& via,
                    const std::string& source) {
  const size_t index = profile_index(rig, profile, source);
  Rig out = rig;
  Profile& p = out.profiles[index];
  Curve c;
  c.points.push_back(node_of(rig, p.from, source).position);
  for (size_t i = 0; i < via.size(); ++i) {
    if (!via[i].allFinite())
      throw InputError(source, profile, "route point " + std::to_string(i) + " is not a finite point");
    c.points.push_back(via[i]);
  }
  c.points.push_back(node_of(rig, p.to, source).position);
  p.curve = std::move(c);
  return checked(std::move(out), source);
}

Rig set_joint_weight(const Rig& rig, const std::vector<std::string>& nodes, const std::string& joint, double weight,
                     const std::string& source) {
  if (!(weight >= 0.0 && weight <= 1.0))
    throw InputError(source, joint, "a weight must be a number in [0, 1]");
  if (!rig.has_skeleton)
    throw InputError(source, "/skeleton", "the rig has no skeleton yet: bind it or make a starter net");
  if (std::none_of(rig.joints.begin(), rig.joints.end(), [&](const Joint& j) { return j.name == joint; }))
    throw InputError(source, joint, "the rig's skeleton has no joint of this name");
  for (const auto& id : nodes)
    node_of(rig, id, source);
  const Rig complete = complete_weights(rig);
  Rig out = rig;
  for (const auto& id : nodes) {
    auto it = complete.weights.find(id);
    std::map<std::string, double> others;
    if (it != complete.weights.end())
      for (const auto& [j, x] : it->second)
        if (j != joint && x > 0)
          others[j] = x;
    double total = 0;
    for (const auto& kv : others)
      total += kv.second;
    std::map<std::string, double> w;
    if (weight > 0)
      w[joint] = weight;
    if (total > 0) {
      for (const auto& [j, x] : others)
        w[j] = x / total * (1.0 - weight);
    } else {
      w = {{joint, 1.0}}; // nothing else to give the rest to
    }
    std::erase_if(w, [](const auto& kv) { return !(kv.second > 0); });
    out.weights[id] = std::move(w);
  }
  return checked(std::move(out), source);
}

} // namespace curvenet
