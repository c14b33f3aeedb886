"""Type stub of the curvenet module: every signature, with what it takes and gives.

Arrays are numpy arrays. Points are (n, 3) float64, matrices (4, 4) float64
acting on column vectors (row-major in numpy, as written on paper), and
skinning matrices are M_j = G_j B_j^-1, one per joint, in the rig's
coordinates. See docs/python.md.
"""

from typing import Any, Callable, Iterable, Mapping, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int32]

class Error(RuntimeError):
    """Base of every curvenet error. `file` and `element` are empty unless an InputError."""

    file: str
    element: str

class InputError(Error):
    """A file or value breaks a rule: `file` names it, `element` the vertex, face, or JSON path at fault."""

    file: str
    element: str

class EmbedError(Error):
    """The net could not be placed on the surface; the message names the stage, profile and place."""

class TopologyError(Error):
    """A broken invariant of the cut mesh: a bug in curvenet, never a property of the input."""

class Mesh:
    """A validated polygon mesh, welded by exact position, with the map back to the input vertices."""

    def __init__(
        self,
        V: npt.ArrayLike,
        F: Union[npt.ArrayLike, Iterable[Sequence[int]]],
        source: str = "<arrays>",
    ) -> None:
        """V: (n, 3) positions. F: an (m, 3) or (m, 4) int array, or a list of polygons.

        Raises InputError (file = source) for a bad index, a degenerate face, a
        non-manifold edge or vertex, or a non-finite coordinate.
        """
    source: str
    @property
    def vertices(self) -> FloatArray:
        """(welded vertices, 3)."""
    @property
    def face_offsets(self) -> IntArray:
        """(faces + 1,): face f's corners are face_vertices[face_offsets[f]:face_offsets[f + 1]]."""
    @property
    def face_vertices(self) -> IntArray: ...
    @property
    def input_to_welded(self) -> IntArray:
        """Per input vertex, its welded vertex."""
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_faces(self) -> int: ...
    @property
    def num_input_vertices(self) -> int:
        """Vertices of the input, in its order: what deform() returns one position for."""
    notes: list[str]
    def bbox_diagonal(self) -> float: ...
    def mean_edge_length(self) -> float: ...

def load_mesh(path: str) -> Mesh:
    """Reads OBJ, glTF/GLB, PLY, OFF or FBX, validates and welds it. Raises InputError."""

class Curve:
    """A profile's shape: kind 'polyline' (points), 'bezier' (control points) or 'nurbs'."""

    def __init__(
        self,
        points: Optional[npt.ArrayLike] = None,
        kind: str = "polyline",
        degree: int = 3,
        knots: Sequence[float] = (),
        weights: Sequence[float] = (),
    ) -> None: ...
    kind: str
    points: FloatArray
    degree: int
    knots: list[float]
    weights: list[float]

class Node:
    def __init__(self, id: str, position: npt.ArrayLike) -> None: ...
    id: str
    position: FloatArray
    """(3,), a writable view into the rig."""

class Profile:
    def __init__(self, id: str, from_: str, to: str, curve: Curve = ...) -> None: ...
    id: str
    from_: str
    """The node it starts at (`from` in the rig file)."""
    to: str
    curve: Curve

class Joint:
    def __init__(self, name: str, parent: Optional[str] = None, bind: npt.ArrayLike = ...) -> None: ...
    name: str
    parent: Optional[str]
    bind: FloatArray
    """(4, 4): the joint's rest world transform, a writable view."""

class NodeList:
    """A list of Node, edited in place (append, del, index)."""
    def __getitem__(self, i: int) -> Node: ...
    def __len__(self) -> int: ...
    def append(self, node: Node) -> None: ...

class ProfileList:
    def __getitem__(self, i: int) -> Profile: ...
    def __len__(self) -> int: ...
    def append(self, profile: Profile) -> None: ...

