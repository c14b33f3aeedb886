// The rig file format, version 1 (docs/rig-format.md): reading with
// validation that names the JSON path of every fault, and writing.

#include "core/matrix_checks.hpp"
#include "curvenet/errors.hpp"
#include "io/file_bytes.hpp"
#include "curvenet/io.hpp"
#include "io/json_text.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace curvenet {

using Json = nlohmann::ordered_json;

const char* to_string(Coverage c) {
  switch (c) {
  case Coverage::Full:
    return "full";
  case Coverage::Local:
    return "local";
  case Coverage::Auto:
    return "auto";
  }
  return "auto";
}

int Rig::node_index(const std::string& id) const {
  for (size_t i = 0; i < nodes.size(); ++i)
    if (nodes[i].id == id)
      return static_cast<int>(i);
  return -1;
}

namespace {

/// More points than any drawn or traced profile needs: past this a rig is damaged or generated wrong.
constexpr size_t kMaxProfilePoints = 100000;

/// A closed polyline of no area, relative to its length: one that goes out
/// and back along itself (its vector area vanishes).
bool encloses_nothing(const std::vector<Eigen::Vector3d>& pts) {
  if (pts.size() < 2)
    return true;
  Eigen::Vector3d area = Eigen::Vector3d::Zero();
  double length = 0;
  for (size_t k = 0; k < pts.size(); ++k) {
    const Eigen::Vector3d& a = pts[k] - pts[0];
    const Eigen::Vector3d& b = pts[(k + 1) % pts.size()] - pts[0];
    area += a.cross(b);
    length += (pts[(k + 1) % pts.size()] - pts[k]).norm();
  }
  return !(area.norm() > 1e-9 * length * length);
}

} // namespace

namespace {

class RigReader {
public:
  RigReader(std::string source, const std::string& text) : source_(std::move(source)), text_(text) {}

  /// The JSON path, and the line and column where that element starts.
  [[noreturn]] void fail(const std::string& path, const std::string& msg) const {
    const std::string place = detail::json_place(text_, path);
    throw InputError(source_, (path.empty() ? "/" : path) + (place.empty() ? "" : " (" + place + ")"), msg);
  }

  const Json& require(const Json& obj, const std::string& path, const char* key) const {
    auto it = obj.find(key);
    if (it == obj.end())
      fail(path, std::string("missing required key '") + key + "'");
    return *it;
  }

  void only_keys(const Json& obj, const std::string& path, std::initializer_list<const char*> allowed) const {
    if (!obj.is_object())
      fail(path, "expected an object");
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      const std::string& k = it.key();
      if (k.rfind("x_", 0) == 0)
        continue;
      bool ok = false;
      for (const char* a : allowed)
        ok = ok || k == a;
      if (!ok)
        fail(path + "/" + k, "unknown key '" + k + "' (extensions must start with 'x_')");
    }
  }

  double number(const Json& j, const std::string& path) const {
    if (!j.is_number())
      fail(path, "expected a number");
    const double v = j.get<double>();
    if (!std::isfinite(v))
      fail(path, "not a finite number");
    return v;
  }

  std::string string(const Json& j, const std::string& path) const {
    if (!j.is_string())
      fail(path, "expected a string");
    return j.get<std::string>();
  }

  Eigen::Vector3d vec3(const Json& j, const std::string& path) const {
    if (!j.is_array() || j.size() != 3)
      fail(path, "expected an array of 3 numbers");
    return {number(j[0], path + "/0"), number(j[1], path + "/1"), number(j[2], path + "/2")};
  }

  std::vector<Eigen::Vector3d> points(const Json& j, const std::string& path, size_t min_count) const {
    if (!j.is_array())
      fail(path, "expected an array of points");
    if (j.size() < min_count)
      fail(path, "needs at least " + std::to_string(min_count) + " points, has " + std::to_string(j.size()));
    if (j.size() > kMaxProfilePoints)
      fail(path, "has " + std::to_string(j.size()) + " points, more than the " + std::to_string(kMaxProfilePoints) +
                     " a profile may have (simplify the curve)");
    std::vector<Eigen::Vector3d> pts;
    for (size_t i = 0; i < j.size(); ++i)
      pts.push_back(vec3(j[i], path + "/" + std::to_string(i)));
    return pts;
  }

  Mat4 matrix(const Json& j, const std::string& path) const {
    if (!j.is_array() || j.size() != 16)
      fail(path, "expected 16 numbers (a 4x4 matrix, row by row)");
    Mat4 m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        m(r, c) = number(j[4 * r + c], path + "/" + std::to_string(4 * r + c));
    if (m(3, 0) != 0 || m(3, 1) != 0 || m(3, 2) != 0 || m(3, 3) != 1)
      fail(path, "the last row of the matrix must be 0 0 0 1");
    return m;
  }

