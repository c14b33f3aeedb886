"""curvenet: topology-independent character deformation with curve networks.

A thin layer over the C++ library (see docs/python.md). Arrays go in and out
as numpy; the library's errors are raised as :class:`Error` and its kinds,
:class:`InputError` (with ``file`` and ``element``), :class:`EmbedError` and
:class:`TopologyError`.
"""

from ._curvenet import (  # noqa: F401
    Binding,
    Curve,
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
    StarterResult,
    TopologyError,
    TransferResult,
    bind,
    clip_frames,
    clip_skinning_matrices,
    compare,
    complete_weights,
    embed,
    load_mesh,
    load_skeleton,
    load_skinned_mesh,
    parse_rig,
    pose_from_clip,
    read_pose,
    read_rig,
    rig_to_json,
    skinning_matrices,
    starter,
    subdivide,
    trace_profiles,
    validate_rig,
    transfer,
    with_skeleton,
    write_pc2,
    write_rig,
)

__version__ = "0.1.0"

# The exceptions carry the file and element at fault (empty when none).
for _cls in (Error, EmbedError, TopologyError, InputError):
    _cls.file = ""
    _cls.element = ""
del _cls