class JointList:
    def __getitem__(self, i: int) -> Joint: ...
    def __len__(self) -> int: ...
    def append(self, joint: Joint) -> None: ...

class JointWeights:
    """joint name -> weight, edited in place."""
    def __init__(self, weights: Mapping[str, float]) -> None: ...
    def __getitem__(self, joint: str) -> float: ...
    def __setitem__(self, joint: str, weight: float) -> None: ...

class NodeWeights:
    """node id -> JointWeights, edited in place; assign a dict to set a node's weights."""
    def __init__(self, weights: Mapping[str, Mapping[str, float]]) -> None: ...
    def __getitem__(self, node: str) -> JointWeights: ...
    def __setitem__(self, node: str, weights: Union[JointWeights, Mapping[str, float]]) -> None: ...
    def __delitem__(self, node: str) -> None: ...
    def __contains__(self, node: str) -> bool: ...

class Rig:
    """The logical Curvenet, as in the rig file format (docs/rig-format.md). It holds no mesh index."""

    def __init__(self) -> None: ...
    coverage: str
    """'auto', 'full' or 'local'."""
    frame: FloatArray
    """(4, 4): maps the rig's coordinates to the mesh's object space."""
    nodes: NodeList
    profiles: ProfileList
    joints: JointList
    has_skeleton: bool
    weights: NodeWeights
    extensions: dict[str, str]
    """Top-level `x_` keys, as JSON text."""
    def node_index(self, id: str) -> int:
        """-1 when absent."""
    def node(self, id: str) -> Node:
        """The node, editable in place. Raises KeyError."""
    def profile(self, id: str) -> Profile:
        """The profile, editable in place. Raises KeyError."""
    def add_node(self, id: str, position: npt.ArrayLike) -> Node:
        """Appends a node. Raises ValueError when the id is taken."""
    def add_profile(self, id: str, from_: str, to: str, points: Optional[npt.ArrayLike] = None) -> Profile:
        """Appends a polyline profile; by default straight from node to node (points include both ends)."""
    def to_json(self) -> str: ...
    @staticmethod
    def from_json(text: str, source: str = "<string>") -> Rig: ...
    def copy(self) -> Rig: ...

def read_rig(path: str) -> Rig:
    """Reads and validates a `.cnrig.json`. Raises InputError with the JSON path, line and column."""

def write_rig(rig: Rig, path: str) -> None:
    """Writes a rig file atomically (all or nothing)."""

def parse_rig(text: str, source: str = "<string>") -> Rig: ...
def rig_to_json(rig: Rig) -> str: ...

class Embedding:
    """One rig embedded in one mesh: the cut mesh, its chains and regions."""

    @property
    def report(self) -> dict[str, Any]:
        """The same keys as `curvenet embed --report` (docs/cli.md)."""
    @property
    def ok(self) -> bool: ...
    @property
    def face_regions(self) -> IntArray:
        """Region of each cut-mesh face, -1 outside a local net."""
    @property
    def face_colours(self) -> npt.NDArray[np.uint8]:
        """(cut faces, 3) RGB preview colours; adjacent regions differ."""
    def cut_mesh(self) -> tuple[FloatArray, IntArray, IntArray]:
        """(vertices (n, 3), face_offsets (m + 1,), face_vertices): the cut mesh's polygons."""
    @property
    def chains(self) -> dict[str, FloatArray]:
        """Profile id -> its CutChain's points (k, 3), in rig order."""
    def cut_mesh_obj(self) -> str: ...
    def regions_ply(self) -> str: ...

def embed(
    mesh: Mesh,
    rig: Rig,
    *,
    density: float = 5.0,
    cage: bool = False,
    max_samples: int = 20_000_000,
    coverage: Optional[str] = None,
    progress: Optional[Callable[[str, float], None]] = None,
) -> Embedding:
    """Embeds the rig. Raises EmbedError when a profile cannot be placed, or two cross.

    A completed embedding with the wrong region count is not an error: its report's `ok` is False.
    """