  Curve curve(const Json& p, const std::string& path) const {
    const int forms = static_cast<int>(p.contains("points")) + static_cast<int>(p.contains("bezier")) +
                      static_cast<int>(p.contains("nurbs"));
    if (forms != 1)
      fail(path, "needs exactly one of 'points', 'bezier' or 'nurbs'");
    Curve c;
    if (p.contains("points")) {
      c.kind = Curve::Kind::Polyline;
      c.points = points(p["points"], path + "/points", 2);
    } else if (p.contains("bezier")) {
      c.kind = Curve::Kind::Bezier;
      c.points = points(p["bezier"], path + "/bezier", 4);
      if ((c.points.size() - 1) % 3 != 0)
        fail(path + "/bezier", "a cubic Bezier needs 3k+1 control points, has " + std::to_string(c.points.size()));
    } else {
      c.kind = Curve::Kind::Nurbs;
      const std::string np = path + "/nurbs";
      const Json& n = p["nurbs"];
      only_keys(n, np, {"degree", "points", "knots", "weights"});
      c.degree = static_cast<int>(detail::json_integer(require(n, np, "degree"), source_, np + "/degree", 1, 32));
      c.points = points(require(n, np, "points"), np + "/points", static_cast<size_t>(c.degree) + 1);
      const Json& k = require(n, np, "knots");
      if (!k.is_array())
        fail(np + "/knots", "expected an array of numbers");
      for (size_t i = 0; i < k.size(); ++i)
        c.knots.push_back(number(k[i], np + "/knots/" + std::to_string(i)));
      const size_t npts = c.points.size(), deg = static_cast<size_t>(c.degree);
      if (c.knots.size() == npts + deg - 1) { // Maya's convention: repeat the end knots once
        c.knots.insert(c.knots.begin(), c.knots.front());
        c.knots.push_back(c.knots.back());
      }
      if (c.knots.size() != npts + deg + 1)
        fail(np + "/knots", "needs " + std::to_string(npts + deg + 1) + " knots (points + degree + 1), has " +
                                std::to_string(k.size()));
      for (size_t i = 1; i < c.knots.size(); ++i)
        if (c.knots[i] < c.knots[i - 1])
          fail(np + "/knots/" + std::to_string(i), "knots must not decrease");
      if (!(c.knots[deg] < c.knots[npts]))
        fail(np + "/knots", "the curve's knot domain is empty");
      if (n.contains("weights")) {
        const Json& w = n["weights"];
        if (!w.is_array() || w.size() != npts)
          fail(np + "/weights", "needs one weight per control point");
        for (size_t i = 0; i < w.size(); ++i) {
          const double v = number(w[i], np + "/weights/" + std::to_string(i));
          if (!(v > 0))
            fail(np + "/weights/" + std::to_string(i), "weights must be positive");
          c.weights.push_back(v);
        }
      }
    }
    return c;
  }

