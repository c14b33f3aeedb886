#include "trace/trace_mesh.hpp"

#include "core/polygon.hpp"
#include "core/predicates.hpp"
#include "core/tolerances.hpp"
#include "curvenet/errors.hpp"

#include <embree3/rtcore.h>

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace curvenet::detail {

struct TraceMesh::Bvh {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  double slack = 0;
  // Embree works in single precision: its vertices are the mesh's moved to
  // the origin and divided by its size, so a mesh at 1e30 or 1e-30 builds
  // the same tree (squares of 1e30 overflow a float).
  Vec3 centre = Vec3::Zero();
  double scale = 1;
  [[nodiscard]] Vec3 to_unit(const Vec3& p) const { return (p - centre) / scale; }
  ~Bvh() {
    if (scene)
      rtcReleaseScene(scene);
    if (device)
      rtcReleaseDevice(device);
  }
};

namespace {
struct QueryData {
  const TraceMesh* mesh;
  Vec3 q;
  double best = std::numeric_limits<double>::infinity();
  int tri = -1;
  TriClosest hit{Vec3::Zero(), {0, 0, 0}};
  double slack = 0; ///< in Embree's units
  double scale = 1; ///< mesh units per Embree unit
};

/// Triangle t as a candidate of the query: kept when nearer (or as near and
/// lower in index), and then the search radius shrinks to it.
bool point_query_triangle(QueryData& d, int t, float& radius) {
  const auto& c = d.mesh->tri(t);
  const TriClosest r = closest_on_triangle(d.q, d.mesh->position(c[0]), d.mesh->position(c[1]), d.mesh->position(c[2]));
  const double dist = (r.point - d.q).norm();
  if (dist < d.best || (dist == d.best && t < d.tri)) {
    d.best = dist;
    d.tri = t;
    d.hit = r;
    // Embree's boxes are in float: keep a little slack so no closer triangle is culled.
    radius = static_cast<float>(dist / d.scale + d.slack);
    return true;
  }
  return false;
}

bool point_query(RTCPointQueryFunctionArguments* args) {
  return point_query_triangle(*static_cast<QueryData*>(args->userPtr), static_cast<int>(args->primID),
                              args->query->radius);
}
} // namespace

TraceMesh::TraceMesh(const SurfaceMesh& mesh, const CutMesh& cut)
    : mesh_(mesh), mean_edge_length_(mesh.mean_edge_length()) {
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(2 * static_cast<size_t>(cut.num_edges()));
  edge_ends_.reserve(cut.num_edges());
  for (int e = 0; e < cut.num_edges(); ++e) {
    edge_ends_.push_back({cut.from(Halfedge(2 * e)).idx, cut.to(Halfedge(2 * e)).idx});
    pairs.emplace_back(edge_ends_[e][0], e);
    pairs.emplace_back(edge_ends_[e][1], e);
  }
  vertex_edges_ = Adjacency::build(mesh.num_vertices(), pairs);
  // A triangle per corner beyond the second: reserved once.
  const size_t triangles = mesh.face_vertices.size() - 2 * static_cast<size_t>(mesh.num_faces());
  tri_.reserve(triangles);
  tri_face_.reserve(triangles);
  side_edge_.reserve(triangles);
  nbr_.reserve(triangles);
  // A face's diagonals pair up within that face: (a, b) -> (tri, side).
  std::vector<std::pair<std::pair<int, int>, std::pair<int, int>>> diagonal;
  std::vector<int> corner, edge;
  std::vector<Vec3> pts;
  std::vector<Halfedge> loop;
  std::vector<std::array<int, 3>> tris;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    cut.face_loop(Face(f), loop);
    const int n = static_cast<int>(loop.size());
    corner.resize(n);
    edge.resize(n);
    pts.resize(n);
    for (int i = 0; i < n; ++i) {
      corner[i] = cut.from(loop[i]).idx;
      edge[i] = cut.edge_origin(loop[i]);
      pts[i] = mesh.positions[corner[i]];
    }
    diagonal.clear();
    triangulate_polygon(pts, tris); // polygon-local corner indices
    for (const auto& lt : tris) {
      const int t = static_cast<int>(tri_.size());
      tri_.push_back({corner[lt[0]], corner[lt[1]], corner[lt[2]]});
      tri_face_.push_back(f);
      std::array<int, 3> se{};
      for (int k = 0; k < 3; ++k) {
        const int i = lt[k], j = lt[(k + 1) % 3];
        se[k] = (j == (i + 1) % n) ? edge[i] : -1;
      }
      side_edge_.push_back(se);
      nbr_.push_back({-1, -1, -1});
      for (int k = 0; k < 3; ++k) {
        if (se[k] < 0) {
          const int a = tri_[t][k], b = tri_[t][(k + 1) % 3];
          const auto key = std::make_pair(std::min(a, b), std::max(a, b));
          auto it = std::find_if(diagonal.begin(), diagonal.end(), [&](const auto& d) { return d.first == key; });
          if (it == diagonal.end()) {
            diagonal.push_back({key, {t, k}});
          } else {
            nbr_[t][k] = it->second.first;
            nbr_[it->second.first][it->second.second] = t;
            diagonal.erase(it);
          }
        }
      }
    }
  }
  pairs.clear();
  for (int t = 0; t < num_triangles(); ++t)
    for (int k = 0; k < 3; ++k)
      pairs.emplace_back(tri_[t][k], t);
  vertex_tris_ = Adjacency::build(mesh.num_vertices(), pairs);
  pairs.clear();
  for (int t = 0; t < num_triangles(); ++t)
    for (int k = 0; k < 3; ++k)
      if (side_edge_[t][k] >= 0)
        pairs.emplace_back(side_edge_[t][k], t);
  edge_tris_ = Adjacency::build(cut.num_edges(), pairs);
  for (int t = 0; t < num_triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int e = side_edge_[t][k];
      if (e < 0)
        continue;
      for (int o : edge_tris_[e])
        if (o != t)
          nbr_[t][k] = o;
    }

  // Embree BVH over the triangles, for closest-point queries.
  bvh_ = std::make_unique<Bvh>();
  // No thread count in the configuration: Embree built on TBB (Debian's)
  // turns "threads=N" into a process-wide tbb::global_control that holds
  // every TBB loop of the process to N threads for as long as the device
  // lives, which was the whole of each embed, bind and transfer. The build
  // is kept on one thread by the arena below instead.
  bvh_->device = rtcNewDevice(nullptr);
  if (!bvh_->device)
    throw Error("Embree: cannot create a device");
  bvh_->scene = rtcNewScene(bvh_->device);
  RTCGeometry geom = rtcNewGeometry(bvh_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                         3 * sizeof(float), mesh.positions.size()));
  {
    Vec3 lo = mesh.positions.empty() ? Vec3::Zero() : mesh.positions[0], hi = lo;
    for (const auto& p : mesh.positions) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    bvh_->centre = (lo + hi) / 2;
    const double size = (hi - lo).norm();
    bvh_->scale = size > 0 && std::isfinite(size) ? size : 1.0;
  }
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    const Vec3 u = bvh_->to_unit(mesh.positions[v]);
    for (int k = 0; k < 3; ++k)
      vb[3 * v + k] = static_cast<float>(u[k]);
  }
  bvh_->slack = 1e-6; // the unit box: coordinates within 1 of the origin
  auto* ib = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), tri_.size()));
  for (size_t t = 0; t < tri_.size(); ++t)
    for (int k = 0; k < 3; ++k)
      ib[3 * t + k] = static_cast<unsigned>(tri_[t][k]);
  rtcSetGeometryPointQueryFunction(geom, point_query);
  // Robust: rays do not slip between triangles. Built once per embed and
  // queried a few thousand times, so the quick (Morton) build pays: a third
  // of the time of a build that was a quarter of a 150k-face embed, and the
  // queries were not slower.
  rtcSetSceneFlags(bvh_->scene, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_COMPACT);
  rtcSetSceneBuildQuality(bvh_->scene, RTC_BUILD_QUALITY_LOW);
  rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_LOW);
  rtcCommitGeometry(geom);
  rtcAttachGeometry(bvh_->scene, geom);
  rtcReleaseGeometry(geom);
  // On one thread, so that the tree, and with it the order in which
  // queries meet tied triangles, does not depend on the thread count.
  tbb::task_arena one(1);
  one.execute([&] { rtcCommitScene(bvh_->scene); });
}