def trace_profiles(mesh: Mesh, rig: Rig, *, density: float = 5.0, cage: bool = False) -> list[FloatArray]:
    """Per profile (rig order), the path on the surface its cut will follow, without cutting."""

class Binding:
    """A rig bound to a mesh. A frame is a sum over each vertex's joints: no solve, no allocation."""

    @property
    def joints(self) -> list[Joint]:
        """In mesh space, in the order skinning matrices are given."""
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def report(self) -> dict[str, Any]:
        """The library's report_to_json(BindReport): vertices, constrained, free, rigid, influences,
        mean_influences, negative_weights_*, flips, timings_ms (stage -> ms, in order), notes."""
    @property
    def node_weights(self) -> dict[str, dict[str, float]]:
        """After completion: given, or automatic."""
    @property
    def num_input_vertices(self) -> int: ...
    @property
    def has_embedding(self) -> bool: ...
    @property
    def method(self) -> str:
        """'dq', 'harmonic' or 'gradient'."""
    @property
    def embedding(self) -> Embedding: ...
    def save(self, path: str) -> None:
        """Writes a binding cache file (atomically)."""
    def deform(self, skinning: npt.ArrayLike, out: Optional[np.ndarray] = None) -> np.ndarray:
        """(J, 4, 4) skinning matrices -> (n, 3) positions, one per input vertex, in its order.

        With `out` (a C-contiguous (n, 3) float64 or float32 array) nothing is allocated.
        Exactly the positions `curvenet pose` writes.
        """
    def deform_frames(self, skinning: npt.ArrayLike) -> FloatArray:
        """(F, J, 4, 4) -> (F, n, 3), frames in parallel with the GIL released; each frame is deform()'s."""

def bind(
    mesh: Mesh,
    rig: Rig,
    *,
    laplacian: str = "intrinsic",
    rigid: str = "per-vertex",
    weight_rule: str = "blend-zone",
    blend: float = 0.3,
    density: float = 5.0,
    cache: Optional[str] = None,
    method: str = "dq",
    cut_aware: bool = True,
    rotation: str = "polar",
    curve_frames: bool = False,
    interior: str = "bone-heat",
) -> Binding:
    """Binds the rig (which needs a skeleton). laplacian: 'intrinsic' or 'uniform'; rigid: 'per-vertex' or 'horn';
    weight_rule for nodes without weights: 'blend-zone' or 'segment'. With `cache`, a binding file is reused when it
    was made for this mesh, rig and options, and written otherwise (not in the gradient mode).
    method: 'dq' (the default: the joints' rigid motions blended per vertex as dual quaternions, with the net's
    weights), 'harmonic' (the joints' matrices blended linearly) or 'gradient' (per-face gradients that turn with the
    sections, and a Poisson solve; docs/deform.md); interior: the dq mode's weights inside the regions, 'bone-heat'
    (the bones inside, corrected to the curves' weights on them) or 'harmonic' (the curves' weights extended);
    rotation: 'polar' or 'quaternion' (the gradient mode's rotation blend); curve_frames: the
    gradient mode's side frames also follow the posed curves; cut_aware=False only for comparison. Raises EmbedError, InputError."""

def complete_weights(rig: Rig, *, weight_rule: str = "blend-zone", blend: float = 0.3) -> Rig:
    """The rig with every node's weights filled in (automatic where none are given), normalised."""

class StarterResult:
    rig: Rig
    messages: list[str]
    rings: int
    joins: int
    unjoined: int
    net_components: int
    ringless: list[tuple[str, str]]
    """Joints without a ring of their own, each with the reason."""

Skeleton = Union[str, Rig, Binding, SkinnedMesh, Sequence[Joint]]
"""A skeleton file path (skinned glTF/GLB/FBX, or a rig file), or anything holding joints."""

