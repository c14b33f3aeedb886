// Deformation quality (include/curvenet/quality.hpp): volume, limb sections,
// growth away from the bones, self-intersecting triangle pairs (exact
// predicates), turned triangles, edge stretch.

#include "curvenet/quality.hpp"

#include "core/dual_quaternion.hpp"
#include "core/plane_section.hpp"
#include "core/polyline_distance.hpp"
#include "core/predicates.hpp"
#include "curvenet/errors.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <unordered_map>

namespace curvenet {

using namespace detail;

namespace {

using Tri = std::array<int, 3>;

std::vector<Tri> fan_triangles(const SurfaceMesh& mesh) {
  std::vector<Tri> t;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const auto c = mesh.face(f);
    for (size_t k = 1; k + 1 < c.size(); ++k)
      t.push_back({c[0], c[k], c[k + 1]});
  }
  return t;
}

/// Whether segment pq meets triangle abc (exact), for a segment not in the
/// triangle's plane.
bool segment_meets_triangle(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const int sp = orient3d(a, b, c, p), sq = orient3d(a, b, c, q);
  if (sp == sq && sp != 0)
    return false; // both ends on one side
  if (sp == 0 && sq == 0)
    return false; // in the plane: left to the coplanar test
  const int s1 = orient3d(p, q, a, b), s2 = orient3d(p, q, b, c), s3 = orient3d(p, q, c, a);
  const bool neg = s1 < 0 || s2 < 0 || s3<0, pos = s1> 0 || s2 > 0 || s3 > 0;
  return !(neg && pos);
}

/// Coplanar triangles: do they overlap in their plane (exact, on the
/// projection that keeps the plane's largest normal component)?
bool coplanar_overlap(const std::array<Vec3, 3>& t, const std::array<Vec3, 3>& u) {
  const Vec3 n = (t[1] - t[0]).cross(t[2] - t[0]);
  int drop = 0;
  n.cwiseAbs().maxCoeff(&drop);
  auto p2 = [drop](const Vec3& v) {
    return drop == 0   ? Eigen::Vector2d(v.y(), v.z())
           : drop == 1 ? Eigen::Vector2d(v.z(), v.x())
                       : Eigen::Vector2d(v.x(), v.y());
  };
  std::array<Eigen::Vector2d, 3> a, b;
  for (int k = 0; k < 3; ++k) {
    a[k] = p2(t[k]);
    b[k] = p2(u[k]);
  }
  auto seg_cross = [](const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& r,
                      const Eigen::Vector2d& s) {
    const int o1 = orient2d(p, q, r), o2 = orient2d(p, q, s), o3 = orient2d(r, s, p), o4 = orient2d(r, s, q);
    return o1 * o2 <= 0 && o3 * o4 <= 0 && !(o1 == 0 && o2 == 0 && o3 == 0 && o4 == 0);
  };
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (seg_cross(a[i], a[(i + 1) % 3], b[j], b[(j + 1) % 3]))
        return true;
  auto inside = [](const std::array<Eigen::Vector2d, 3>& tri, const Eigen::Vector2d& p) {
    const int o1 = orient2d(tri[0], tri[1], p), o2 = orient2d(tri[1], tri[2], p), o3 = orient2d(tri[2], tri[0], p);
    return (o1 >= 0 && o2 >= 0 && o3 >= 0) || (o1 <= 0 && o2 <= 0 && o3 <= 0);
  };
  return inside(a, b[0]) || inside(b, a[0]);
}

bool triangles_intersect(const std::array<Vec3, 3>& t, const std::array<Vec3, 3>& u) {
  // One side of the other's plane: apart.
  int su[3], st[3];
  for (int k = 0; k < 3; ++k) {
    su[k] = orient3d(t[0], t[1], t[2], u[k]);
    st[k] = orient3d(u[0], u[1], u[2], t[k]);
  }
  auto one_side = [](const int* s) { return (s[0] > 0 && s[1] > 0 && s[2] > 0) || (s[0] < 0 && s[1] < 0 && s[2] < 0); };
  if (one_side(su) || one_side(st))
    return false;
  if (su[0] == 0 && su[1] == 0 && su[2] == 0)
    return coplanar_overlap(t, u);
  for (int k = 0; k < 3; ++k) {
    if (segment_meets_triangle(u[k], u[(k + 1) % 3], t[0], t[1], t[2]))
      return true;
    if (segment_meets_triangle(t[k], t[(k + 1) % 3], u[0], u[1], u[2]))
      return true;
  }
  return false;
}

} // namespace