TraceMesh::~TraceMesh() = default;

Vec3 TraceMesh::tri_normal(int t) const {
  const auto& c = tri_[t];
  return (position(c[1]) - position(c[0])).cross(position(c[2]) - position(c[0])).normalized();
}

Adjacency Adjacency::build(int keys, const std::vector<std::pair<int, int>>& pairs) {
  Adjacency a;
  a.offset_.assign(static_cast<size_t>(keys) + 1, 0);
  for (const auto& [k, v] : pairs)
    ++a.offset_[k + 1];
  for (int k = 0; k < keys; ++k)
    a.offset_[k + 1] += a.offset_[k];
  a.items_.resize(pairs.size());
  std::vector<int> fill(a.offset_.begin(), a.offset_.end() - 1);
  for (const auto& [k, v] : pairs)
    a.items_[fill[k]++] = v;
  return a;
}

double TraceMesh::edge_length(int t) const {
  const auto& c = tri_[t];
  double sum = 0, all = 0;
  int n = 0;
  for (int k = 0; k < 3; ++k) {
    const double len = (position(c[(k + 1) % 3]) - position(c[k])).norm();
    all += len;
    if (side_edge_[t][k] >= 0) {
      sum += len;
      ++n;
    }
  }
  return n > 0 ? sum / n : all / 3;
}