def starter(
    mesh: Mesh,
    skeleton: Skeleton,
    *,
    nodes_per_ring: int = 4,
    rings_per_bone: int = 1,
    coverage: str = "auto",
    first_angle: float = 0.0,
    weight_rule: str = "auto",
    blend: float = 0.3,
    deforming: Optional[list[str]] = None,
    middle_nodes: bool = True,
) -> StarterResult:
    """A starter net for the skeleton (bind matrices in the mesh's object space), checked to embed.

    coverage: 'auto' (the default) makes a full net on a closed mesh and a local one on an open mesh, with a message
    saying so; 'full' or 'local' forces one.

    weight_rule: 'skin' weights each node with the skin's weights where it lies on the surface (the skeleton must be
    a SkinnedMesh, or a skinned file, of this mesh); 'blend-zone' or 'segment' by the bones; 'auto' (the default):
    the skin when the skeleton is this mesh's skin, else 'blend-zone'.

    deforming: the names of the joints that carry skin weight; by default taken from the skin when `skeleton` is a
    SkinnedMesh or a skinned file, else every joint may. Joints that deform nothing (IK poles, helpers, a root on the
    floor) are left out of the net, with the reason in `ringless`."""

class TransferResult:
    rig: Rig
    """In the target's space, with the same ids, skeleton and weights."""
    @property
    def report(self) -> dict[str, Any]:
        """The same keys as `curvenet transfer --report`."""
    @property
    def ok(self) -> bool: ...
    @property
    def agreement(self) -> float:
        """Fraction of the target's area whose region has the same identity on the source."""

def transfer(
    rig: Rig,
    source: Mesh,
    target: Mesh,
    *,
    source_frame: Optional[npt.ArrayLike] = None,
    target_frame: Optional[npt.ArrayLike] = None,
    max_offset: float = 0.05,
    source_cage_levels: int = 0,
    target_cage_levels: int = 0,
    max_faces: int = 4_000_000,
    density: float = 5.0,
    align: str = "auto",
    source_skeleton: Optional[Skeleton] = None,
    target_skeleton: Optional[Skeleton] = None,
) -> TransferResult:
    """Transfers the rig to another mesh of the same character, by logical ids only.

    The frames (4, 4) map each mesh's space to a common world (Blender: the objects' matrix_world).
    Or the meshes line up by their skins' skeletons (each a skinned file path, a SkinnedMesh or joints, in its
    mesh's space): align 'skeletons' fits the similarity that carries the source's joints onto the target's, by
    name, and refuses when they do not fit; 'auto' does so when both skeletons are given, no frame is, and they
    fit, else uses the frames (report['alignment'] says which and why); 'frames' ignores the skeletons."""

def compare(a: Mesh, b: Mesh, *, samples_per_edge: int = 4) -> dict[str, Any]:
    """Symmetric surface distance: the keys of `curvenet compare --json`."""

def subdivide(cage: Mesh, levels: int = 2, *, max_faces: int = 4_000_000) -> Mesh:
    """Catmull-Clark refinement of a control cage (OpenSubdiv)."""

class JointPose:
    """A joint's pose entry L = T R S against its rest pose."""
    def __init__(self) -> None: ...
    translation: FloatArray
    rotation: FloatArray
    """Unit quaternion (w, x, y, z)."""
    scale: FloatArray
    def matrix(self) -> FloatArray: ...