int self_intersecting_pairs(const SurfaceMesh& mesh, std::span<const Vec3> pos) {
  if (pos.size() != static_cast<size_t>(mesh.num_vertices()))
    throw Error("self_intersecting_pairs: " + std::to_string(pos.size()) + " positions for a mesh of " +
                std::to_string(mesh.num_vertices()) + " vertices");
  const std::vector<Tri> tris = fan_triangles(mesh);
  const int n = static_cast<int>(tris.size());
  if (n < 2)
    return 0;
  // A uniform grid of cells about twice the mean triangle size; each
  // triangle is listed in every cell its bounding box touches.
  std::vector<Eigen::AlignedBox3d> box(n);
  double extent = 0;
  Eigen::AlignedBox3d all;
  for (int t = 0; t < n; ++t) {
    for (int k = 0; k < 3; ++k)
      box[t].extend(pos[tris[t][k]]);
    all.extend(box[t]);
    extent += box[t].diagonal().maxCoeff();
  }
  const double cell = std::max(2 * extent / n, 1e-300);
  const Vec3 lo = all.min();
  auto cell_of = [&](const Vec3& p) {
    Eigen::Vector3i c;
    for (int k = 0; k < 3; ++k)
      c[k] = static_cast<int>(std::min(std::floor((p[k] - lo[k]) / cell), 1e6));
    return c;
  };
  std::unordered_map<std::uint64_t, std::vector<int>> grid;
  auto key = [](int x, int y, int z) {
    return (static_cast<std::uint64_t>(x) << 42) ^ (static_cast<std::uint64_t>(y) << 21) ^
           static_cast<std::uint64_t>(z);
  };
  for (int t = 0; t < n; ++t) {
    const Eigen::Vector3i a = cell_of(box[t].min()), b = cell_of(box[t].max());
    // A stretched triangle spanning very many cells is listed in a coarse way: its cells capped per axis.
    for (int x = a.x(); x <= std::min(b.x(), a.x() + 64); ++x)
      for (int y = a.y(); y <= std::min(b.y(), a.y() + 64); ++y)
        for (int z = a.z(); z <= std::min(b.z(), a.z() + 64); ++z)
          grid[key(x, y, z)].push_back(t);
  }
  // Pairs found in several cells are counted once: only in the cell holding
  // the lower corner of their boxes' overlap.
  int count = 0;
  for (const auto& [k, list] : grid) {
    for (size_t i = 0; i < list.size(); ++i)
      for (size_t j = i + 1; j < list.size(); ++j) {
        const int t = list[i], u = list[j];
        if (!box[t].intersects(box[u]))
          continue;
        const Eigen::Vector3i c = cell_of(box[t].intersection(box[u]).min());
        if (key(c.x(), c.y(), c.z()) != k)
          continue;
        const Tri &a = tris[t], &b = tris[u];
        bool shared = false;
        for (int p = 0; p < 3; ++p)
          for (int q = 0; q < 3; ++q)
            shared = shared || a[p] == b[q];
        if (shared)
          continue;
        if (triangles_intersect({pos[a[0]], pos[a[1]], pos[a[2]]}, {pos[b[0]], pos[b[1]], pos[b[2]]}))
          ++count;
      }
  }
  return count;
}

double section_area(const SurfaceMesh& mesh, std::span<const Vec3> positions, const Vec3& point, const Vec3& normal) {
  SurfaceMesh posed = mesh;
  posed.positions.assign(positions.begin(), positions.end());
  const SectionMesh sm(posed);
  double best = 0;
  for (const Section& s : plane_sections(sm, point, normal)) {
    if (!s.closed || s.points.size() < 3 || winding_number(s.points, point, point, normal) == 0)
      continue;
    Vec3 area = Vec3::Zero();
    for (size_t i = 0; i < s.points.size(); ++i)
      area += (s.points[i] - point).cross(s.points[(i + 1) % s.points.size()] - point);
    const double a = 0.5 * std::abs(area.dot(normal.normalized()));
    if (best == 0 || a < best)
      best = a;
  }
  return best;
}