  Rig read(const Json& root) const {
    Rig rig;
    only_keys(root, "", {"format", "version", "coverage", "frame", "nodes", "profiles", "skeleton", "weights"});
    if (string(require(root, "", "format"), "/format") != "curvenet-rig")
      fail("/format", "must be \"curvenet-rig\"");
    if (detail::json_integer(require(root, "", "version"), source_, "/version", 1, 1) != 1)
      fail("/version", "only version 1 is supported");
    if (root.contains("coverage")) {
      const std::string c = string(root["coverage"], "/coverage");
      if (c == "full")
        rig.coverage = Coverage::Full;
      else if (c == "local")
        rig.coverage = Coverage::Local;
      else if (c == "auto")
        rig.coverage = Coverage::Auto;
      else
        fail("/coverage", "must be \"full\", \"local\" or \"auto\", not \"" + c + "\"");
    }
    if (root.contains("frame")) {
      rig.frame = matrix(root["frame"], "/frame");
      if (!detail::similarity(rig.frame))
        fail("/frame", "the frame must be a similarity (a rotation, a uniform scale and a translation)");
    }
    for (auto it = root.begin(); it != root.end(); ++it)
      if (it.key().rfind("x_", 0) == 0)
        rig.extensions[it.key()] = it->dump();

    const Json& nodes = require(root, "", "nodes");
    if (!nodes.is_array())
      fail("/nodes", "expected an array");
    std::set<std::string> node_ids;
    for (size_t i = 0; i < nodes.size(); ++i) {
      const std::string path = "/nodes/" + std::to_string(i);
      only_keys(nodes[i], path, {"id", "position"});
      Node n;
      n.id = string(require(nodes[i], path, "id"), path + "/id");
      if (!node_ids.insert(n.id).second)
        fail(path + "/id", "duplicate node id '" + n.id + "'");
      n.position = vec3(require(nodes[i], path, "position"), path + "/position");
      rig.nodes.push_back(std::move(n));
    }

    const Json& profiles = require(root, "", "profiles");
    if (!profiles.is_array())
      fail("/profiles", "expected an array");
    std::set<std::string> profile_ids;
    for (size_t i = 0; i < profiles.size(); ++i) {
      const std::string path = "/profiles/" + std::to_string(i);
      only_keys(profiles[i], path, {"id", "from", "to", "points", "bezier", "nurbs"});
      Profile p;
      p.id = string(require(profiles[i], path, "id"), path + "/id");
      if (!profile_ids.insert(p.id).second)
        fail(path + "/id", "duplicate profile id '" + p.id + "'");
      p.from = string(require(profiles[i], path, "from"), path + "/from");
      if (!node_ids.count(p.from))
        fail(path + "/from", "names node '" + p.from + "', which does not exist");
      p.to = string(require(profiles[i], path, "to"), path + "/to");
      if (!node_ids.count(p.to))
        fail(path + "/to", "names node '" + p.to + "', which does not exist");
      p.curve = curve(profiles[i], path);
      if (p.from == p.to && encloses_nothing(p.curve.points))
        fail(path, "a loop from node '" + p.from + "' back to itself that encloses nothing (it goes out and back " +
                       "along itself); a loop must go round");
      rig.profiles.push_back(std::move(p));
    }

    std::set<std::string> joint_names;
    if (root.contains("skeleton")) {
      const Json& sk = root["skeleton"];
      only_keys(sk, "/skeleton", {"joints"});
      const Json& joints = require(sk, "/skeleton", "joints");
      if (!joints.is_array())
        fail("/skeleton/joints", "expected an array");
      rig.has_skeleton = true;
      for (size_t i = 0; i < joints.size(); ++i) {
        const std::string path = "/skeleton/joints/" + std::to_string(i);
        only_keys(joints[i], path, {"name", "parent", "bind"});
        Joint j;
        j.name = string(require(joints[i], path, "name"), path + "/name");
        const Json& parent = require(joints[i], path, "parent");
        if (!parent.is_null()) {
          j.parent = string(parent, path + "/parent");
          if (!joint_names.count(*j.parent))
            fail(path + "/parent", "parent '" + *j.parent + "' is not listed before this joint");
        }
        if (!joint_names.insert(j.name).second)
          fail(path + "/name", "duplicate joint name '" + j.name + "'");
        j.bind = matrix(require(joints[i], path, "bind"), path + "/bind");
        if (!detail::bounded_scale(j.bind))
          fail(path + "/bind", "the bind matrix is singular, nearly so, or scales by more than 1e9");
        rig.joints.push_back(std::move(j));
      }
      if (rig.joints.empty())
        fail("/skeleton/joints", "the skeleton has no joints (leave the skeleton out instead)");
    }

    if (root.contains("weights")) {
      const Json& w = root["weights"];
      if (!w.is_object())
        fail("/weights", "expected an object");
      for (auto it = w.begin(); it != w.end(); ++it) {
        const std::string path = "/weights/" + it.key();
        if (!node_ids.count(it.key()))
          fail(path, "names node '" + it.key() + "', which does not exist");
        if (!it->is_object())
          fail(path, "expected an object of joint weights");
        auto& entry = rig.weights[it.key()];
        for (auto jt = it->begin(); jt != it->end(); ++jt) {
          const std::string jp = path + "/" + jt.key();
          if (!joint_names.count(jt.key()))
            fail(jp, "names joint '" + jt.key() + "', which the skeleton lacks");
          const double v = number(*jt, jp);
          if (v < 0)
            fail(jp, "weights must not be negative");
          entry[jt.key()] = v;
        }
      }
    }
    return rig;
  }

private:
  std::string source_;
  const std::string& text_;
};

Json vec_json(const Eigen::Vector3d& p) {
  return Json::array({p.x(), p.y(), p.z()});
}
Json points_json(const std::vector<Eigen::Vector3d>& pts) {
  Json a = Json::array();
  for (const auto& p : pts)
    a.push_back(vec_json(p));
  return a;
}
Json matrix_json(const Mat4& m) {
  Json a = Json::array();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      a.push_back(m(r, c));
  return a;
}

} // namespace

Rig parse_rig(const std::string& text, const std::string& source) {
  return RigReader(source, text).read(detail::parse_json(text, source));
}

Rig read_rig(const std::string& path) {
  if (std::filesystem::is_directory(path))
    throw InputError(path, "", "is a folder, not a rig file");
  return parse_rig(detail::file_bytes(path), path); // a FIFO no one writes is refused, not waited on
}

