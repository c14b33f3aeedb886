#pragma once
// The starter net's stages (docs/starter.md), each a function with its own
// options and result, run in order by make_starter (starter.cpp):
//
//   rings     (rings.cpp)     a candidate ring local to each joint's bone
//   trunks    (rings.cpp)     one ring across a trunk that several joints share
//   clearance (rings.cpp)     keep rings smallest first, moving or dropping those too close
//   chains    (rings.cpp)     each ring's parent ring, and its nodes at consistent angles
//   net       (net.cpp)       arcs, profiles along chains, joins on both sides of a fork
//   check     (net.cpp)       clearances and angles between profiles, and the embedding
//   weights   (starter.cpp)   automatic weights on every node

#include "core/plane_section.hpp"
#include "curvenet/embed.hpp"
#include "curvenet/rig.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/surface_mesh.hpp"

#include <functional>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace curvenet::detail {

struct Skeleton {
  std::vector<Vec3> origin;
  std::vector<int> parent;
  std::vector<std::vector<int>> kids;
  std::vector<Eigen::Matrix3d> rotation;
  std::vector<int> subtree; ///< joints in the subtree, the joint included
  explicit Skeleton(const std::vector<Joint>& joints);
};

/// Where a ring may sit: the plane through base + t * step, with normal
/// `along` (or `start_axis` at t = 0), for t in [t_min, t_max]. Moving a ring
/// along its bone raises t.
struct Placement {
  Vec3 base = Vec3::Zero(), step = Vec3::Zero();
  Vec3 along = Vec3::UnitZ(), start_axis = Vec3::UnitZ();
  double t_min = 0, t_max = 0;
  [[nodiscard]] Vec3 point(double t) const { return base + t * step; }
  [[nodiscard]] Vec3 axis(double t) const { return t == 0 ? start_axis : along; }
};

/// A ring: a closed section around a limb (or around several, a trunk).
struct Ring {
  std::string id;
  int joint = -1;       ///< the joint it belongs to
  double frac = 1;      ///< its order among the rings of `joint` (1: the joint's own ring; 0: a shared trunk's)
  std::vector<int> own; ///< the joints whose bones it may enclose: `joint`, or a trunk's joints
  Placement place;
  double t = 0; ///< where in `place` it sits
  Vec3 centre = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ(); ///< the plane's normal, along the bone
  std::vector<Vec3> loop;    ///< counter-clockwise about `axis`
  std::vector<double> at;    ///< arc length of each loop point
  double perimeter = 0;
  int replaced_by = -1; ///< dropped: the ring that stands for it
  bool active = false;
  Vec3 ref = Vec3::Zero();        ///< direction of node 0 from the centre
  std::vector<double> base_nodes; ///< arc-length positions of nodes 0..N-1
  [[nodiscard]] double radius() const { return perimeter / (2 * std::numbers::pi); }
};

/// What every stage reads: the mesh, its sections, the skeleton, the scale,
/// and where to say what was moved or dropped. What a stage is asked to do
/// comes in its own options (RingOptions, NetOptions, NodeWeightOptions).
struct StarterContext {
  const SurfaceMesh& mesh;
  const std::vector<Joint>& joints;
  Skeleton sk;
  SectionMesh sm;
  double diag = 1, h = 1, tol = 1e-6;
  std::function<void(const std::string&)> say;
  /// The mesh's vertex neighbours (compressed rows), for paths along edges.
  std::vector<int> next_offset, next_vertex;
  /// Paths along the surface found so far, by their ends and third points:
  /// the net is built again after each repair, mostly between the same nodes.
  mutable std::map<std::vector<double>, std::vector<std::vector<Vec3>>> path_cache;
  StarterContext(const SurfaceMesh& m, const std::vector<Joint>& j, std::function<void(const std::string&)> message);
  [[nodiscard]] std::string bone_name(int c) const;
};

/// The ring stages (1 to 4) and the repairs that move rings.
struct RingOptions {
  /// Nodes on each ring; a section that crosses fewer mesh edges is no ring.
  int nodes_per_ring = 4;
  /// One ring at each bone's end joint, and rings_per_bone - 1 more along it.
  int rings_per_bone = 1;
  /// Node 0's angle from its ring's reference direction, in degrees.
  double first_angle_deg = 0;
  /// Rings closer than this fraction of the smaller one's radius are too close.
  double ring_gap = 0.25;
  /// A shared trunk's ring sits back from the fork by this fraction of the
  /// bones (the weight rule's blend zone, so that it blends as they do).
  double trunk_setback = 0.3;
  /// The joints that carry skin weight (empty: every joint may): a leaf that
  /// carries weight and ends its limb gets a ring out beyond it too.
  std::set<std::string> deforming;
  [[nodiscard]] static RingOptions from(const StarterOptions& o);
  /// How close rings a and b may come.
  [[nodiscard]] double gap(const Ring& a, const Ring& b) const;
};

