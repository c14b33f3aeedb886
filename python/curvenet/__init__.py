"""curvenet: topology-independent character deformation with curve networks.

A thin layer over the C++ library (see docs/python.md). Arrays go in and out
as numpy; the library's errors are raised as :class:`Error` and its kinds,
:class:`InputError` (with ``file`` and ``element``), :class:`EmbedError` and
:class:`TopologyError`.
"""

from ._curvenet import (  # noqa: F401
    Binding,
    Curve,
    CurveLayer,
    EmbedError,
    Embedding,
    Error,
    InputError,
    Joint,
    JointPose,
    Mesh,
    Node,
    Profile,
    Rig,
    SkinnedMesh,
    SkinWeights,
    StarterResult,
    TopologyError,
    TransferResult,
    animate,
    animate_poses,
    bake,
    bake_weights,
    bind,
    bind_layer,
    clip_frames,
    clip_notes,
    clip_skinning_matrices,
    compare,
    complete_weights,
    embed,
    farm_merge,
    farm_status,
    farm_submit,
    fit_weights,
    helper_matrix,
    load_mesh,
    merge_nodes,
    move_node,
    nearest_parameter,
    load_skeleton,
    load_skinned_mesh,
    parse_rig,
    pose_from_clip,
    read_pose,
    read_pose_nodes,
    read_rig,
    remove_nodes,
    remove_profiles,
    reroute_profile,
    rig_to_json,
    set_joint_weight,
    skin_positions,
    skinned_glb,
    skinning_matrices,
    training_poses,
    split_profile,
    starter,
    subdivide,
    trace_profiles,
    validate_rig,
    transfer,
    weights_csv,
    with_skeleton,
    write_file,
    write_pc2,
    write_rig,
)

__version__ = "0.1.0"


def write_weights_npz(path, weights):
    """Writes baked weights as a numpy .npz: `joint` (n, k) int (-1 unused),
    `weight` (n, k) float, `joints` (the joint names), and `helpers` (h, 2)
    int, the two rig joints of each helper joint (the last h of `joints`),
    for pipelines that paint on top. Read back with numpy.load(path)."""
    import numpy as np

    helpers = np.array(weights.helpers, dtype=np.int64).reshape(-1, 2)
    np.savez(path, joint=weights.joint, weight=weights.weight, joints=np.array(weights.joints), helpers=helpers)

# The exceptions carry the file and element at fault (empty when none).
for _cls in (Error, EmbedError, TopologyError, InputError):
    _cls.file = ""
    _cls.element = ""
del _cls
