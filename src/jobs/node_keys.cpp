// Node offsets keyed over the frames of an animation (docs/rig-format.md).

#include "curvenet/errors.hpp"
#include "curvenet/jobs.hpp"
#include "io/file_bytes.hpp"
#include "io/json_text.hpp"

#include <cmath>

namespace curvenet {

NodeOffsets NodeKeys::at(double frame) const {
  NodeOffsets out;
  for (const auto& [id, keys] : nodes) {
    if (keys.empty())
      continue;
    if (frame <= keys.front().first) {
      out[id] = keys.front().second;
      continue;
    }
    if (frame >= keys.back().first) {
      out[id] = keys.back().second;
      continue;
    }
    size_t k = 1;
    while (keys[k].first < frame)
      ++k;
    const auto& [f0, o0] = keys[k - 1];
    const auto& [f1, o1] = keys[k];
    const double t = (frame - f0) / (f1 - f0);
    out[id] = (1 - t) * o0 + t * o1;
  }
  return out;
}

NodeKeys parse_node_keys(const std::string& text, const std::string& source) {
  const nlohmann::ordered_json root = detail::parse_json(text, source);
  auto fail = [&](const std::string& path, const std::string& msg) { throw InputError(source, path, msg); };
  if (!root.is_object())
    fail("/", "expected an object");
  if (!root.contains("format") || root["format"] != "curvenet-node-keys")
    fail("/format", "must be \"curvenet-node-keys\"");
  if (!root.contains("version"))
    fail("/version", "only version 1 is supported");
  detail::json_integer(root["version"], source, "/version", 1, 1);
  for (auto it = root.begin(); it != root.end(); ++it)
    if (it.key() != "format" && it.key() != "version" && it.key() != "nodes" && it.key().rfind("x_", 0) != 0)
      fail("/" + it.key(), "unknown key '" + it.key() + "'");
  NodeKeys keys;
  if (!root.contains("nodes"))
    return keys;
  const auto& nodes = root["nodes"];
  if (!nodes.is_object())
    fail("/nodes", "expected an object");
  auto number = [&](const nlohmann::ordered_json& j, const std::string& path) {
    if (!j.is_number() || !std::isfinite(j.get<double>()))
      fail(path, "expected a finite number");
    return j.get<double>();
  };
  for (auto it = nodes.begin(); it != nodes.end(); ++it) {
    const std::string path = "/nodes/" + it.key();
    if (!it->is_array() || it->empty())
      fail(path, "expected an array of keys, {\"frame\": F, \"offset\": [x, y, z]}");
    auto& list = keys.nodes[it.key()];
    for (size_t k = 0; k < it->size(); ++k) {
      const std::string kp = path + "/" + std::to_string(k);
      const auto& key = (*it)[k];
      if (!key.is_object() || !key.contains("frame") || !key.contains("offset"))
        fail(kp, "expected {\"frame\": F, \"offset\": [x, y, z]}");
      for (auto f = key.begin(); f != key.end(); ++f)
        if (f.key() != "frame" && f.key() != "offset" && f.key().rfind("x_", 0) != 0)
          fail(kp + "/" + f.key(), "unknown key '" + f.key() + "'");
      const double frame = number(key["frame"], kp + "/frame");
      const auto& o = key["offset"];
      if (!o.is_array() || o.size() != 3)
        fail(kp + "/offset", "expected an array of 3 numbers");
      const Vec3 offset(number(o[0], kp + "/offset/0"), number(o[1], kp + "/offset/1"), number(o[2], kp + "/offset/2"));
      if (!list.empty() && frame <= list.back().first)
        fail(kp + "/frame", "the keys' frames must increase");
      list.emplace_back(frame, offset);
    }
  }
  return keys;
}

NodeKeys read_node_keys(const std::string& path) {
  return parse_node_keys(detail::file_bytes(path), path);
}

} // namespace curvenet
