// Catmull-Clark and bilinear refinement through OpenSubdiv's Far layer: the
// topology refined uniformly, then the positions interpolated level by level.

#include "curvenet/subdivide.hpp"

#include "curvenet/errors.hpp"
#include "generate/refine.hpp"

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>

#include <cmath>
#include <memory>
#include <new>

namespace curvenet {

namespace {

using namespace OpenSubdiv;

/// A position in the shape PrimvarRefiner interpolates.
struct Point {
  Vec3 p = Vec3::Zero();
  void Clear(void* = nullptr) { p.setZero(); }
  void AddWithWeight(const Point& s, double w) { p += w * s.p; }
};

/// The cage refined by `scheme`; `base_face` receives each refined face's cage face.
SurfaceMesh refine(const SurfaceMesh& cage, int levels, Sdc::SchemeType scheme, const char* name, long long max_faces,
                   std::vector<int>* base_face = nullptr) {
  if (levels < 1 || levels > 6)
    throw InputError(cage.source, "subdivision levels", "must be between 1 and 6, not " + std::to_string(levels));
  // The size up front: an n-gon gives n quads, and each level 4 times as many.
  const double faces = static_cast<double>(cage.face_vertices.size()) * std::pow(4.0, levels - 1);
  if (faces > static_cast<double>(max_faces))
    throw InputError(cage.source, "levels " + std::to_string(levels),
                     "would make " + std::to_string(static_cast<long long>(faces)) + " faces (about " +
                         std::to_string(static_cast<long long>(faces * 400 / (1 << 20))) +
                         " MB), more than the limit of " + std::to_string(max_faces) +
                         " (--max-faces); use fewer levels");
  std::vector<int> counts;
  for (int f = 0; f < cage.num_faces(); ++f)
    counts.push_back(static_cast<int>(cage.face(f).size()));
  Far::TopologyDescriptor desc;
  desc.numVertices = cage.num_vertices();
  desc.numFaces = cage.num_faces();
  desc.numVertsPerFace = counts.data();
  desc.vertIndicesPerFace = cage.face_vertices.data();
  Sdc::Options sdc;
  sdc.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);
  using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
  std::unique_ptr<Far::TopologyRefiner> refiner(Factory::Create(desc, Factory::Options(scheme, sdc)));
  if (!refiner)
    throw InputError(cage.source, "subdivision", "OpenSubdiv cannot refine this mesh");
  refiner->RefineUniform(Far::TopologyRefiner::UniformOptions(levels));

  std::vector<Point> points(refiner->GetNumVerticesTotal());
  for (int v = 0; v < cage.num_vertices(); ++v)
    points[v].p = cage.positions[v];
  Far::PrimvarRefinerReal<double> interpolate(*refiner); // double weights: no float rounding
  Point* from = points.data();
  for (int level = 1; level <= levels; ++level) {
    Point* to = from + refiner->GetLevel(level - 1).GetNumVertices();
    interpolate.Interpolate(level, from, to);
    from = to;
  }
  const Far::TopologyLevel& last = refiner->GetLevel(levels);
  if (base_face) {
    base_face->resize(last.GetNumFaces());
    for (int f = 0; f < last.GetNumFaces(); ++f) {
      int g = f;
      for (int level = levels; level > 0; --level)
        g = refiner->GetLevel(level).GetFaceParentFace(g);
      (*base_face)[f] = g;
    }
  }
  RawMesh raw;
  raw.positions.reserve(last.GetNumVertices());
  for (int v = 0; v < last.GetNumVertices(); ++v)
    raw.positions.push_back(from[v].p);
  for (int f = 0; f < last.GetNumFaces(); ++f) {
    const Far::ConstIndexArray fv = last.GetFaceVertices(f);
    const std::vector<int> corners(fv.begin(), fv.end());
    raw.add_face(corners);
  }
  return make_surface_mesh(raw, cage.source + " (" + name + " level " + std::to_string(levels) + ")");
}

} // namespace

namespace {
/// Out of memory within the limit (a machine with less than the estimate) says which option to lower.
template <class F> auto naming_levels(const SurfaceMesh& cage, int levels, F&& f) {
  try {
    return f();
  } catch (const std::bad_alloc&) {
    throw InputError(cage.source, "levels " + std::to_string(levels),
                     "out of memory while refining: use fewer levels, or a lower --max-faces");
  }
}
} // namespace

SurfaceMesh catmull_clark(const SurfaceMesh& cage, int levels, long long max_faces) {
  return naming_levels(cage, levels,
                       [&] { return refine(cage, levels, Sdc::SCHEME_CATMARK, "Catmull-Clark", max_faces); });
}

SurfaceMesh midpoint_subdivide(const SurfaceMesh& mesh, int levels, long long max_faces) {
  return naming_levels(mesh, levels, [&] { return refine(mesh, levels, Sdc::SCHEME_BILINEAR, "midpoint", max_faces); });
}

namespace detail {

CageRefinement refine_cage(const SurfaceMesh& cage, int levels, long long max_faces) {
  CageRefinement r;
  naming_levels(cage, levels, [&] {
    r.limit = refine(cage, levels, Sdc::SCHEME_CATMARK, "Catmull-Clark", max_faces, &r.base_face);
    r.flat = refine(cage, levels, Sdc::SCHEME_BILINEAR, "bilinear", max_faces);
    return 0;
  });
  if (r.limit.positions.size() != r.flat.positions.size() || r.limit.face_vertices != r.flat.face_vertices)
    throw InputError(cage.source, "subdivision",
                     "the two refinements of the cage do not share their vertices and faces");
  return r;
}

} // namespace detail

} // namespace curvenet
