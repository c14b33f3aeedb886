#include "curvenet/pose.hpp"

#include "curvenet/errors.hpp"
#include "io/file_bytes.hpp"
#include "skeleton/skeleton_fit.hpp"

#include <nlohmann/json.hpp>

#include "io/json_text.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <sstream>

namespace curvenet {

Mat4 JointPose::matrix() const {
  Eigen::Affine3d a = Eigen::Affine3d::Identity();
  a.translate(translation);
  a.rotate(rotation);
  a.scale(scale);
  return a.matrix();
}

PoseFile parse_pose_file(const std::string& text, const std::string& source) {
  const nlohmann::ordered_json root = detail::parse_json(text, source);
  auto fail = [&](const std::string& path, const std::string& msg) { throw InputError(source, path, msg); };
  if (!root.is_object())
    fail("/", "expected an object");
  if (!root.contains("format") || root["format"] != "curvenet-pose")
    fail("/format", "must be \"curvenet-pose\"");
  if (!root.contains("version"))
    fail("/version", "give the version: 1, or 2 with node offsets");
  const int version = static_cast<int>(detail::json_integer(root["version"], source, "/version", 1, 2));
  for (auto it = root.begin(); it != root.end(); ++it)
    if (it.key() != "format" && it.key() != "version" && it.key() != "joints" && it.key().rfind("x_", 0) != 0 &&
        !(it.key() == "nodes" && version >= 2))
      fail("/" + it.key(), "unknown key '" + it.key() + "'" + (it.key() == "nodes" ? " (nodes need version 2)" : ""));
  PoseFile file;
  Pose& pose = file.joints;
  auto numbers = [&](const nlohmann::ordered_json& j, size_t n, const std::string& path) {
    if (!j.is_array() || j.size() != n)
      fail(path, "expected an array of " + std::to_string(n) + " numbers");
    std::vector<double> v;
    for (size_t i = 0; i < n; ++i) {
      if (!j[i].is_number() || !std::isfinite(j[i].get<double>()))
        fail(path + "/" + std::to_string(i), "expected a finite number");
      v.push_back(j[i].get<double>());
    }
    return v;
  };
  if (root.contains("nodes")) {
    const auto& nodes = root["nodes"];
    if (!nodes.is_object())
      fail("/nodes", "expected an object");
    for (auto it = nodes.begin(); it != nodes.end(); ++it) {
      const std::string path = "/nodes/" + it.key();
      if (!it->is_object())
        fail(path, "expected an object");
      for (auto k = it->begin(); k != it->end(); ++k)
        if (k.key() != "offset" && k.key().rfind("x_", 0) != 0)
          fail(path + "/" + k.key(), "unknown key '" + k.key() + "'");
      if (!it->contains("offset"))
        fail(path + "/offset", "a node entry gives its offset");
      const auto o = numbers((*it)["offset"], 3, path + "/offset");
      file.nodes[it.key()] = Eigen::Vector3d(o[0], o[1], o[2]);
    }
  }
  if (!root.contains("joints"))
    return file;
  const auto& joints = root["joints"];
  if (!joints.is_object())
    fail("/joints", "expected an object");
  for (auto it = joints.begin(); it != joints.end(); ++it) {
    const std::string path = "/joints/" + it.key();
    if (!it->is_object())
      fail(path, "expected an object");
    JointPose jp;
    for (auto k = it->begin(); k != it->end(); ++k) {
      const std::string kp = path + "/" + k.key();
      if (k.key() == "rotation") {
        const auto q = numbers(*k, 4, kp);
        const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (std::abs(norm - 1) > 1e-6) {
          char text[64];
          std::snprintf(text, sizeof text, "%.9g", norm);
          fail(kp, std::string("not a unit quaternion: its norm is ") + text +
                       ", and the format asks for 1 within 1e-6 (divide the four numbers by their norm)");
        }
        jp.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
      } else if (k.key() == "translation") {
        const auto t = numbers(*k, 3, kp);
        jp.translation = {t[0], t[1], t[2]};
      } else if (k.key() == "scale") {
        const auto s = numbers(*k, 3, kp);
        jp.scale = {s[0], s[1], s[2]};
      } else if (k.key().rfind("x_", 0) != 0) {
        fail(kp, "unknown key '" + k.key() + "'");
      }
    }
    pose[it.key()] = jp;
  }
  return file;
}

Pose parse_pose(const std::string& text, const std::string& source) {
  return parse_pose_file(text, source).joints;
}

Pose read_pose(const std::string& path) {
  return read_pose_file(path).joints;
}

PoseFile read_pose_file(const std::string& path) {
  if (std::filesystem::is_directory(path))
    throw InputError(path, "", "is a folder, not a pose file");
  return parse_pose_file(detail::file_bytes(path), path); // a FIFO no one writes is refused, not waited on
}

std::vector<Mat4> skinning_matrices(const std::vector<Joint>& joints, const Pose& pose, const std::string& source) {
  std::map<std::string, int> index;
  for (size_t j = 0; j < joints.size(); ++j)
    index[joints[j].name] = static_cast<int>(j);
  for (const auto& [name, entry] : pose)
    if (!index.count(name))
      throw InputError(source, "/joints/" + name, "names joint '" + name + "', which the skeleton lacks");
  std::vector<Mat4> world(joints.size()), out(joints.size());
  for (size_t j = 0; j < joints.size(); ++j) {
    auto it = pose.find(joints[j].name);
    const Mat4 local = it == pose.end() ? Mat4::Identity() : it->second.matrix();
    if (joints[j].parent) {
      const int p = index.at(*joints[j].parent);
      world[j] = world[p] * (joints[p].bind.inverse() * joints[j].bind) * local;
    } else {
      world[j] = joints[j].bind * local;
    }
    out[j] = world[j] * joints[j].bind.inverse();
  }
  return out;
}

namespace {

/// A joint's entry from its local transform: translation, rotation, scale
/// (no shear in a joint's motion).
JointPose entry_of(const Mat4& local) {
  JointPose e;
  e.translation = local.block<3, 1>(0, 3);
  Eigen::Matrix3d m = local.block<3, 3>(0, 0);
  for (int c = 0; c < 3; ++c) {
    e.scale[c] = m.col(c).norm();
    if (e.scale[c] > 0)
      m.col(c) /= e.scale[c];
  }
  if (m.determinant() < 0) {
    e.scale[0] = -e.scale[0];
    m.col(0) = -m.col(0);
  }
  e.rotation = Eigen::Quaterniond(m).normalized();
  return e;
}

} // namespace

Pose pose_from_clip(const SkinnedMesh& file, int clip, double t) {
  const auto world = file.joint_world(clip, t);
  std::map<std::string, int> index;
  for (size_t j = 0; j < file.joints.size(); ++j)
    index[file.joints[j].name] = static_cast<int>(j);
  Pose pose;
  for (size_t j = 0; j < file.joints.size(); ++j) {
    const Joint& jt = file.joints[j];
    if (jt.parent) {
      const int p = index.at(*jt.parent);
      pose[jt.name] = entry_of((file.joints[p].bind.inverse() * jt.bind).inverse() * (world[p].inverse() * world[j]));
    } else {
      pose[jt.name] = entry_of(jt.bind.inverse() * world[j]);
    }
  }
  return pose;
}

std::pair<Eigen::Matrix3Xd, Eigen::Matrix3Xd> detail::matched_bind_positions(const std::vector<Joint>& by,
                                                                             const std::vector<Joint>& other) {
  std::map<std::string, Eigen::Vector3d> in_other;
  for (const Joint& j : other)
    in_other[j.name] = j.bind.block<3, 1>(0, 3);
  std::vector<Eigen::Vector3d> mine, theirs;
  for (const Joint& j : by)
    if (const auto it = in_other.find(j.name); it != in_other.end()) {
      mine.push_back(j.bind.block<3, 1>(0, 3));
      theirs.push_back(it->second);
    }
  Eigen::Matrix3Xd P(3, mine.size()), Q(3, theirs.size());
  for (size_t k = 0; k < mine.size(); ++k) {
    P.col(static_cast<Eigen::Index>(k)) = mine[k];
    Q.col(static_cast<Eigen::Index>(k)) = theirs[k];
  }
  return {P, Q};
}

std::optional<Mat4> detail::skeleton_similarity(const std::vector<Joint>& rig, const SkinnedMesh& clips) {
  const auto [to, from] = matched_bind_positions(rig, clips.joints);
  if (to.cols() < 3)
    return std::nullopt;
  return Mat4(Eigen::umeyama(from, to, true));
}

namespace {

/// The placing, per joint of the file, under which the file's joints lie
/// where the rig's do, or none (placed_by_armature).
std::optional<std::vector<Mat4>> armature_placing(const std::vector<Joint>& rig, const SkinnedMesh& clips) {
  // The ways the file's scene may show its joints: under its armature at
  // their binds, or at their roots' rest (a root whose rest is not its
  // bind: the T-rex's has a scale of 3 the bind has and the rest lacks).
  // Blender's importer takes the one or the other as its rest, and its
  // re-exports keep it.
  std::vector<std::vector<Mat4>> ways = clips.scene_placings();
  if (ways.empty())
    return std::nullopt;
  std::map<std::string, size_t> in_file;
  for (size_t j = 0; j < clips.joints.size(); ++j)
    in_file[clips.joints[j].name] = j;
  // The joints' places (a re-export may turn the bones' axes), within a
  // hundredth of the rig's skeleton's extent, where the placing moves the
  // file's joints by more.
  Eigen::AlignedBox3d box;
  for (const Joint& j : rig)
    box.extend(Eigen::Vector3d(j.bind.block<3, 1>(0, 3)));
  const double tol = 1e-2 * box.diagonal().norm();
  auto apart = [&](const std::vector<Mat4>* way) {
    double worst = 0;
    int matched = 0;
    for (const Joint& j : rig)
      if (const auto it = in_file.find(j.name); it != in_file.end()) {
        const Mat4& b = clips.joints[it->second].bind;
        const Eigen::Vector3d at = way ? Eigen::Vector3d(Mat4((*way)[it->second] * b).block<3, 1>(0, 3))
                                       : Eigen::Vector3d(b.block<3, 1>(0, 3));
        worst = std::max(worst, (at - j.bind.block<3, 1>(0, 3)).norm());
        ++matched;
      }
    return matched >= 2 ? worst : std::numeric_limits<double>::infinity();
  };
  if (apart(nullptr) <= tol)
    return std::nullopt;
  // A re-export may also move the whole skeleton and its mesh (Blender puts
  // the Apatosaurus's twice its root's place lower): the similarity that
  // takes the file's binds to the rig's joints places it, where its scale
  // and turn are a way's, whatever its translation, and are a scale or a
  // turn (a way that only moves the skeleton says nothing of a rig moved
  // by its user).
  if (const auto fitted = detail::skeleton_similarity(rig, clips)) {
    const Mat4& g = *fitted;
    const Eigen::Matrix3d turn = g.topLeftCorner<3, 3>();
    const bool a_ways =
        g.allFinite() && std::any_of(ways.begin(), ways.end(), [&](const std::vector<Mat4>& way) {
          return std::all_of(way.begin(), way.end(), [&](const Mat4& m) {
            const Eigen::Matrix3d w = m.topLeftCorner<3, 3>();
            return (w - turn).norm() <= 1e-2 * w.norm() && (w - Eigen::Matrix3d::Identity()).norm() > 1e-2 * w.norm();
          });
        });
    if (a_ways) {
      const std::vector<Mat4> moved(clips.joints.size(), g);
      if (apart(&moved) <= tol)
        ways.push_back(moved);
    }
  }
  // The nearer way, where both fit (they differ a little where a root's
  // rest is not quite its bind, as on the horse and the wolf).
  const std::vector<Mat4>* best = nullptr;
  double nearest = tol;
  for (const auto& way : ways)
    if (const double d = apart(&way); d <= nearest) {
      nearest = d;
      best = &way;
    }
  return best ? std::optional<std::vector<Mat4>>(*best) : std::nullopt;
}

} // namespace

bool placed_by_armature(const std::vector<Joint>& rig, const SkinnedMesh& clips) {
  return armature_placing(rig, clips).has_value();
}

namespace {

/// clip_pose_for() with the file's placing (armature_placing()) given.
Pose clip_pose_placed(const std::vector<Joint>& rig, const SkinnedMesh& clips, int clip, double t,
                      const std::optional<std::vector<Mat4>>& placing) {
  Pose all = pose_from_clip(clips, clip, t), pose;
  for (const auto& j : rig)
    if (auto it = all.find(j.name); it != all.end())
      pose.insert(*it);
  if (!placing)
    return pose;
  // The rig's mesh is the file's placed: a point p of the file's is P p on
  // it. A root of the file skins p by W(t) B^-1, so P p by
  // W(t) B^-1 P^-1, and the rig's root (bind R, whatever its bone's axes)
  // takes the entry that gives it that skinning matrix.
  const auto world = clips.joint_world(clip, t);
  std::map<std::string, const Joint*> in_rig;
  for (const Joint& j : rig)
    in_rig[j.name] = &j;
  for (size_t j = 0; j < clips.joints.size() && j < world.size(); ++j)
    if (const auto it = in_rig.find(clips.joints[j].name); !clips.joints[j].parent && it != in_rig.end()) {
      const Mat4& r = it->second->bind;
      const Mat4 placed_bind = (*placing)[j] * clips.joints[j].bind;
      pose[it->first] = entry_of(r.inverse() * world[j] * placed_bind.inverse() * r);
    }
  return pose;
}

std::vector<Mat4> clip_matrices_placed(const std::vector<Joint>& joints, const SkinnedMesh& clips, int clip, double t,
                                       const std::optional<std::vector<Mat4>>& placing) {
  // The clip's entries for the joints it shares with `joints`, by name.
  const Pose pose = clip_pose_placed(joints, clips, clip, t, placing);
  if (pose.empty() && !clips.joints.empty())
    throw InputError(clips.source, "skin", "no joint of the clip's skeleton matches a joint of the rig by name");
  return skinning_matrices(joints, pose, clips.source);
}

} // namespace

Pose clip_pose_for(const std::vector<Joint>& rig, const SkinnedMesh& clips, int clip, double t) {
  return clip_pose_placed(rig, clips, clip, t, armature_placing(rig, clips));
}

std::vector<Mat4> clip_skinning_matrices(const std::vector<Joint>& joints, const SkinnedMesh& clips, int clip,
                                         double t) {
  return clip_matrices_placed(joints, clips, clip, t, armature_placing(joints, clips));
}

ClipPoser::ClipPoser(const std::vector<Joint>& joints, const SkinnedMesh& clips)
    : joints_(joints), clips_(clips), placing_(armature_placing(joints, clips)) {}

std::vector<Mat4> ClipPoser::operator()(int clip, double t) const {
  return clip_matrices_placed(joints_, clips_, clip, t, placing_);
}

std::pair<int, int> clip_frames(const SkinnedMesh& clips, int clip, double fps) {
  const auto [t0, t1] = clips.clip_range(clip);
  const double first = std::floor(t0 * fps + 1e-9), last = std::ceil(t1 * fps - 1e-9);
  // A frame number is an int: a clip whose keys run to 1e7 s at 24 fps, or
  // 3e38 s, is refused here instead of wrapping (or sampled for hours).
  constexpr double lo = std::numeric_limits<int>::min(), hi = std::numeric_limits<int>::max();
  if (!(first >= lo && last <= hi)) {
    char text[160];
    std::snprintf(text, sizeof text,
                  "its keys run from %g to %g s: frames %.6g to %.6g at %g fps, past what a frame number holds", t0, t1,
                  first, last, fps);
    throw InputError(clips.source, "clip '" + clips.clip_names[static_cast<size_t>(clip)] + "'", text);
  }
  return {static_cast<int>(first), static_cast<int>(last)};
}

} // namespace curvenet