std::vector<int> TraceMesh::triangles_of(const SurfacePoint& p) const {
  switch (p.kind) {
  case SurfacePoint::Kind::Vertex: {
    const auto l = vertex_tris_[p.vertex];
    return {l.begin(), l.end()};
  }
  case SurfacePoint::Kind::Edge: {
    const auto l = edge_tris_[p.edge];
    return {l.begin(), l.end()};
  }
  case SurfacePoint::Kind::Face: {
    std::vector<int> out{p.tri};
    // On a diagonal of its polygon: the triangle across it holds p too.
    const auto& c = tri_[p.tri];
    for (int k = 0; k < 3; ++k)
      if (side_edge_[p.tri][k] < 0 && nbr_[p.tri][k] >= 0 &&
          collinear3d(position(c[k]), position(c[(k + 1) % 3]), p.pos))
        out.push_back(nbr_[p.tri][k]);
    return out;
  }
  }
  return {};
}

std::vector<int> TraceMesh::faces_of(const SurfacePoint& p) const {
  std::vector<int> out;
  for (int t : triangles_of(p))
    out.push_back(tri_face_[t]);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

TraceMesh::Nearest TraceMesh::nearest(const Vec3& q) const {
  RTCPointQuery query;
  // In the unit box's frame; a point past a million diagonals away is
  // brought in along its direction (the nearest triangle barely changes,
  // and the caller measures the distance from q itself), so that the query
  // stays within single precision.
  if (!q.allFinite())
    throw EmbedError("closest point: the point is not a finite number");
  Vec3 u = bvh_->to_unit(q);
  if (!u.allFinite()) { // past the range of a double in the mesh's units (a point at 1e308): its direction
    const Vec3 d = q - bvh_->centre;
    u = (d / d.cwiseAbs().maxCoeff()).normalized() * 1e6;
  }
  if (u.stableNorm() > 1e6)
    u *= 1e6 / u.stableNorm();
  QueryData data{this, bvh_->centre + bvh_->scale * u};
  data.slack = bvh_->slack;
  data.scale = bvh_->scale;
  query.x = static_cast<float>(u.x());
  query.y = static_cast<float>(u.y());
  query.z = static_cast<float>(u.z());
  query.time = 0.f;
  query.radius = std::numeric_limits<float>::infinity();
  // Queries come in runs along a curve: the triangle this thread found last
  // bounds the distance from the start, so the search skips most of the
  // tree. The answer does not depend on it (the nearest, the lowest index
  // among equally near ones, within the bound).
  thread_local const TraceMesh* last_mesh = nullptr;
  thread_local int last_tri = -1;
  if (last_mesh == this && last_tri >= 0 && last_tri < num_triangles())
    point_query_triangle(data, last_tri, query.radius);
  RTCPointQueryContext context;
  rtcInitPointQueryContext(&context);
  rtcPointQuery(bvh_->scene, &query, &context, nullptr, &data);
  if (data.tri < 0)
    throw EmbedError("closest point: the surface has no triangle");
  last_mesh = this;
  last_tri = data.tri;
  return {data.tri, data.hit.point, data.hit.bary};
}

std::optional<TraceMesh::Nearest> TraceMesh::ray_hit(const Vec3& origin, const Vec3& dir, double t_max,
                                                     const Vec3& facing) const {
  double t_near = 0; // in Embree's units
  const Vec3 o = bvh_->to_unit(origin);
  // A ray Embree can take: finite, within single precision, with a direction.
  if (!o.allFinite() || o.norm() > 1e6 || !dir.allFinite() || !(dir.norm() > 0) || !(t_max >= 0))
    return std::nullopt;
  for (int pass = 0; pass < 64; ++pass) { // each pass steps past one triangle facing away
    RTCRayHit rh{};
    rh.ray.org_x = static_cast<float>(o.x());
    rh.ray.org_y = static_cast<float>(o.y());
    rh.ray.org_z = static_cast<float>(o.z());
    rh.ray.dir_x = static_cast<float>(dir.x());
    rh.ray.dir_y = static_cast<float>(dir.y());
    rh.ray.dir_z = static_cast<float>(dir.z());
    rh.ray.tnear = static_cast<float>(t_near);
    rh.ray.tfar = static_cast<float>(std::min(t_max / bvh_->scale, 1e30));
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    rtcIntersect1(bvh_->scene, &context, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID)
      return std::nullopt;
    const int t = static_cast<int>(rh.hit.primID);
    const Vec3 n = tri_normal(t);
    if (n.dot(facing) > 0) {
      // The hit again in double precision: the line meets the triangle's
      // plane, then the nearest point of the triangle to that.
      const auto& c = tri_[t];
      const double along = n.dot(dir);
      double s = rh.ray.tfar * bvh_->scale;
      if (std::abs(along) > 1e-12)
        s = n.dot(position(c[0]) - origin) / along;
      const TriClosest cl = closest_on_triangle(origin + s * dir, position(c[0]), position(c[1]), position(c[2]));
      return Nearest{t, cl.point, cl.bary};
    }
    t_near = std::nextafter(rh.ray.tfar, std::numeric_limits<float>::infinity());
  }
  return std::nullopt;
}

bool TraceMesh::segment_blocked(const Vec3& a, const Vec3& b, double skip) const {
  const Vec3 o = bvh_->to_unit(a), e = bvh_->to_unit(b);
  const Vec3 d = e - o;
  const double len = d.norm();
  if (!o.allFinite() || !e.allFinite() || o.norm() > 1e6 || e.norm() > 1e6)
    return true;
  const double start = skip / bvh_->scale;
  if (!(len > start))
    return false; // nothing left of the segment to meet
  RTCRay ray{};
  ray.org_x = static_cast<float>(o.x());
  ray.org_y = static_cast<float>(o.y());
  ray.org_z = static_cast<float>(o.z());
  ray.dir_x = static_cast<float>(d.x() / len);
  ray.dir_y = static_cast<float>(d.y() / len);
  ray.dir_z = static_cast<float>(d.z() / len);
  ray.tnear = static_cast<float>(start);
  ray.tfar = static_cast<float>(len);
  ray.mask = 0xFFFFFFFFu;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  rtcOccluded1(bvh_->scene, &context, &ray);
  return ray.tfar < 0; // Embree marks an occluded ray with tfar = -inf
}

SmoothNormals::SmoothNormals(const TraceMesh& mesh) : mesh_(mesh), vertex_(mesh.mesh().positions.size(), Vec3::Zero()) {
  // Each vertex sums its triangles in their order (the order of
  // vertex_triangles): the same sums on any thread count.
  tbb::parallel_for(0, static_cast<int>(vertex_.size()), [&](int v) {
    for (const int t : mesh.vertex_triangles(v)) {
      const auto& c = mesh.tri(t);
      const Vec3 area = (mesh.position(c[1]) - mesh.position(c[0])).cross(mesh.position(c[2]) - mesh.position(c[0]));
      if (!(area.norm() > 0))
        continue; // a sliver of a polygon with collinear corners
      const int k = c[0] == v ? 0 : c[1] == v ? 1 : 2;
      const Vec3 a = mesh.position(c[(k + 1) % 3]) - mesh.position(c[k]);
      const Vec3 b = mesh.position(c[(k + 2) % 3]) - mesh.position(c[k]);
      vertex_[v] += std::atan2(a.cross(b).norm(), a.dot(b)) * area.normalized();
    }
  });
}

Vec3 SmoothNormals::at(int t, const std::array<double, 3>& bary) const {
  Vec3 n = Vec3::Zero();
  for (int k = 0; k < 3; ++k)
    if (vertex_[mesh_.tri(t)[k]].norm() > 0)
      n += bary[k] * vertex_[mesh_.tri(t)[k]].normalized();
  return n.norm() > 0 ? n.normalized() : mesh_.tri_normal(t);
}

SurfacePoint TraceMesh::closest_point(const Vec3& q) const {
  const Nearest data = nearest(q);
  const int t = data.tri;
  const auto& c = tri_[t];
  // Classify: within Tolerances::crossing_min_param (relative) of a corner
  // or of an input edge, the point is on it.
  const auto& l = data.bary;
  const double d = Tolerances::crossing_min_param;
  for (int k = 0; k < 3; ++k)
    if (l[k] > 1 - d)
      return vertex_point(c[k]);
  SurfacePoint sp;
  sp.tri = t;
  sp.pos = data.point;
  for (int k = 0; k < 3; ++k) {
    const int e = side_edge_[t][k];
    if (e < 0 || !(l[(k + 2) % 3] < d))
      continue;
    // On side k, from corner k to corner k+1.
    const double s = l[(k + 1) % 3] / (l[k] + l[(k + 1) % 3]);
    const auto& ends = edge_ends(e);
    sp.kind = SurfacePoint::Kind::Edge;
    sp.edge = e;
    sp.t = ends[0] == c[k] ? s : 1 - s;
    if (!(sp.t > d))
      return vertex_point(ends[0]);
    if (!(sp.t < 1 - d))
      return vertex_point(ends[1]);
    sp.pos = (1 - sp.t) * position(ends[0]) + sp.t * position(ends[1]);
    return sp;
  }
  return sp;
}

} // namespace curvenet::detail