std::vector<Vec3> mean_curvature_normals(const SurfaceMesh& mesh, std::span<const Vec3> x) {
  const size_t nv = static_cast<size_t>(mesh.num_vertices());
  if (x.size() != nv)
    throw Error("mean_curvature_normals: " + std::to_string(x.size()) + " positions for " + std::to_string(nv) +
                " vertices");
  std::vector<Vec3> lap(nv, Vec3::Zero());
  std::vector<double> area(nv, 0.0);
  for (const Tri& t : fan_triangles(mesh)) {
    const double a = 0.5 * (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]).norm();
    if (!(a > 0))
      continue;
    for (int k = 0; k < 3; ++k) {
      const int i = t[k], j = t[(k + 1) % 3], o = t[(k + 2) % 3];
      // The cotangent of the angle at o, opposite the edge i-j.
      const Vec3 u = x[i] - x[o], w = x[j] - x[o];
      const double cot = u.dot(w) / (2 * a);
      lap[i] += 0.5 * cot * (x[j] - x[i]);
      lap[j] += 0.5 * cot * (x[i] - x[j]);
      area[t[k]] += a / 3;
    }
  }
  for (size_t v = 0; v < nv; ++v)
    lap[v] = area[v] > 0 ? Vec3(-lap[v] / (2 * area[v])) : Vec3::Zero();
  return lap;
}

int turned_triangles(const SurfaceMesh& mesh, std::span<const Vec3> posed, std::span<const Mat4> skinning,
                     std::span<const int> dominant, double degrees) {
  const int nj = static_cast<int>(skinning.size());
  const std::vector<Vec3>& rest = mesh.positions;
  if (posed.size() != rest.size() || dominant.size() != rest.size())
    throw Error("turned_triangles: the positions and dominant joints do not fit the mesh");
  std::vector<Eigen::Matrix3d> rot(nj);
  for (int j = 0; j < nj; ++j)
    rot[j] = nearest_rotation(skinning[j].topLeftCorner<3, 3>());
  const double limit = std::cos(degrees * std::numbers::pi / 180);
  int turned = 0;
  for (const Tri& t : fan_triangles(mesh)) {
    const int a = dominant[t[0]], b = dominant[t[1]], c = dominant[t[2]];
    const int j = (b == c && a != b) ? b : a;
    if (j < 0 || j >= nj)
      continue;
    const Vec3 n0 = rot[j] * (rest[t[1]] - rest[t[0]]).cross(rest[t[2]] - rest[t[0]]);
    const Vec3 n1 = (posed[t[1]] - posed[t[0]]).cross(posed[t[2]] - posed[t[0]]);
    if (n0.norm() > 0 && !(n1.normalized().dot(n0.normalized()) >= limit))
      ++turned;
  }
  return turned;
}

std::vector<int> dominant_joints(const SurfaceMesh& mesh, const SkinnedMesh& skin) {
  std::vector<int> d(mesh.num_vertices(), 0);
  std::vector<double> best(mesh.num_vertices(), -1);
  const size_t n = std::min(skin.vertex_joint.size(), mesh.input_to_welded.size());
  for (size_t i = 0; i < n; ++i) {
    const int v = mesh.input_to_welded[i];
    for (int k = 0; k < 4; ++k)
      if (skin.vertex_joint[i][k] >= 0 && skin.vertex_weight[i][k] > best[v]) {
        best[v] = skin.vertex_weight[i][k];
        d[v] = skin.vertex_joint[i][k];
      }
  }
  return d;
}