namespace {
/// No rig is written with a number that is not finite: it would read back
/// as null, or not at all.
void check_finite(const Rig& rig) {
  auto bad = [](const Eigen::Vector3d& p) { return !p.allFinite(); };
  if (!rig.frame.allFinite())
    throw Error("rig: the frame is not finite; nothing was written");
  for (const auto& n : rig.nodes)
    if (bad(n.position))
      throw Error("rig: node '" + n.id + "' has a position that is not finite; nothing was written");
  for (const auto& p : rig.profiles) {
    for (const auto& q : p.curve.points)
      if (bad(q))
        throw Error("rig: profile '" + p.id + "' has a point that is not finite; nothing was written");
    for (double k : p.curve.knots)
      if (!std::isfinite(k))
        throw Error("rig: profile '" + p.id + "' has a knot that is not finite; nothing was written");
    for (double k : p.curve.weights)
      if (!std::isfinite(k))
        throw Error("rig: profile '" + p.id + "' has a weight that is not finite; nothing was written");
  }
  for (const auto& j : rig.joints)
    if (!j.bind.allFinite())
      throw Error("rig: joint '" + j.name + "' has a bind matrix that is not finite; nothing was written");
  for (const auto& [node, w] : rig.weights)
    for (const auto& [joint, v] : w)
      if (!std::isfinite(v))
        throw Error("rig: the weight of node '" + node + "' for joint '" + joint +
                    "' is not finite; nothing was written");
}
} // namespace

std::string rig_to_json(const Rig& rig) {
  check_finite(rig);
  Json root;
  root["format"] = "curvenet-rig";
  root["version"] = 1;
  root["coverage"] = to_string(rig.coverage);
  root["frame"] = matrix_json(rig.frame);
  Json nodes = Json::array();
  for (const auto& n : rig.nodes)
    nodes.push_back({{"id", n.id}, {"position", vec_json(n.position)}});
  root["nodes"] = nodes;
  Json profiles = Json::array();
  for (const auto& p : rig.profiles) {
    Json j{{"id", p.id}, {"from", p.from}, {"to", p.to}};
    switch (p.curve.kind) {
    case Curve::Kind::Polyline:
      j["points"] = points_json(p.curve.points);
      break;
    case Curve::Kind::Bezier:
      j["bezier"] = points_json(p.curve.points);
      break;
    case Curve::Kind::Nurbs: {
      Json n{{"degree", p.curve.degree}, {"points", points_json(p.curve.points)}, {"knots", p.curve.knots}};
      if (!p.curve.weights.empty())
        n["weights"] = p.curve.weights;
      j["nurbs"] = n;
      break;
    }
    }
    profiles.push_back(j);
  }
  root["profiles"] = profiles;
  if (rig.has_skeleton) {
    Json joints = Json::array();
    for (const auto& jt : rig.joints)
      joints.push_back({{"name", jt.name},
                        {"parent", jt.parent ? Json(*jt.parent) : Json(nullptr)},
                        {"bind", matrix_json(jt.bind)}});
    root["skeleton"] = {{"joints", joints}};
  }
  if (!rig.weights.empty()) {
    Json w = Json::object();
    for (const auto& [node, m] : rig.weights) {
      Json e = Json::object();
      for (const auto& [joint, v] : m)
        e[joint] = v;
      w[node] = e;
    }
    root["weights"] = w;
  }
  for (const auto& [key, text] : rig.extensions)
    root[key] = Json::parse(text);
  return root.dump(1) + "\n";
}

namespace {
/// The reader's rules, on a rig in memory. Its faults name the JSON path
/// only: the line and column of text that was never a file mean nothing.
std::string checked_json(const Rig& rig, const std::string& source, bool writing) {
  std::string text;
  try {
    text = rig_to_json(rig);
  } catch (const InputError&) {
    throw;
  } catch (const Error& e) {
    // A number that is not finite: rig_to_json names the node, profile or joint.
    std::string message = e.what();
    if (message.rfind("rig: ", 0) == 0)
      message = message.substr(5);
    const std::string tail = "; nothing was written";
    if (!writing && message.size() > tail.size() &&
        message.compare(message.size() - tail.size(), tail.size(), tail) == 0)
      message.resize(message.size() - tail.size());
    throw InputError(source, "", message);
  }
  try {
    (void)parse_rig(text, source);
  } catch (const InputError& e) {
    const std::string element = e.element().substr(0, e.element().find(" (line "));
    std::string message = e.what();
    const std::string head = source + ": " + e.element() + ": ";
    if (message.rfind(head, 0) == 0)
      message = message.substr(head.size());
    throw InputError(source, element, message);
  }
  return text;
}
} // namespace

void validate_rig(const Rig& rig, const std::string& source) {
  (void)checked_json(rig, source, false);
}

void write_rig(const Rig& rig, const std::string& path) {
  write_file_atomic(path, checked_json(rig, path, true)); // never a file that read_rig would refuse
}

} // namespace curvenet