/// The net and its check (stages 5 and 6).
struct NetOptions {
  int nodes_per_ring = 4;
  bool middle_nodes = true; ///< StarterOptions::middle_nodes
  /// The smallest ring (radius, as a fraction of the diagonal) whose arcs get middle nodes.
  double arc_middle_radius = 0.02;
  /// A join's new node keeps this fraction of its ring's radius from the
  /// ring's own nodes; profiles that share no node keep half of it.
  double ring_gap = 0.25;
  Coverage coverage = Coverage::Full;
  [[nodiscard]] static NetOptions from(const StarterOptions& o);
  /// Profiles that share no node keep half the ring gap of the limb they are
  /// on (radius), and at most 0.75 % of the diagonal on a thick body.
  [[nodiscard]] double profile_clearance(double diagonal, double radius) const;
};

/// The node weights (stage 8).
struct NodeWeightOptions {
  AutoWeightOptions rule;            ///< where there is no skin, or it names no joint of the skeleton
  const SkinnedMesh* skin = nullptr; ///< the mesh's own skin (StarterOptions::skin)
  std::set<std::string> deforming;   ///< as RingOptions::deforming
  [[nodiscard]] static NodeWeightOptions from(const StarterOptions& o);
};

// ---- loops --------------------------------------------------------------

Vec3 loop_point(const Ring& r, double s);
/// The loop between arc positions s0 and s1 (going forward), ends included.
std::vector<Vec3> loop_between(const Ring& r, double s0, double s1);
/// Arc-length position of the loop point closest to p.
double closest_on_loop(const Ring& r, const Vec3& p, double* distance = nullptr);
/// The smallest closed section of the plane (point, axis) that winds around
/// `point`, as a ring: counter-clockwise about the axis, with its area
/// centroid and arc lengths.
std::optional<Ring> section_ring(const SectionMesh& sm, const Vec3& point, const Vec3& axis);
/// Nodes at angles 2 pi k / N about the axis from r.ref; spread by arc
/// length when the rays do not meet the loop in order (returns false then).
bool place_nodes(Ring& r, int N, double first_angle_deg);
std::string percent(double t);

// ---- stage 1: rings -----------------------------------------------------

/// A joint's section through the joint, where it is not local: where its
/// bones meet other joints', for the shared trunks.
struct SharedStart {
  Vec3 point, axis;
  double radius;
  std::vector<int> inside; ///< bones (by child joint) through the section
};

struct RingsResult {
  std::vector<Ring> rings;
  std::map<int, std::string> ringless; ///< joint -> why it has no ring
  std::map<int, SharedStart> shared_start;
};

/// A candidate ring local to each joint's bone (and rings_per_bone - 1
/// more along each bone).
RingsResult candidate_rings(const StarterContext& c, const RingOptions& ro);

/// Whether a ring at t of its placement is local, and if so, the ring there.
bool place_ring_at(const StarterContext& c, const RingOptions& ro, Ring& r, double t);

// ---- stage 2: trunks ------------------------------------------------------

/// Rings across trunks that several joints share (the knuckles of a palm):
/// appended to `rings`.
void trunk_rings(const StarterContext& c, const RingOptions& ro, const std::map<int, SharedStart>& shared_start,
                 std::vector<Ring>& rings);

// ---- stage 3: clearance ---------------------------------------------------

/// Keeps rings greedily, smallest first; a ring too close to one already
/// kept is moved along its bone, and dropped only when that does not clear
/// it. Sets `active` and `replaced_by`; returns the kept rings.
std::vector<int> keep_clear_rings(const StarterContext& c, const RingOptions& ro, std::vector<Ring>& rings,
                                  std::map<int, std::string>& ringless);

/// The first ring of `among` (but `self`) that `r` comes too close to, or -1.
int ring_conflict(const StarterContext& c, const RingOptions& ro, const Ring& r, const std::vector<Ring>& rings,
                  const std::vector<int>& among, int self);

/// Moves a ring a tenth of its range's bone further along, to the next local section.
bool move_ring_on(const StarterContext& c, const RingOptions& ro, Ring& r);

// ---- stage 4: chains ------------------------------------------------------

/// Each kept ring's parent ring (the ring at the nearest position up the
/// skeleton), and its nodes, node 0 carried from the parent.
std::map<int, int> chain_rings(const StarterContext& c, const RingOptions& ro, std::vector<Ring>& rings,
                               const std::vector<int>& kept);

// ---- stages 5 and 6: the net and its check -------------------------------