class SkinnedMesh:
    """A file's own skeleton, skin weights and clips (glTF/GLB; FBX without clips)."""
    @staticmethod
    def from_weights(
        joints: Sequence[Joint], joint: npt.ArrayLike, weight: npt.ArrayLike, source: str = "weights"
    ) -> "SkinnedMesh":
        """A skin from (n, 4) joint indices (-1 unused) and weights per vertex over `joints` (a Blender mesh's vertex
        groups, say). Raises InputError for an index past the joints or a negative weight."""
    joints: list[Joint]
    clip_names: list[str]
    source: str
    @property
    def num_clips(self) -> int: ...
    def find_clip(self, name_or_index: str) -> int:
        """-1 when there is none."""
    def clip_range(self, clip: int) -> tuple[float, float]:
        """In seconds."""
    def skinning_matrices(self, clip: int, t: float) -> FloatArray:
        """The file's own (J, 4, 4) at time t of a clip (-1: rest)."""
    @property
    def vertex_joints(self) -> IntArray:
        """(file vertices, 4), -1 where unused."""
    @property
    def vertex_weights(self) -> FloatArray: ...

def load_skinned_mesh(path: str) -> SkinnedMesh: ...
def load_skeleton(path: str) -> list[Joint]:
    """Joints of a skinned glTF/GLB/FBX, or of a rig file with a skeleton."""
def with_skeleton(rig: Rig, skeleton: Skeleton, source: str = "skeleton") -> Rig:
    """The rig with its skeleton replaced (matched to its weights by joint name). Raises InputError."""
def read_pose(path: str) -> dict[str, JointPose]: ...

PoseLike = Union[str, Mapping[str, Any]]
"""A pose file path; a pose file's dict; or joint name -> JointPose or {'rotation': (w, x, y, z),
'translation': (x, y, z), 'scale': (x, y, z)}."""

def skinning_matrices(skeleton: Skeleton, pose: PoseLike) -> FloatArray:
    """(J, 4, 4) for the skeleton's joints; joints the pose leaves out stay at rest. Raises InputError."""
def pose_from_clip(skin: SkinnedMesh, clip: int, t: float) -> dict[str, JointPose]: ...
def clip_skinning_matrices(skeleton: Skeleton, clips: SkinnedMesh, clip: int, t: float) -> FloatArray:
    """(J, 4, 4) at time t of a clip, joints matched by name. Raises InputError when none match."""
def clip_notes(skeleton: Skeleton, clips: SkinnedMesh) -> list[str]:
    """What `curvenet animate` and `curvenet bake` note of a clip file against the skeleton, one line each: the
    skeleton's joints the file lacks (matched by name; they stay at rest), and a file whose skeleton is not this one
    (a bone both have 5 % longer or shorter, or turned more than 10 degrees, against its parent): its keys would move
    the joints by other amounts or about other axes. Empty when the file fits."""
def clip_frames(clips: SkinnedMesh, clip: int, fps: float = 24.0) -> tuple[int, int]:
    """First and last whole frame of a clip at fps."""
def animate(
    binding: Binding, clips: SkinnedMesh, clip: int, path: str, *, fps: float = 24.0, frames: str = "",
    max_frames: int = 100000
) -> tuple[int, int]:
    """Writes a clip deformed through the binding as a PC2 cache, streamed in blocks: the frames `curvenet animate`
    writes. `frames` is "A:B" or "" for the clip's range. Returns (first, last). Each of `clip_notes` is a
    UserWarning, as the CLI prints it as a note. Raises InputError for a bad range, a clip none of whose joints are
    the binding's, or a non-finite position, writing nothing."""
def animate_poses(
    deformer: Union[Binding, CurveLayer], pose: Callable[[int], Any], first: int, last: int, path: str, *,
    fps: float = 24.0
) -> None:
    """Writes frames first..last as a PC2 cache, `pose(frame)` giving each frame's (J, 4, 4) skinning matrices, in
    frame order: the frame job of `animate`, in blocks of bounded memory, all or nothing (the Blender add-on's bake).
    Through a CurveLayer, `pose(frame)` may instead give (matrices, envelope, offsets or None): a keyed envelope and
    pulled nodes, each frame exactly what `CurveLayer.deform` gives. Raises what `pose` raises, or InputError for an
    envelope outside [0, 1] or a non-finite position, writing nothing."""
