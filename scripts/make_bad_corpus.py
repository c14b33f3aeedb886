#!/usr/bin/env python3
"""Writes the generated files of tests/data/bad: one fault per file, each a
small valid skinned glTF, rig, pose or PLY with that one fault put in.
Run from the repository root: /usr/bin/python3 scripts/make_bad_corpus.py"""
import base64
import json
import os
import struct

OUT = os.path.join(os.path.dirname(__file__), "..", "tests", "data", "bad")


def skinned_triangle(inverse_bind=None, joints=(0, 0, 0, 0), matrix=None, key=(0, 0, 0, 1), version="2.0"):
    """A triangle skinned to one joint, with a one-key rotation clip."""
    positions = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)
    indices = struct.pack("<3H", 0, 1, 2) + b"\0\0"
    joint_data = struct.pack("<12B", *(list(joints) * 3))
    weight_data = struct.pack("<12f", *([1, 0, 0, 0] * 3))
    ibm = struct.pack("<16f", *(inverse_bind or [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]))
    times = struct.pack("<f", 0)
    keys = struct.pack("<4f", *key)
    parts = [positions, indices, joint_data, weight_data, ibm, times, keys]
    views, offset = [], 0
    for p in parts:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(p)})
        offset += len(p)
    data = b"".join(parts)
    joint_node = {"name": "bone"}
    if matrix is not None:
        joint_node["matrix"] = matrix
    return {
        "asset": {"version": version},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0, "skin": 0}, joint_node],
        "skins": [{"joints": [1], "inverseBindMatrices": 4}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 2, "WEIGHTS_0": 3}, "indices": 1}]}],
        "buffers": [{"byteLength": len(data),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
        "bufferViews": views,
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5121, "count": 3, "type": "VEC4"},
            {"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"},
            {"bufferView": 4, "componentType": 5126, "count": 1, "type": "MAT4"},
            {"bufferView": 5, "componentType": 5126, "count": 1, "type": "SCALAR", "min": [0], "max": [0]},
            {"bufferView": 6, "componentType": 5126, "count": 1, "type": "VEC4"},
        ],
        "animations": [{"name": "turn", "samplers": [{"input": 5, "output": 6, "interpolation": "LINEAR"}],
                        "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}]}],
    }


def deep(levels):
    return "[" * levels + "]" * levels


RIG = {"format": "curvenet-rig", "version": 1,
       "nodes": [{"id": "a", "position": [0, 0.5, 0]}, {"id": "b", "position": [1, 0.5, 0]}],
       "profiles": [{"id": "p", "from": "a", "to": "b", "points": [[0, 0.5, 0], [1, 0.5, 0]]}]}


def rig(**changes):
    r = json.loads(json.dumps(RIG))
    r.update(changes)
    return r


def main():
    files = {
        "gltf_version_1.gltf": skinned_triangle(version="1.0"),
        "gltf_singular_inverse_bind.gltf": skinned_triangle(inverse_bind=[1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]),
        "gltf_inverse_bind_not_affine.gltf": skinned_triangle(inverse_bind=[1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]),
        "gltf_joint_out_of_range.gltf": skinned_triangle(joints=(7, 0, 0, 0)),
        "gltf_projective_matrix.gltf": skinned_triangle(matrix=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 2, 0, 0, 0, 1]),
        "gltf_zero_quaternion_key.gltf": skinned_triangle(key=(0, 0, 0, 0)),
        "rig_empty_skeleton.cnrig.json": rig(skeleton={"joints": []}),
        "rig_huge_bind.cnrig.json": rig(skeleton={"joints": [
            {"name": "j", "parent": None, "bind": [1e200, 0, 0, 0, 0, 1e200, 0, 0, 0, 0, 1e200, 0, 0, 0, 0, 1]}]}),
        "rig_nearly_singular_bind.cnrig.json": rig(skeleton={"joints": [
            {"name": "j", "parent": None, "bind": [1, 0, 0, 0, 0, 1e-15, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}]}),
        "rig_points_far_off.cnrig.json": rig(profiles=[
            {"id": "p", "from": "a", "to": "b", "points": [[0, 0.5, 0], [0.5, 0.5, 10], [1, 0.5, 0]]}]),
        "rig_points_1e300.cnrig.json": rig(profiles=[
            {"id": "p", "from": "a", "to": "b", "points": [[0, 0.5, 0], [0.5, 1e300, 0], [1, 0.5, 0]]}]),
        "rig_open_self_loop.cnrig.json": rig(profiles=[
            {"id": "p", "from": "a", "to": "a", "points": [[0, 0.5, 0], [0.5, 0.5, 0], [0, 0.5, 0]]}]),
    }
    for name, value in files.items():
        with open(os.path.join(OUT, name), "w") as f:
            json.dump(value, f)
    texts = {
        "rig_trailing_comma.cnrig.json": json.dumps(RIG)[:-1] + ",}",
        "rig_deep_nesting.cnrig.json": '{"format":"curvenet-rig","version":1,"nodes":' + deep(100000) + "}",
        "pose_deep_nesting.pose.json": '{"format":"curvenet-pose","version":1,"joints":' + deep(100000) + "}",
        "gltf_deep_nesting.gltf": '{"asset":{"version":"2.0"},"extras":' + deep(100000) + "}",
        "ply_fewer_faces.ply": "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                               "property float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n"
                               "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n",
    }
    for name, text in texts.items():
        with open(os.path.join(OUT, name), "w") as f:
            f.write(text)


if __name__ == "__main__":
    main()