DeformationQuality measure_deformation(const SurfaceMesh& mesh, std::span<const Vec3> posed,
                                       const std::vector<Joint>& joints, std::span<const Mat4> skinning,
                                       std::span<const int> dominant, const QualityOptions& opt) {
  const int nv = mesh.num_vertices(), nj = static_cast<int>(joints.size());
  if (posed.size() != static_cast<size_t>(nv) || dominant.size() != static_cast<size_t>(nv) ||
      skinning.size() != joints.size())
    throw Error("measure_deformation: the positions, dominant joints and matrices do not fit the mesh and skeleton");
  DeformationQuality q;
  const std::vector<Vec3>& rest = mesh.positions;
  const std::vector<Vec3> posed_v(posed.begin(), posed.end());
  const double v0 = mesh.enclosed_volume(rest);
  q.volume_change = v0 != 0 ? mesh.enclosed_volume(posed_v) / v0 - 1 : 0;

  // The skeleton at rest and posed: each joint's origin.
  std::map<std::string, int> index;
  for (int j = 0; j < nj; ++j)
    index[joints[j].name] = j;
  std::vector<Vec3> head0(nj), head1(nj);
  for (int j = 0; j < nj; ++j) {
    head0[j] = joints[j].bind.block<3, 1>(0, 3);
    head1[j] = (skinning[j] * joints[j].bind).block<3, 1>(0, 3);
  }

  // Sections across the limbs.
  double smallest = INFINITY;
  for (const auto& limb : opt.limbs) {
    if (limb.size() < 2)
      continue;
    for (size_t b = 0; b + 1 < limb.size(); ++b) {
      const int j = limb[b], k = limb[b + 1];
      for (int s = 0; s <= opt.planes_per_bone; ++s) {
        const double u = static_cast<double>(s) / opt.planes_per_bone;
        if (s == opt.planes_per_bone && b + 2 < limb.size())
          continue; // the joint between two bones is measured once, from the next bone
        auto axis = [&](const std::vector<Vec3>& h, Vec3& point, Vec3& normal) {
          point = (1 - u) * h[j] + u * h[k];
          normal = (h[k] - h[j]).normalized();
          if (s == 0 && b > 0) // at a joint: the bisector of its two bones
            normal = (normal + (h[j] - h[limb[b - 1]]).normalized()).normalized();
        };
        Vec3 p0, n0, p1, n1;
        axis(head0, p0, n0);
        axis(head1, p1, n1);
        if (!n0.allFinite() || !n1.allFinite())
          continue;
        const double a0 = section_area(mesh, rest, p0, n0);
        if (!(a0 > 0))
          continue;
        smallest = std::min(smallest, section_area(mesh, posed, p1, n1) / a0);
      }
    }
  }

  if (std::isfinite(smallest))
    q.smallest_section = smallest;

  // Growth away from the bones.
  std::vector<std::pair<int, int>> bones;
  for (int j = 0; j < nj; ++j)
    if (joints[j].parent && (opt.bone_joints.empty() || opt.bone_joints[j]))
      if (auto it = index.find(*joints[j].parent); it != index.end())
        bones.emplace_back(it->second, j);
  if (!bones.empty()) {
    double worst = 0;
    for (int v = 0; v < nv; ++v) {
      if (!opt.bulge_vertices.empty() && !opt.bulge_vertices[v])
        continue;
      double d0 = INFINITY, d1 = INFINITY;
      for (const auto& [a, b] : bones) {
        d0 = std::min(d0, point_segment_distance(rest[v], head0[a], head0[b]));
        d1 = std::min(d1, point_segment_distance(posed[v], head1[a], head1[b]));
      }
      worst = std::max(worst, d1 - d0);
    }
    q.bulge = worst / mesh.bbox_diagonal();
  }

  q.self_intersections = self_intersecting_pairs(mesh, posed);

  q.turned = turned_triangles(mesh, posed, skinning, dominant, opt.turn_degrees);

  // Edge stretch.
  double sum = 0;
  int edges = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const auto c = mesh.face(f);
    for (size_t k = 0; k < c.size(); ++k) {
      const int a = c[k], b = c[(k + 1) % c.size()];
      if (a > b)
        continue; // each interior edge once (the twin runs b -> a)
      const double l0 = (rest[b] - rest[a]).norm();
      if (!(l0 > 0))
        continue;
      const double e = std::abs((posed[b] - posed[a]).norm() / l0 - 1);
      sum += e;
      q.stretch_max = std::max(q.stretch_max, e);
      ++edges;
    }
  }
  q.stretch_mean = edges > 0 ? sum / edges : 0;

  // The detail: each counted vertex's mean-curvature normal against the
  // rest one, carried by the rotation of its dominant joint (the polar
  // part of its matrix).
  const std::vector<Vec3> h0 = mean_curvature_normals(mesh, rest), h1 = mean_curvature_normals(mesh, posed);
  double change = 0, length = 0;
  for (int v = 0; v < nv; ++v) {
    if (!opt.detail_vertices.empty() && !opt.detail_vertices[v])
      continue;
    const int j = dominant[v];
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    if (j >= 0 && j < nj) {
      const Eigen::JacobiSVD<Eigen::Matrix3d> svd(skinning[j].block<3, 3>(0, 0),
                                                  Eigen::ComputeFullU | Eigen::ComputeFullV);
      R = svd.matrixU() * svd.matrixV().transpose();
    }
    change += (h1[v] - R * h0[v]).norm();
    length += h0[v].norm();
  }
  q.detail_change = length > 0 ? change / length : 0;
  return q;
}

} // namespace curvenet