class CurveLayer:
    """The net as a layer over the mesh's own skin, or over its own deformation (docs/deform.md)."""

    joint_names: list[str]
    joints: list[Joint]
    num_input_vertices: int
    over_skin: bool
    binding: Binding
    """The net's own binding (its report, weights, embedding)."""
    mask: FloatArray
    """(n,): how much of the correction each input vertex takes; empty for all of it."""
    def region_mask(self, values: Mapping[str, float], others: float = 1.0, falloff: float = 0.0) -> npt.NDArray[np.float64]:
        """A mask by region, for with_mask: {region key: 0 to 1} (the keys of binding.embedding.report["region_list"],
        "profile:L|profile:R"), every other region `others`. A vertex takes the largest value of the regions
        around it. `falloff` (a fraction of the diagonal): inside a region, the value rises smoothly towards a
        larger one across its curves over that distance along the surface; beyond it, the region's value exactly.
        Raises InputError naming an unknown key or a value outside [0, 1]."""
    def with_mask(self, mask: Optional[Sequence[float]]) -> CurveLayer:
        """The same layer with another mask (one value from 0 to 1 per input vertex, or None), sharing its binding:
        nothing is solved again (a vertex group edited in Blender). Raises InputError naming a bad vertex."""
    def deform(
        self, skinning: npt.ArrayLike, *, envelope: float = 1.0, offsets: Optional[Mapping[str, npt.ArrayLike]] = None
    ) -> FloatArray:
        """(n, 3): the base (the skin, or the net) moved by skinning matrices (J, 4, 4), plus `envelope` times the
        masked correction that puts the chains on the posed curves and their nodes' `offsets` (node id -> (3,) in rest
        space). Envelope 0 is the base exactly."""
    def rest_correction(
        self, skinning: npt.ArrayLike, *, envelope: float = 1.0, offsets: Optional[Mapping[str, npt.ArrayLike]] = None
    ) -> FloatArray:
        """Over a skin: (n, 3) displacements in rest space that the skin moves to `deform`'s result, for a corrective
        shape key under Blender's Armature modifier."""

def bind_layer(
    mesh: Mesh, rig: Rig, *, skin: Optional[SkinnedMesh] = None, skinning: str = "linear",
    mask: Optional[Sequence[float]] = None, method: str = "dq"
) -> CurveLayer:
    """Binds the rig as a layer over `skin` (the mesh file's own SkinnedMesh, moved by 'linear' or 'dq' skinning with
    its weights; the rig goes on the skin's skeleton), or over the net's own deformation. `mask`: one value from 0 to
    1 per input vertex. Raises InputError naming a joint whose bind differs from the skin's."""
def read_pose_nodes(path: str) -> dict[str, FloatArray]:
    """The node offsets of a version 2 pose file: node id -> (3,) in rest space."""
def farm_submit(
    mesh: str, rig: str, clip_file: str, folder: str, *, output: str = "", obj_sequence: str = "", clip: str = "",
    frames: str = "", fps: float = 24.0, shard_frames: int = 100, skeleton: str = "", method: str = "dq",
    sbatch_options: list[str] = ..., executable: str = "", dry_run: bool = False
) -> str:
    """Writes a farm job folder (docs/farm.md) for `curvenet animate`'s inputs, to a PC2 `output` or an
    `obj_sequence` folder, in shards of `shard_frames`, and submits it to Slurm with sbatch unless `dry_run`.
    `executable` is the curvenet program the tasks run (found on PATH when empty). Returns the job folder.
    Raises InputError for bad inputs before anything is written, Error when sbatch refuses."""
def farm_merge(folder: str) -> dict[str, Any]:
    """Checks every part of a farm job and writes its output, bit for bit one `animate`: {'output', 'frames',
    'vertices', 'parts'}. Raises InputError naming every missing or damaged part with the sbatch line to rerun it."""
def farm_status(folder: str) -> list[dict[str, Any]]:
    """Each task's {'task', 'first', 'last', 'state', 'detail'}: from squeue and sacct where they answer, else its
    part file (done, damaged or missing)."""