/// How far each branch join has been given up: per 2 * child ring + slot,
/// 0 a new node on the parent ring where it comes nearest, 1 the parent's
/// nearest node, 2 and 3 a new node in the middle of the parent's nearest
/// and second-nearest arcs, kJoinTries none.
using JoinAttempts = std::map<int, int>;
inline constexpr int kJoinTries = 4;
/// Per longitudinal profile, how many of its surface paths (the plane
/// sections between its nodes, best first) were given up.
using PathSkips = std::map<std::string, int>;
inline constexpr int kPathTries = 3;

struct NetResult {
  Rig rig;
  /// profile -> (kind: 'a' arc, 'l' longitudinal, 'j' join; ring, or 2 * child ring + slot for a join)
  std::map<std::string, std::pair<char, int>> owner;
  std::map<std::string, double> scale; ///< profile -> the radius of the limb it is on
  std::vector<int> unjoined;           ///< child rings with no join left
  /// Per node of `rig`, the ring it lies on (the middle of a profile along
  /// a chain: the chain's child ring), and whether it is such a middle.
  std::vector<int> node_ring;
  std::vector<char> node_middle;
  int joins = 0;
  std::string failure; ///< the first reason the net cannot be used, or empty
};

/// The net of the active rings: their arcs, N profiles along each chain,
/// and joins on both sides of each fork.
NetResult build_net(const StarterContext& c, const NetOptions& no, const std::vector<Ring>& rings,
                    const std::vector<int>& active, const std::function<int(int)>& parent_of,
                    const JoinAttempts& attempts, const PathSkips& skips = {});

/// Profiles that share no node keep their clearance, profiles leaving one
/// node part at a clear angle. The first fault, or empty.
std::string check_net(const StarterContext& c, const NetOptions& no, const NetResult& net);

/// Each profile along a bone and each arc of a ring, at least as long as
/// its limb's radius, split in two at half its length by a node of its own
/// (`<profile>_mid`, the halves `<profile>_a` and `<profile>_b`): the
/// curve's weights are interpolated along each profile between its end
/// nodes, so without it the middle of a bone blends the joints at both
/// ends, and the middle of an arc the weights of two sides of the limb.
/// Arcs only on rings of radius `NetOptions::arc_middle_radius` of the
/// diagonal or more: an ear's eight nodes on a few faces of a coarse
/// decimation fold.
void split_profiles_at_middle(const StarterContext& c, const NetOptions& no, NetResult& net);

// ---- stage 7: repairs ----------------------------------------------------

/// What the repairs have changed so far: the rings dropped, the joins moved
/// or given up, and the parents that chains join instead of their own.
struct NetRepairs {
  std::vector<int> kept;          ///< the rings clearance kept
  std::map<int, int> parent_ring; ///< chain_rings()
  std::set<int> dropped;
  JoinAttempts join_attempt;
  PathSkips path_skip;
  int path_retries = 0; ///< paths given up so far, on every ring
  std::map<int, std::string> join_failure; ///< child ring -> why its last join was given up
  std::map<int, int> parent_override;      ///< child ring -> the ring it joins instead of its own parent
  std::map<int, std::set<int>> tried;      ///< child ring -> the parents whose joins were given up
  int attempts = 0;
  /// The kept rings not dropped.
  [[nodiscard]] std::vector<int> active() const;
  /// The ring that ring i's chain joins: its override, or its parent, past dropped rings.
  [[nodiscard]] int effective_parent(int i) const;
};

/// Gives up what `failure` (why `net` cannot be used) names, cheapest
/// first: a join (moved to a node, to an arc's middle, then to another
/// ring up the chain), the child ring of a longitudinal, the ring of an arc,
/// a trunk's ring last; with no profile named, the largest ring. A ring is
/// moved along its bone where it keeps clear, dropped otherwise, and rings
/// it had displaced come back.
/// \throw EmbedError when nothing is left to give up.
void repair_net(const StarterContext& c, const RingOptions& ro, std::vector<Ring>& rings,
                std::map<int, std::string>& ringless, const NetResult& net, const std::string& failure,
                NetRepairs& state);

// ---- stage 8: weights -----------------------------------------------------

/// Each node's weights. With the mesh's own skin (StarterOptions::skin):
/// the skin's where the node lies on the surface (`embedding`'s node
/// vertex). Otherwise, or where the skin names no joint of the skeleton,
/// by the weight rule on the bone its ring's centre lies nearest to, of
/// those near its ring's joints (that meet at them, at their parents or at
/// their children): a node follows the limb it lies on, whatever passes
/// near it. A ring out beyond a weighted joint that ends its chain (a
/// foot, a head) is that joint's alone, as is the joint's own ring when
/// that ring is the last.
void node_weights(const StarterContext& c, const NodeWeightOptions& wo, const std::vector<Ring>& rings,
                  const std::vector<int>& active, const Embedding& embedding, const std::vector<Joint>& rig_joints,
                  NetResult& net);

} // namespace curvenet::detail