def write_pc2(path: str, frames: npt.ArrayLike, start_frame: float = 0.0) -> None:
    """Writes (F, n, 3) positions as a PC2 point cache, all or nothing. Raises InputError for a non-finite value."""
def validate_rig(rig: Rig, source: str = "rig") -> None:
    """Checks a rig built in memory by read_rig's rules. Every call that takes a rig does it first.

    Raises InputError naming `source` and the JSON path of the fault, e.g. `/profiles/2/from`."""

# --- the net editor (docs/python.md): each returns the edited copy, validated;
# an unknown id raises InputError naming `source` and the id.

def remove_nodes(rig: Rig, nodes: Sequence[str], source: str = "rig") -> Rig:
    """The rig without these nodes, every profile through them, and their weights."""

def remove_profiles(rig: Rig, profiles: Sequence[str], source: str = "rig") -> Rig:
    """The rig without these profiles; a node they leave on no profile goes too."""

def move_node(rig: Rig, node: str, position: npt.ArrayLike, source: str = "rig") -> Rig:
    """The rig with the node moved: its curves' ends follow, the displacement fading along each curve."""

def split_profile(rig: Rig, profile: str, t: float, source: str = "rig") -> tuple[Rig, str, str]:
    """(rig, new node, new profile): a node inserted at normalised arc length t in (0, 1).

    The profile keeps its id and ends at the new node; the new profile continues to the old end.
    Weighted ends give the new node their weights interpolated at t, so the deformation stays."""

def nearest_parameter(rig: Rig, profile: str, point: npt.ArrayLike, source: str = "rig") -> float:
    """The normalised arc length of the profile's point nearest to `point` (for a split at a click)."""

def merge_nodes(rig: Rig, kept: str, merged: str, source: str = "rig") -> Rig:
    """The rig with `merged` merged into `kept`: profiles between them go, the others end at `kept`."""

def reroute_profile(rig: Rig, profile: str, via: npt.ArrayLike, source: str = "rig") -> Rig:
    """The rig with the profile's curve running from its first node through `via` (k, 3) to its last."""

def set_joint_weight(rig: Rig, nodes: Sequence[str], joint: str, weight: float, source: str = "rig") -> Rig:
    """The rig with `joint`'s weight set to `weight` on each node, the node's other joints scaled to sum to 1.

    A node without weights starts from its automatic ones."""

class SkinWeights:
    """A linear-blend skin: `influences` (joint, weight) slots per input vertex, largest first."""

    def __init__(
        self, joints: Sequence[str], joint: npt.ArrayLike, weight: npt.ArrayLike,
        helpers: Sequence[tuple[int, int]] = ()
    ) -> None:
        """joint: (n, k) indices into `joints` (-1 unused); weight: (n, k), non-negative; helpers: the last
        len(helpers) of `joints` are helper joints, each half way between these two rig joints."""
    influences: int
    joints: list[str]
    helpers: list[tuple[int, int]]
    """Helper joints, after the rig's in `joints`: each half way between these two rig joints (bake --helpers)."""
    @property
    def rig_joints(self) -> int:
        """Joints of the rig; the helpers follow them in `joints`."""
    @property
    def num_vertices(self) -> int: ...
    @property
    def joint(self) -> IntArray:
        """(n, k), -1 for an unused slot."""
    @property
    def weight(self) -> FloatArray:
        """(n, k); each row sums to 1."""

def bake(
    mesh: str, rig: str, *, output: str = "", weights_csv: str = "", clip_file: str = "",
    clip_names: Sequence[str] = (), fit: str = "", weights: str = "harmonic", max_influences: int = 4,
    fps: float = 24.0, max_frames: int = 100000, up: str = "y", skeleton: str = "", method: str = "dq",
    interior: str = "bone-heat", over_skin: bool = False, skinning: str = "linear", envelope: float = 1.0,
    mask: str = "", helpers: int = 0
) -> dict[str, Any]:
    """The job `curvenet bake` runs, from files to files, all or nothing: the GLB at `output` and/or the CSV at
    `weights_csv` (bit for bit the CLI's), and what the CLI prints: 'notes' (a clip or fit file of another skeleton
    among them), 'vertices', 'bind' (the bind report), 'joints', 'influences', 'mean_joints', 'most_joints', 'clips',
    'training_poses', and with a clip file 'fidelity': per carried clip, worst first, a dict of 'clip', 'index',
    'frames', 'mean', 'max', 'worst_vertex', 'worst_rest', 'worst_joint', 'worst_time', 'worst_floor' and
    'worst_joints' (distances as fractions of the diagonal; docs/bake.md, "What bake reports"). `over_skin`,
    `skinning`, `envelope` and `mask` are the CLI's layer options (with `fit`); `helpers` is `--helpers` (up to that
    many helper joints, with fitted weights; 'helpers' in the dict counts those written, 'helper_joints' names them). Raises InputError for bad
    input, writing nothing."""
def bake_weights(binding: Binding, max_influences: int = 4) -> SkinWeights:
    """The k largest harmonic weights s_j of each input vertex, renormalised (docs/bake.md)."""

def fit_weights(binding: Binding, poses: npt.ArrayLike, max_influences: int = 4, helpers: int = 0) -> SkinWeights:
    """Weights fitted to the binding's own deformation over poses (P, J, 4, 4): least squares per vertex,
    non-negative, summing to 1, on the joints that bound the vertex's region; with `helpers`, also on up to that
    many helper joints, each half way between two joints (SkinWeights.helpers, docs/bake.md)."""

def training_poses(
    binding: Binding,
    bends: Sequence[float] = [10.0, 20.0],
    twist: float = 10.0,
    random_poses: int = 48,
    random_bend: float = 15.0,
    random_twist: float = 10.0,
    seed: int = 1,
) -> FloatArray:
    """Poses of the binding's skeleton alone, (P, J, 4, 4) skinning matrices, for fit_weights without clips:
    each joint bent alone by `bends` degrees both ways about both axes across its bone and twisted both ways by
    `twist`, then `random_poses` poses of every joint at once (up to `random_bend` and `random_twist` degrees,
    from `seed`). What `curvenet bake --weights fitted` fits over."""

def skin_positions(weights: SkinWeights, rest: npt.ArrayLike, skinning: npt.ArrayLike) -> FloatArray:
    """Linear blend skinning: rest (n, 3) moved by skinning (J, 4, 4) with the weights; J is every joint of the
    weights, or their rig joints alone, each helper's matrix then the dual-quaternion mean of its two joints'."""

def helper_matrix(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """A helper joint's skinning matrix (4, 4): the dual-quaternion mean of two joints' skinning matrices."""

def weights_csv(weights: SkinWeights) -> str:
    """The weights as CSV: `vertex,joint_0,weight_0,...`, joints by name."""

def skinned_glb(
    mesh_path: str,
    skeleton: Skeleton,
    weights: SkinWeights,
    clips: Optional[SkinnedMesh] = None,
    *,
    up: str = "y",
    fps: float = 24.0,
    clip_names: Sequence[str] = (),
) -> bytes:
    """A skinned glTF 2.0 binary of the mesh file: its topology, UVs, normals (and a glTF source's materials),
    the skeleton with inverse bind matrices, JOINTS/WEIGHTS, and the clips retargeted by joint name.
    up: the source's up axis ('z' is turned to glTF's Y-up)."""

def write_file(path: str, data: bytes) -> None:
    """Writes bytes atomically (all or nothing)."""

def write_weights_npz(path: str, weights: SkinWeights) -> None:
    """Writes `joint`, `weight` and `joints` arrays to a numpy .npz."""
