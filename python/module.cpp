// The curvenet Python module (pybind11): a thin layer over the library.
// Arrays go in and out as numpy; the library's exceptions become
// curvenet.Error, InputError (with .file and .element), EmbedError and
// TopologyError. Long calls release the GIL.

#include "curvenet/bake.hpp"
#include "curvenet/compare.hpp"
#include "curvenet/deform.hpp"
#include "curvenet/edit.hpp"
#include "curvenet/embed.hpp"
#include "curvenet/errors.hpp"
#include "curvenet/farm.hpp"
#include "curvenet/io.hpp"
#include "curvenet/jobs.hpp"
#include "curvenet/layer.hpp"
#include "curvenet/mesh_output.hpp"
#include "curvenet/pose.hpp"
#include "curvenet/skin.hpp"
#include "curvenet/starter.hpp"
#include "curvenet/subdivide.hpp"
#include "curvenet/transfer.hpp"
#include "curvenet/weights.hpp"

#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl_bind.h>

#include <cmath>
#include <exception>
#include <optional>
#include <string>
#include <vector>

namespace py = pybind11;
using namespace curvenet;

using JointWeights = std::map<std::string, double>;
using NodeWeights = std::map<std::string, JointWeights>;
PYBIND11_MAKE_OPAQUE(std::vector<Node>);
PYBIND11_MAKE_OPAQUE(std::vector<Profile>);
PYBIND11_MAKE_OPAQUE(std::vector<Joint>);
PYBIND11_MAKE_OPAQUE(NodeWeights);
PYBIND11_MAKE_OPAQUE(JointWeights);

namespace {

using Points = py::array_t<double, py::array::c_style | py::array::forcecast>;
using Indices = py::array_t<long long, py::array::c_style | py::array::forcecast>;

/// An (n, 3) array from points.
py::array_t<double> points_array(const std::vector<Vec3>& pts) {
  py::array_t<double> a({static_cast<py::ssize_t>(pts.size()), py::ssize_t{3}});
  auto m = a.mutable_unchecked<2>();
  for (size_t i = 0; i < pts.size(); ++i)
    for (int c = 0; c < 3; ++c)
      m(i, c) = pts[i][c];
  return a;
}

/// Points from an (n, 3) array; `what` names it in the message.
std::vector<Vec3> points_from(const py::handle& obj, const char* what) {
  const Points a = Points::ensure(obj);
  if (!a || a.ndim() != 2 || a.shape(1) != 3)
    throw py::value_error(std::string(what) + ": expected an (n, 3) array of numbers");
  std::vector<Vec3> out(static_cast<size_t>(a.shape(0)));
  auto r = a.unchecked<2>();
  for (py::ssize_t i = 0; i < a.shape(0); ++i)
    out[i] = {r(i, 0), r(i, 1), r(i, 2)};
  return out;
}

template <class T> py::array_t<T> vector_array(const std::vector<T>& v) {
  py::array_t<T> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

/// An (n, k) array of the values `data` holds row after row.
template <class T> py::array_t<T> table_array(const T* data, size_t n, size_t k) {
  py::array_t<T> a({static_cast<py::ssize_t>(n), static_cast<py::ssize_t>(k)});
  std::copy(data, data + n * k, a.mutable_data());
  return a;
}

Mat4 matrix_from(const py::handle& obj, const char* what) {
  const Points a = Points::ensure(obj);
  if (!a || a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
    throw py::value_error(std::string(what) + ": expected a 4x4 array");
  Mat4 m;
  auto r = a.unchecked<2>();
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      m(i, j) = r(i, j);
  if (!m.allFinite())
    throw InputError(what, "matrix", "has a non-finite entry");
  return m;
}

py::array_t<double> matrices_array(const std::vector<Mat4>& ms) {
  py::array_t<double> a({static_cast<py::ssize_t>(ms.size()), py::ssize_t{4}, py::ssize_t{4}});
  auto m = a.mutable_unchecked<3>();
  for (size_t k = 0; k < ms.size(); ++k)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        m(k, i, j) = ms[k](i, j);
  return a;
}

/// Reads (..., J, 4, 4) row-major matrices into Eigen's (column-major) form.
void matrices_into(const py::array_t<double, py::array::c_style | py::array::forcecast>& a, std::vector<Mat4>& out) {
  const double* p = a.data();
  const size_t n = static_cast<size_t>(a.size() / 16);
  out.resize(n);
  for (size_t k = 0; k < n; ++k, p += 16) {
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        out[k](i, j) = p[4 * i + j];
    if (!out[k].allFinite())
      throw InputError("skinning", "matrix " + std::to_string(k), "has a non-finite entry");
  }
}

/// A rig from Python is checked by the rules of the file reader before use.
const Rig& checked(const Rig& rig) {
  validate_rig(rig, "rig");
  return rig;
}

py::object json_module() {
  return py::module_::import("json");
}
py::object from_json(const std::string& text) {
  return json_module().attr("loads")(text);
}

/// A mesh from numpy arrays: V (n, 3), F an (m, k) int array or a list of polygons.
SurfaceMesh mesh_from_arrays(const py::object& V, const py::object& F, const std::string& source) {
  RawMesh raw;
  raw.positions = points_from(V, "V");
  std::vector<int> corners;
  auto index = [&](long long i) {
    if (i < 0 || i >= static_cast<long long>(raw.positions.size()))
      throw InputError(source, "index " + std::to_string(i),
                       "is not a vertex (there are " + std::to_string(raw.positions.size()) + ")");
    return static_cast<int>(i);
  };
  if (py::isinstance<py::array>(F)) {
    const char kind = py::reinterpret_borrow<py::array>(F).dtype().kind();
    if (kind != 'i' && kind != 'u')
      throw py::value_error("F: expected integer vertex indices, not an array of dtype kind '" + std::string(1, kind) +
                            "'");
    const Indices a = Indices::ensure(F);
    if (!a || a.ndim() != 2 || a.shape(1) < 3)
      throw py::value_error("F: expected an (m, 3) or (m, 4) int array, or a list of polygons");
    auto r = a.unchecked<2>();
    for (py::ssize_t f = 0; f < a.shape(0); ++f) {
      corners.clear();
      for (py::ssize_t c = 0; c < a.shape(1); ++c)
        corners.push_back(index(r(f, c)));
      raw.add_face(corners);
    }
  } else {
    for (const py::handle poly : F) {
      corners.clear();
      for (const py::handle i : poly)
        corners.push_back(index(i.cast<long long>()));
      raw.add_face(corners);
    }
  }
  py::gil_scoped_release release;
  return make_surface_mesh(raw, source);
}

Coverage coverage_from(const std::string& s) {
  if (s == "auto")
    return Coverage::Auto;
  if (s == "full")
    return Coverage::Full;
  if (s == "local")
    return Coverage::Local;
  throw py::value_error("coverage: expected 'auto', 'full' or 'local', got '" + s + "'");
}

AutoWeightOptions weight_options(const std::string& rule, double blend) {
  AutoWeightOptions o;
  if (rule == "blend-zone")
    o.rule = WeightRule::BlendZone;
  else if (rule == "segment")
    o.rule = WeightRule::Segment;
  else
    throw py::value_error("weight_rule: expected 'blend-zone' or 'segment', got '" + rule + "'");
  if (!(blend > 0 && blend <= 0.5))
    throw py::value_error("blend: expected a number in (0, 0.5]");
  o.blend = blend;
  return o;
}

/// Embedding options from keyword arguments; progress is called with the GIL held.
struct EmbedKwargs {
  double density = 5.0;
  bool cage = false;
  long long max_samples = 20'000'000;
  std::optional<std::string> coverage;
  std::optional<py::function> progress;
  std::shared_ptr<std::exception_ptr> progress_error = std::make_shared<std::exception_ptr>();

  EmbedOptions options() const {
    EmbedOptions o;
    o.density = density;
    o.cage = cage;
    o.max_samples = max_samples;
    if (coverage)
      o.coverage = coverage_from(*coverage);
    if (progress) {
      py::function f = *progress;
      auto error = progress_error;
      o.progress = [f, error](std::string_view stage, double fraction) {
        py::gil_scoped_acquire gil;
        if (*error)
          return;
        try {
          f(std::string(stage), fraction);
        } catch (...) {
          *error = std::current_exception(); // raised once the call returns
        }
      };
    }
    return o;
  }
  void rethrow() const {
    if (*progress_error)
      std::rethrow_exception(*progress_error);
  }
};

/// The options' lambda holds a py::function: it must be destroyed with the GIL held.
template <class F> auto call_released(const EmbedKwargs& kw, F&& f) {
  EmbedOptions opt = kw.options();
  auto result = [&] {
    py::gil_scoped_release release;
    return f(opt);
  }();
  kw.rethrow();
  return result;
}

/// A Binding with scratch space, so that deform() with `out` allocates nothing.
struct PyBinding {
  Binding binding;
  std::vector<Mat4> matrices;
  std::vector<Vec3> positions;
};

std::vector<Joint> joints_from(const py::object& obj) {
  if (py::isinstance<py::str>(obj)) {
    const std::string path = obj.cast<std::string>();
    py::gil_scoped_release release;
    return load_skeleton(path);
  }
  if (py::isinstance<Rig>(obj)) {
    const Rig& rig = obj.cast<const Rig&>();
    if (!rig.has_skeleton)
      throw InputError("rig", "/skeleton", "the rig has no skeleton");
    return rig.joints;
  }
  if (py::isinstance<PyBinding>(obj))
    return obj.cast<const PyBinding&>().binding.joints();
  if (py::isinstance<SkinnedMesh>(obj))
    return obj.cast<const SkinnedMesh&>().joints;
  return obj.cast<std::vector<Joint>>();
}

Pose pose_from(const py::object& obj) {
  if (py::isinstance<py::str>(obj)) {
    const std::string path = obj.cast<std::string>();
    return read_pose(path);
  }
  if (py::isinstance<py::dict>(obj)) {
    py::dict d = obj.cast<py::dict>();
    py::dict file;
    if (d.contains("format")) {
      file = d;
    } else {
      file["format"] = "curvenet-pose";
      file["version"] = 1;
      py::dict joints;
      for (auto [name, entry] : d) {
        if (py::isinstance<JointPose>(entry)) {
          const JointPose& e = entry.cast<const JointPose&>();
          py::dict je;
          je["translation"] = py::make_tuple(e.translation.x(), e.translation.y(), e.translation.z());
          je["rotation"] = py::make_tuple(e.rotation.w(), e.rotation.x(), e.rotation.y(), e.rotation.z());
          je["scale"] = py::make_tuple(e.scale.x(), e.scale.y(), e.scale.z());
          joints[name] = je;
        } else {
          joints[name] = entry;
        }
      }
      file["joints"] = joints;
    }
    // numpy values become lists, so the file's own reader checks them.
    py::object np = py::module_::import("numpy");
    py::object dumps = json_module().attr("dumps");
    py::object text;
    try {
      text = dumps(file, py::arg("allow_nan") = false,
                   py::arg("default") = py::cpp_function([np](py::object o) -> py::object {
                     if (py::isinstance(o, np.attr("ndarray")))
                       return o.attr("tolist")();
                     if (py::isinstance(o, np.attr("generic")))
                       return o.attr("item")();
                     throw py::type_error("not a JSON value");
                   }));
    } catch (const py::error_already_set& e) {
      if (!e.matches(PyExc_ValueError))
        throw;
      throw InputError("pose dict", "", "a value is not a finite number");
    }
    return parse_pose(text.cast<std::string>(), "pose dict");
  }
  return obj.cast<Pose>();
}

void check_finite_output(const std::vector<Vec3>::const_iterator begin, size_t n, size_t frame, bool frames) {
  for (size_t i = 0; i < n; ++i)
    if (!begin[static_cast<std::ptrdiff_t>(i)].allFinite())
      throw InputError("skinning",
                       (frames ? "frame " + std::to_string(frame) + " " : "") + "vertex " + std::to_string(i),
                       "the pose moves it out of range (not a finite number)");
}

/// A layer's positions for (J, 4, 4) skinning matrices, through `call`
/// (CurveLayer::deform or rest_correction), the GIL released.
py::array_t<double>
layer_positions(const CurveLayer& l, const py::array_t<double, py::array::c_style | py::array::forcecast>& skinning,
                double envelope, const std::optional<std::map<std::string, Vec3>>& offsets,
                void (CurveLayer::*call)(std::span<const Mat4>, std::span<Vec3>, double, const NodeOffsets*) const) {
  const size_t nj = l.joints().size();
  if (skinning.ndim() != 3 || static_cast<size_t>(skinning.shape(0)) != nj || skinning.shape(1) != 4 ||
      skinning.shape(2) != 4)
    throw py::value_error("skinning: expected a (" + std::to_string(nj) + ", 4, 4) array, one per joint");
  if (!(envelope >= 0 && envelope <= 1))
    throw py::value_error("envelope: expected a number from 0 to 1");
  std::vector<Mat4> M;
  matrices_into(skinning, M);
  std::vector<Vec3> out(static_cast<size_t>(l.num_input_vertices()));
  {
    py::gil_scoped_release release;
    (l.*call)(M, out, envelope, offsets ? &*offsets : nullptr);
  }
  return points_array(out);
}

py::dict distance_dict(const SurfaceDistance& d) {
  auto one = [](const OneWayDistance& o) {
    py::dict x;
    x["mean"] = o.mean;
    x["rms"] = o.rms;
    x["max"] = o.max;
    return x;
  };
  py::dict out;
  out["a_to_b"] = one(d.a_to_b);
  out["b_to_a"] = one(d.b_to_a);
  out["mean"] = d.mean;
  out["rms"] = d.rms;
  out["max"] = d.max;
  out["diagonal"] = d.diagonal;
  out["mean_percent"] = d.percent(d.mean);
  out["rms_percent"] = d.percent(d.rms);
  out["max_percent"] = d.percent(d.max);
  return out;
}

} // namespace

PYBIND11_MODULE(_curvenet, m) {
  m.doc() = "curvenet: topology-independent character deformation with curve networks";

  // Exceptions: Error(RuntimeError) and its three kinds.
  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  static py::exception<InputError> input_error(m, "InputError", error.ptr());
  static py::exception<EmbedError> embed_error(m, "EmbedError", error.ptr());
  static py::exception<TopologyError> topology_error(m, "TopologyError", error.ptr());
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p)
        std::rethrow_exception(p);
    } catch (const InputError& e) {
      py::object inst = py::handle(input_error.ptr())(e.what());
      inst.attr("file") = e.file();
      inst.attr("element") = e.element();
      PyErr_SetObject(input_error.ptr(), inst.ptr());
    } catch (const EmbedError& e) {
      embed_error(e.what());
    } catch (const TopologyError& e) {
      topology_error(e.what());
    } catch (const Error& e) {
      error(e.what());
    }
  });

  // Meshes.
  py::class_<SurfaceMesh>(m, "Mesh", "A validated polygon mesh, welded by position")
      .def(py::init([](const py::object& V, const py::object& F, const std::string& source) {
             return mesh_from_arrays(V, F, source);
           }),
           py::arg("V"), py::arg("F"), py::arg("source") = "<arrays>")
      .def_readonly("source", &SurfaceMesh::source)
      .def_property_readonly("vertices", [](const SurfaceMesh& s) { return points_array(s.positions); })
      .def_property_readonly("face_offsets", [](const SurfaceMesh& s) { return vector_array(s.face_offsets); })
      .def_property_readonly("face_vertices", [](const SurfaceMesh& s) { return vector_array(s.face_vertices); })
      .def_property_readonly("input_to_welded", [](const SurfaceMesh& s) { return vector_array(s.input_to_welded); })
      .def_property_readonly("num_vertices", &SurfaceMesh::num_vertices)
      .def_property_readonly("num_faces", &SurfaceMesh::num_faces)
      .def_property_readonly("num_input_vertices",
                             [](const SurfaceMesh& s) { return static_cast<int>(s.input_to_welded.size()); })
      .def_readonly("notes", &SurfaceMesh::notes)
      .def("bbox_diagonal", &SurfaceMesh::bbox_diagonal)
      .def("mean_edge_length", &SurfaceMesh::mean_edge_length)
      .def("__repr__", [](const SurfaceMesh& s) {
        return "<curvenet.Mesh " + s.source + ": " + std::to_string(s.num_vertices()) + " vertices, " +
               std::to_string(s.num_faces()) + " faces>";
      });
  m.def(
      "load_mesh",
      [](const std::string& path) {
        py::gil_scoped_release release;
        return load_mesh(path);
      },
      py::arg("path"));

  // The rig.
  py::class_<Curve> curve(m, "Curve", "The shape of a profile: a polyline, Bezier or NURBS");
  curve
      .def(py::init([](const py::object& points, const std::string& kind, int degree, std::vector<double> knots,
                       std::vector<double> weights) {
             Curve c;
             c.kind = kind == "polyline" ? Curve::Kind::Polyline
                      : kind == "bezier" ? Curve::Kind::Bezier
                      : kind == "nurbs"  ? Curve::Kind::Nurbs
                                         : throw py::value_error("kind: expected 'polyline', 'bezier' or 'nurbs'");
             if (!points.is_none())
               c.points = points_from(points, "points");
             c.degree = degree;
             c.knots = std::move(knots);
             c.weights = std::move(weights);
             return c;
           }),
           py::arg("points") = py::none(), py::arg("kind") = "polyline", py::arg("degree") = 3,
           py::arg("knots") = std::vector<double>{}, py::arg("weights") = std::vector<double>{})
      .def_property(
          "kind",
          [](const Curve& c) {
            return c.kind == Curve::Kind::Polyline ? "polyline" : c.kind == Curve::Kind::Bezier ? "bezier" : "nurbs";
          },
          [](Curve& c, const std::string& k) {
            if (k == "polyline")
              c.kind = Curve::Kind::Polyline;
            else if (k == "bezier")
              c.kind = Curve::Kind::Bezier;
            else if (k == "nurbs")
              c.kind = Curve::Kind::Nurbs;
            else
              throw py::value_error("kind: expected 'polyline', 'bezier' or 'nurbs'");
          })
      .def_property(
          "points", [](const Curve& c) { return points_array(c.points); },
          [](Curve& c, const py::object& p) { c.points = points_from(p, "points"); })
      .def_readwrite("degree", &Curve::degree)
      .def_readwrite("knots", &Curve::knots)
      .def_readwrite("weights", &Curve::weights);

  py::class_<Node>(m, "Node")
      .def(py::init([](std::string id, const Vec3& p) {
             return Node{std::move(id), p};
           }),
           py::arg("id"), py::arg("position"))
      .def_readwrite("id", &Node::id)
      .def_property(
          "position",
          py::cpp_function([](Node& x) -> Vec3& { return x.position; }, py::return_value_policy::reference_internal),
          [](Node& x, const Vec3& v) { x.position = v; })
      .def("__repr__", [](const Node& n) { return "<curvenet.Node '" + n.id + "'>"; });
  py::class_<Profile>(m, "Profile")
      .def(py::init([](std::string id, std::string from, std::string to, const Curve& c) {
             return Profile{std::move(id), std::move(from), std::move(to), c};
           }),
           py::arg("id"), py::arg("from_"), py::arg("to"), py::arg("curve") = Curve{})
      .def_readwrite("id", &Profile::id)
      .def_readwrite("from_", &Profile::from)
      .def_readwrite("to", &Profile::to)
      .def_readwrite("curve", &Profile::curve)
      .def("__repr__",
           [](const Profile& p) { return "<curvenet.Profile '" + p.id + "' " + p.from + " -> " + p.to + ">"; });
  py::class_<Joint>(m, "Joint")
      .def(py::init([](std::string name, std::optional<std::string> parent, const Mat4& bind) {
             return Joint{std::move(name), std::move(parent), bind};
           }),
           py::arg("name"), py::arg("parent") = py::none(), py::arg("bind") = Mat4(Mat4::Identity()))
      .def_readwrite("name", &Joint::name)
      .def_readwrite("parent", &Joint::parent)
      .def_property(
          "bind",
          py::cpp_function([](Joint& x) -> Mat4& { return x.bind; }, py::return_value_policy::reference_internal),
          [](Joint& x, const Mat4& v) { x.bind = v; })
      .def("__repr__", [](const Joint& j) { return "<curvenet.Joint '" + j.name + "'>"; });

  py::bind_vector<std::vector<Node>>(m, "NodeList");
  py::bind_vector<std::vector<Profile>>(m, "ProfileList");
  py::bind_vector<std::vector<Joint>>(m, "JointList");
  py::implicitly_convertible<py::list, std::vector<Node>>();
  py::implicitly_convertible<py::list, std::vector<Profile>>();
  py::implicitly_convertible<py::list, std::vector<Joint>>();
  py::bind_map<JointWeights>(m, "JointWeights").def(py::init([](const py::dict& d) {
    JointWeights w;
    for (auto [k, v] : d)
      w[k.cast<std::string>()] = v.cast<double>();
    return w;
  }));
  py::implicitly_convertible<py::dict, JointWeights>();
  py::bind_map<NodeWeights>(m, "NodeWeights").def(py::init([](const py::dict& d) {
    NodeWeights w;
    for (auto [k, v] : d)
      for (auto [j, x] : v.cast<py::dict>())
        w[k.cast<std::string>()][j.cast<std::string>()] = x.cast<double>();
    return w;
  }));
  py::implicitly_convertible<py::dict, NodeWeights>();

  py::class_<Rig>(m, "Rig", "The logical Curvenet: nodes, profiles, skeleton and node weights")
      .def(py::init<>())
      .def_property(
          "coverage", [](const Rig& r) { return std::string(to_string(r.coverage)); },
          [](Rig& r, const std::string& s) { r.coverage = coverage_from(s); })
      .def_property(
          "frame",
          py::cpp_function([](Rig& x) -> Mat4& { return x.frame; }, py::return_value_policy::reference_internal),
          [](Rig& x, const Mat4& v) { x.frame = v; })
      .def_readwrite("nodes", &Rig::nodes)
      .def_readwrite("profiles", &Rig::profiles)
      .def_readwrite("joints", &Rig::joints)
      .def_readwrite("has_skeleton", &Rig::has_skeleton)
      .def_readwrite("weights", &Rig::weights)
      .def_readwrite("extensions", &Rig::extensions)
      .def("node_index", &Rig::node_index, py::arg("id"))
      .def(
          "node",
          [](Rig& r, const std::string& id) -> Node& {
            const int i = r.node_index(id);
            if (i < 0)
              throw py::key_error("no node '" + id + "'");
            return r.nodes[i];
          },
          py::return_value_policy::reference_internal, py::arg("id"))
      .def(
          "profile",
          [](Rig& r, const std::string& id) -> Profile& {
            for (auto& p : r.profiles)
              if (p.id == id)
                return p;
            throw py::key_error("no profile '" + id + "'");
          },
          py::return_value_policy::reference_internal, py::arg("id"))
      .def(
          "add_node",
          [](Rig& r, const std::string& id, const Vec3& position) -> Node& {
            if (r.node_index(id) >= 0)
              throw py::value_error("a node '" + id + "' exists already");
            r.nodes.push_back({id, position});
            return r.nodes.back();
          },
          py::return_value_policy::reference_internal, py::arg("id"), py::arg("position"))
      .def(
          "add_profile",
          [](Rig& r, const std::string& id, const std::string& from, const std::string& to,
             const py::object& points) -> Profile& {
            for (const auto& p : r.profiles)
              if (p.id == id)
                throw py::value_error("a profile '" + id + "' exists already");
            const int a = r.node_index(from), b = r.node_index(to);
            if (a < 0 || b < 0)
              throw py::key_error("no node '" + (a < 0 ? from : to) + "'");
            Profile p{id, from, to, {}};
            if (points.is_none())
              p.curve.points = {r.nodes[a].position, r.nodes[b].position}; // straight, node to node
            else
              p.curve.points = points_from(points, "points");
            r.profiles.push_back(std::move(p));
            return r.profiles.back();
          },
          py::return_value_policy::reference_internal, py::arg("id"), py::arg("from_"), py::arg("to"),
          py::arg("points") = py::none())
      .def("to_json", [](const Rig& r) { return rig_to_json(r); })
      .def_static("from_json", &parse_rig, py::arg("text"), py::arg("source") = "<string>")
      .def("copy", [](const Rig& r) { return Rig(r); })
      .def("__copy__", [](const Rig& r) { return Rig(r); })
      .def("__deepcopy__", [](const Rig& r, py::dict) { return Rig(r); })
      .def("__repr__", [](const Rig& r) {
        return "<curvenet.Rig: " + std::to_string(r.nodes.size()) + " nodes, " + std::to_string(r.profiles.size()) +
               " profiles, " + std::to_string(r.joints.size()) + " joints>";
      });
  m.def("read_rig", &read_rig, py::arg("path"));
  m.def("write_rig", &write_rig, py::arg("rig"), py::arg("path"));
  m.def("parse_rig", &parse_rig, py::arg("text"), py::arg("source") = "<string>");
  m.def("rig_to_json", &rig_to_json, py::arg("rig"));
  m.def("validate_rig", &validate_rig, py::arg("rig"), py::arg("source") = "rig");

  // The net editor (edit.hpp): each returns the edited copy, validated.
  m.def("remove_nodes", &remove_nodes, py::arg("rig"), py::arg("nodes"), py::arg("source") = "rig",
        "The rig without these nodes, their profiles and their weights");
  m.def("remove_profiles", &remove_profiles, py::arg("rig"), py::arg("profiles"), py::arg("source") = "rig",
        "The rig without these profiles (and the nodes they leave on no profile)");
  m.def("move_node", &move_node, py::arg("rig"), py::arg("node"), py::arg("position"), py::arg("source") = "rig",
        "The rig with the node moved; its curves' ends follow, the displacement fading along them");
  m.def(
      "split_profile",
      [](const Rig& rig, const std::string& profile, double t, const std::string& source) {
        SplitResult r = split_profile(rig, profile, t, source);
        return py::make_tuple(std::move(r.rig), r.node, r.profile);
      },
      py::arg("rig"), py::arg("profile"), py::arg("t"), py::arg("source") = "rig",
      "(rig, new node, new profile): a node inserted on the profile at normalised arc length t");
  m.def("nearest_parameter", &nearest_parameter, py::arg("rig"), py::arg("profile"), py::arg("point"),
        py::arg("source") = "rig", "The normalised arc length of the profile's point nearest to `point`");
  m.def("merge_nodes", &merge_nodes, py::arg("rig"), py::arg("kept"), py::arg("merged"), py::arg("source") = "rig",
        "The rig with node `merged` merged into `kept`");
  m.def(
      "reroute_profile",
      [](const Rig& rig, const std::string& profile, const py::object& via, const std::string& source) {
        return reroute_profile(rig, profile, via.is_none() ? std::vector<Vec3>{} : points_from(via, "via"), source);
      },
      py::arg("rig"), py::arg("profile"), py::arg("via"), py::arg("source") = "rig",
      "The rig with the profile's curve running from its first node through `via` (k, 3) to its last");
  m.def("set_joint_weight", &set_joint_weight, py::arg("rig"), py::arg("nodes"), py::arg("joint"), py::arg("weight"),
        py::arg("source") = "rig",
        "The rig with the joint's weight set on the nodes, their other joints scaled to sum to 1");

  // Embedding.
  py::class_<Embedding>(m, "Embedding", "One rig embedded in one mesh")
      .def_property_readonly("report", [](const Embedding& e) { return from_json(report_to_json(e.report())); })
      .def_property_readonly("ok", [](const Embedding& e) { return e.report().ok; })
      .def_property_readonly("face_regions", [](const Embedding& e) { return vector_array(e.face_regions()); })
      .def_property_readonly("face_colours",
                             [](const Embedding& e) {
                               const auto n = static_cast<py::ssize_t>(e.face_regions().size());
                               py::array_t<uint8_t> a({n, py::ssize_t{3}});
                               auto w = a.mutable_unchecked<2>();
                               for (py::ssize_t f = 0; f < n; ++f) {
                                 const auto c = e.face_colour(static_cast<int>(f));
                                 for (int k = 0; k < 3; ++k)
                                   w(f, k) = static_cast<uint8_t>(c[k]);
                               }
                               return a;
                             })
      .def(
          "cut_mesh",
          [](const Embedding& e) {
            const RawMesh r = e.cut_mesh();
            return py::make_tuple(points_array(r.positions), vector_array(r.face_offsets),
                                  vector_array(r.face_vertices));
          },
          "(vertices (n, 3), face_offsets (m + 1,), face_vertices): the cut mesh's polygons")
      .def_property_readonly("chains",
                             [](const Embedding& e) {
                               py::dict d; // in rig order
                               for (const auto& [id, pts] : e.chains())
                                 d[py::str(id)] = points_array(pts);
                               return d;
                             })
      .def("cut_mesh_obj", [](const Embedding& e) { return e.cut_mesh_obj(); })
      .def("regions_ply", &Embedding::regions_ply);

  m.def(
      "embed",
      [](const SurfaceMesh& mesh, const Rig& rig, double density, bool cage, long long max_samples,
         std::optional<std::string> coverage, std::optional<py::function> progress) {
        EmbedKwargs kw{density, cage, max_samples, std::move(coverage), std::move(progress)};
        checked(rig);
        return call_released(kw, [&](const EmbedOptions& o) { return embed(mesh, rig, o); });
      },
      py::arg("mesh"), py::arg("rig"), py::kw_only(), py::arg("density") = 5.0, py::arg("cage") = false,
      py::arg("max_samples") = 20'000'000LL, py::arg("coverage") = py::none(), py::arg("progress") = py::none());
  m.def(
      "trace_profiles",
      [](const SurfaceMesh& mesh, const Rig& rig, double density, bool cage) {
        EmbedKwargs kw;
        kw.density = density;
        kw.cage = cage;
        checked(rig);
        const auto paths = call_released(kw, [&](const EmbedOptions& o) { return trace_profiles(mesh, rig, o); });
        py::list out;
        for (const auto& p : paths)
          out.append(points_array(p));
        return out;
      },
      py::arg("mesh"), py::arg("rig"), py::kw_only(), py::arg("density") = 5.0, py::arg("cage") = false);

  // Binding and deformation.
  py::class_<PyBinding>(m, "Binding", "A rig bound to a mesh: deforms it through the Curvenet")
      .def_property_readonly("joints", [](const PyBinding& b) { return b.binding.joints(); })
      .def_property_readonly("joint_names",
                             [](const PyBinding& b) {
                               std::vector<std::string> names;
                               for (const auto& j : b.binding.joints())
                                 names.push_back(j.name);
                               return names;
                             })
      .def_property_readonly("report", [](const PyBinding& b) { return from_json(report_to_json(b.binding.report())); })
      .def_property_readonly("node_weights", [](const PyBinding& b) { return b.binding.node_weights(); })
      .def_property_readonly("num_input_vertices", [](const PyBinding& b) { return b.binding.num_input_vertices(); })
      .def_property_readonly("has_embedding", [](const PyBinding& b) { return b.binding.has_embedding(); })
      .def_property_readonly("method", [](const PyBinding& b) { return to_string(b.binding.method()); })
      .def_property_readonly("embedding",
                             [](const PyBinding& b) {
                               if (!b.binding.has_embedding())
                                 throw py::value_error("a binding read from a cache file has no embedding");
                               return b.binding.embedding();
                             })
      .def(
          "save", [](const PyBinding& b, const std::string& path) { b.binding.save(path); }, py::arg("path"))
      .def(
          "deform",
          [](PyBinding& b, const py::array_t<double, py::array::c_style | py::array::forcecast>& skinning,
             std::optional<py::array> out) -> py::object {
            const size_t nj = b.binding.joints().size(), nv = static_cast<size_t>(b.binding.num_input_vertices());
            if (skinning.ndim() != 3 || static_cast<size_t>(skinning.shape(0)) != nj || skinning.shape(1) != 4 ||
                skinning.shape(2) != 4)
              throw py::value_error("skinning: expected a (" + std::to_string(nj) + ", 4, 4) array, one per joint");
            matrices_into(skinning, b.matrices);
            b.positions.resize(nv);
            b.binding.deform(b.matrices, b.positions);
            check_finite_output(b.positions.cbegin(), nv, 0, false);
            py::array result;
            if (out) {
              result = *out;
              if (result.ndim() != 2 || static_cast<size_t>(result.shape(0)) != nv || result.shape(1) != 3 ||
                  !(result.flags() & py::array::c_style) || !result.writeable())
                throw py::value_error("out: expected a writable C-contiguous (" + std::to_string(nv) + ", 3) array");
            } else {
              result = py::array_t<double>({static_cast<py::ssize_t>(nv), py::ssize_t{3}});
            }
            if (result.dtype().is(py::dtype::of<double>())) {
              std::memcpy(result.mutable_data(), b.positions.data(), nv * 3 * sizeof(double));
            } else if (result.dtype().is(py::dtype::of<float>())) {
              auto* dst = static_cast<float*>(result.mutable_data());
              for (size_t i = 0; i < nv; ++i)
                for (int c = 0; c < 3; ++c)
                  dst[3 * i + c] = static_cast<float>(b.positions[i][c]);
            } else {
              throw py::value_error("out: expected a float64 or float32 array");
            }
            return std::move(result);
          },
          py::arg("skinning"), py::arg("out") = py::none(),
          "Positions (n, 3), one per input vertex, for skinning matrices (J, 4, 4)")
      .def(
          "deform_frames",
          [](const PyBinding& b, const py::array_t<double, py::array::c_style | py::array::forcecast>& skinning) {
            const size_t nj = b.binding.joints().size(), nv = static_cast<size_t>(b.binding.num_input_vertices());
            if (skinning.ndim() != 4 || static_cast<size_t>(skinning.shape(1)) != nj || skinning.shape(2) != 4 ||
                skinning.shape(3) != 4)
              throw py::value_error("skinning: expected an (F, " + std::to_string(nj) + ", 4, 4) array");
            const size_t frames = static_cast<size_t>(skinning.shape(0));
            std::vector<Mat4> M;
            matrices_into(skinning, M);
            py::array_t<double> result(
                {static_cast<py::ssize_t>(frames), static_cast<py::ssize_t>(nv), py::ssize_t{3}});
            auto* dst = reinterpret_cast<Vec3*>(result.mutable_data());
            {
              py::gil_scoped_release release;
              b.binding.deform_frames(M, std::span<Vec3>(dst, frames * nv));
            }
            for (size_t i = 0; i < frames * nv; ++i)
              if (!dst[i].allFinite())
                throw InputError("skinning", "frame " + std::to_string(i / nv) + " vertex " + std::to_string(i % nv),
                                 "the pose moves it out of range (not a finite number)");
            return result;
          },
          py::arg("skinning"), "Positions (F, n, 3) for skinning matrices (F, J, 4, 4), frames in parallel");

  m.def(
      "bind",
      [](const SurfaceMesh& mesh, const Rig& rig, const std::string& laplacian, const std::string& rigid,
         const std::string& weight_rule, double blend, double density, std::optional<std::string> cache,
         const std::string& method, bool cut_aware, const std::string& rotation, bool curve_frames,
         const std::string& interior) {
        BindOptions o;
        o.curve_frames = curve_frames;
        if (!parse_interior_weights(interior, o.interior))
          throw py::value_error("interior: expected 'bone-heat' or 'harmonic', got '" + interior + "'");
        if (rotation != "polar" && rotation != "quaternion")
          throw py::value_error("rotation: expected 'polar' or 'quaternion'");
        o.rotation_blend =
            rotation == "quaternion" ? BindOptions::RotationBlend::Quaternion : BindOptions::RotationBlend::Polar;
        if (!parse_deform_method(method, o.method))
          throw py::value_error("method: expected 'dq', 'harmonic' or 'gradient', got '" + method + "'");
        o.cut_aware = cut_aware;
        if (laplacian != "intrinsic" && laplacian != "uniform")
          throw py::value_error("laplacian: expected 'intrinsic' or 'uniform'");
        if (rigid != "per-vertex" && rigid != "horn")
          throw py::value_error("rigid: expected 'per-vertex' or 'horn'");
        o.laplacian = laplacian == "uniform" ? LaplacianChoice::Uniform : LaplacianChoice::IntrinsicDelaunay;
        o.rigid = rigid == "horn" ? RigidMode::Horn : RigidMode::PerVertex;
        o.weights = weight_options(weight_rule, blend);
        o.embed.density = density;
        checked(rig);
        py::gil_scoped_release release;
        return PyBinding{cache ? bind_cached(mesh, rig, o, *cache) : bind(mesh, rig, o), {}, {}};
      },
      py::arg("mesh"), py::arg("rig"), py::kw_only(), py::arg("laplacian") = "intrinsic",
      py::arg("rigid") = "per-vertex", py::arg("weight_rule") = "blend-zone", py::arg("blend") = 0.3,
      py::arg("density") = 5.0, py::arg("cache") = py::none(), py::arg("method") = "dq", py::arg("cut_aware") = true,
      py::arg("rotation") = "polar", py::arg("curve_frames") = false, py::arg("interior") = "bone-heat");
  m.def(
      "complete_weights",
      [](const Rig& rig, const std::string& weight_rule, double blend) {
        return complete_weights(checked(rig), weight_options(weight_rule, blend));
      },
      py::arg("rig"), py::kw_only(), py::arg("weight_rule") = "blend-zone", py::arg("blend") = 0.3);

  // Starter, transfer, compare, subdivide.
  py::class_<StarterResult>(m, "StarterResult")
      .def_readonly("rig", &StarterResult::rig)
      .def_readonly("messages", &StarterResult::messages)
      .def_readonly("rings", &StarterResult::rings)
      .def_readonly("joins", &StarterResult::joins)
      .def_readonly("unjoined", &StarterResult::unjoined)
      .def_readonly("net_components", &StarterResult::net_components)
      .def_readonly("ringless", &StarterResult::ringless);
  m.def(
      "starter",
      [](const SurfaceMesh& mesh, const py::object& skeleton, int nodes_per_ring, int rings_per_bone,
         const std::string& coverage, double first_angle, const std::string& weight_rule, double blend,
         const py::object& deforming, bool middle_nodes) {
        std::vector<Joint> joints;
        StarterOptions o;
        o.middle_nodes = middle_nodes;
        std::optional<SkinnedMesh> file_skin; // a skinned file's, read here
        const SkinnedMesh* skin = nullptr;
        std::string placed_note;
        if (py::isinstance<py::str>(skeleton)) { // a file, read once: its joints, and which its skin weights
          const std::string path = skeleton.cast<std::string>();
          py::gil_scoped_release release;
          SkeletonFile f = read_skeleton_file(path, mesh); // placed for the mesh, as the CLI's --skeleton
          joints = std::move(f.joints);
          o.deforming = std::move(f.deforming);
          placed_note = std::move(f.note);
          if (weight_rule == "auto" || weight_rule == "skin")
            if (is_skinned_file(path)) {
              file_skin = load_skinned_mesh(path);
              skin = &*file_skin;
            }
        } else {
          joints = joints_from(skeleton);
          if (py::isinstance<SkinnedMesh>(skeleton)) { // a skin says which joints deform, and weights the nodes
            skin = &skeleton.cast<const SkinnedMesh&>();
            o.deforming = weighted_joints(*skin);
          }
        }
        // The skin weights the nodes when it is this mesh's (by its vertex count).
        if (skin && (weight_rule == "auto" || weight_rule == "skin") &&
            (weight_rule == "skin" || skin->vertex_joint.size() == mesh.input_to_welded.size()))
          o.skin = skin;
        if (weight_rule == "skin" && !o.skin)
          throw py::value_error("weight_rule 'skin': the skeleton has no skin (give a SkinnedMesh or a skinned file)");
        if (!deforming.is_none()) {
          o.deforming.clear();
          for (const auto& name : deforming.cast<std::vector<std::string>>())
            o.deforming.insert(name);
        }
        if (nodes_per_ring < 2 || nodes_per_ring > 64)
          throw py::value_error("nodes_per_ring: expected 2 to 64, as the CLI takes");
        if (rings_per_bone < 1 || rings_per_bone > 16)
          throw py::value_error("rings_per_bone: expected 1 to 16");
        if (!std::isfinite(first_angle))
          throw py::value_error("first_angle: expected a finite number");
        o.nodes_per_ring = nodes_per_ring;
        o.rings_per_bone = rings_per_bone;
        o.coverage = coverage_from(coverage);
        o.first_angle_deg = first_angle;
        o.weights = weight_options(weight_rule == "auto" || weight_rule == "skin" ? "blend-zone" : weight_rule, blend);
        py::gil_scoped_release release;
        StarterResult r = make_starter(mesh, joints, o);
        if (!placed_note.empty())
          r.messages.insert(r.messages.begin(), placed_note);
        return r;
      },
      py::arg("mesh"), py::arg("skeleton"), py::kw_only(), py::arg("nodes_per_ring") = 4, py::arg("rings_per_bone") = 1,
      py::arg("coverage") = "auto", py::arg("first_angle") = 0.0, py::arg("weight_rule") = "auto",
      py::arg("blend") = 0.3, py::arg("deforming") = py::none(), py::arg("middle_nodes") = true);

  py::class_<TransferResult>(m, "TransferResult")
      .def_readonly("rig", &TransferResult::rig)
      .def_property_readonly("report",
                             [](const TransferResult& r) { return from_json(transfer_report_json(r.report)); })
      .def_property_readonly("ok", [](const TransferResult& r) { return r.report.ok; })
      .def_property_readonly("agreement", [](const TransferResult& r) { return r.report.agreement; });
  m.def(
      "transfer",
      [](const Rig& rig, const SurfaceMesh& source, const SurfaceMesh& target, const py::object& source_frame,
         const py::object& target_frame, double max_offset, int source_cage_levels, int target_cage_levels,
         long long max_faces, double density, const std::string& align, const py::object& source_skeleton,
         const py::object& target_skeleton) {
        TransferOptions o;
        o.alignment = parse_alignment(align, "align");
        if (!source_skeleton.is_none())
          o.source_skeleton = joints_from(source_skeleton);
        if (!target_skeleton.is_none())
          o.target_skeleton = joints_from(target_skeleton);
        if (!source_frame.is_none())
          o.source_frame = matrix_from(source_frame, "source_frame");
        if (!target_frame.is_none())
          o.target_frame = matrix_from(target_frame, "target_frame");
        if (!(max_offset > 0 && max_offset <= 1))
          throw py::value_error("max_offset: expected a fraction in (0, 1]");
        o.max_offset = max_offset;
        o.source_cage_levels = source_cage_levels;
        o.target_cage_levels = target_cage_levels;
        o.max_faces = max_faces;
        o.embed.density = density;
        checked(rig);
        py::gil_scoped_release release;
        return transfer(rig, source, target, o);
      },
      py::arg("rig"), py::arg("source"), py::arg("target"), py::kw_only(), py::arg("source_frame") = py::none(),
      py::arg("target_frame") = py::none(), py::arg("max_offset") = 0.05, py::arg("source_cage_levels") = 0,
      py::arg("target_cage_levels") = 0, py::arg("max_faces") = 4'000'000LL, py::arg("density") = 5.0,
      py::arg("align") = "auto", py::arg("source_skeleton") = py::none(), py::arg("target_skeleton") = py::none());
  m.def(
      "compare",
      [](const SurfaceMesh& a, const SurfaceMesh& b, int samples_per_edge) {
        if (samples_per_edge < 1 || samples_per_edge > 64)
          throw py::value_error("samples_per_edge: expected 1 to 64");
        SurfaceDistance d;
        {
          py::gil_scoped_release release;
          d = surface_distance(a, b, samples_per_edge);
        }
        return distance_dict(d);
      },
      py::arg("a"), py::arg("b"), py::kw_only(), py::arg("samples_per_edge") = 4);
  m.def(
      "subdivide",
      [](const SurfaceMesh& cage, int levels, long long max_faces) {
        py::gil_scoped_release release;
        return catmull_clark(cage, levels, max_faces);
      },
      py::arg("cage"), py::arg("levels") = 2, py::kw_only(), py::arg("max_faces") = 4'000'000LL);

  // Skeletons, skins, poses and clips.
  py::class_<JointPose>(m, "JointPose", "A joint's pose entry L = T R S against its rest pose")
      .def(py::init<>())
      .def_property("translation",
                    py::cpp_function([](JointPose& x) -> Eigen::Vector3d& { return x.translation; },
                                     py::return_value_policy::reference_internal),
                    [](JointPose& x, const Eigen::Vector3d& v) { x.translation = v; })
      .def_property(
          "rotation",
          [](const JointPose& p) {
            return Eigen::Vector4d(p.rotation.w(), p.rotation.x(), p.rotation.y(), p.rotation.z());
          },
          [](JointPose& p, const Eigen::Vector4d& q) {
            if (!q.allFinite() || std::abs(q.norm() - 1) > 1e-6)
              throw py::value_error("rotation: expected a unit quaternion (w, x, y, z)");
            p.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
          },
          "unit quaternion (w, x, y, z)")
      .def_property("scale",
                    py::cpp_function([](JointPose& x) -> Eigen::Vector3d& { return x.scale; },
                                     py::return_value_policy::reference_internal),
                    [](JointPose& x, const Eigen::Vector3d& v) { x.scale = v; })
      .def("matrix", &JointPose::matrix);
  py::class_<SkinnedMesh>(m, "SkinnedMesh", "A file's own skeleton, skin weights and clips")
      .def_static(
          "from_weights",
          [](const std::vector<Joint>& joints, const py::object& joint, const py::object& weight,
             const std::string& source) {
            const Indices j = Indices::ensure(joint);
            const Points w = Points::ensure(weight);
            if (!j || !w || j.ndim() != 2 || w.ndim() != 2 || j.shape(0) != w.shape(0) || j.shape(1) != 4 ||
                w.shape(1) != 4)
              throw py::value_error("joint and weight: expected two (n, 4) arrays");
            SkinnedMesh s;
            s.joints = joints;
            s.source = source;
            for (const Joint& jt : joints)
              s.inverse_bind.push_back(jt.bind.inverse());
            for (py::ssize_t v = 0; v < j.shape(0); ++v) {
              std::array<int, 4> jj{};
              std::array<double, 4> ww{};
              for (int k = 0; k < 4; ++k) {
                jj[k] = j.at(v, k);
                ww[k] = w.at(v, k);
                if (jj[k] < -1 || jj[k] >= static_cast<int>(joints.size()))
                  throw InputError(source, "vertex " + std::to_string(v), "names no joint");
                if (!std::isfinite(ww[k]) || ww[k] < 0)
                  throw InputError(source, "vertex " + std::to_string(v), "has a weight that is not finite or >= 0");
              }
              s.vertex_joint.push_back(jj);
              s.vertex_weight.push_back(ww);
            }
            return s;
          },
          py::arg("joints"), py::arg("joint"), py::arg("weight"), py::arg("source") = "weights",
          "A skin from weights: (n, 4) joint indices (-1 unused) and weights per vertex, over `joints` (a Blender "
          "mesh's vertex groups, say)")
      .def_readonly("joints", &SkinnedMesh::joints)
      .def_readonly("clip_names", &SkinnedMesh::clip_names)
      .def_readonly("source", &SkinnedMesh::source)
      .def_property_readonly("num_clips", &SkinnedMesh::num_clips)
      .def("find_clip", &SkinnedMesh::find_clip, py::arg("name_or_index"))
      .def("clip_range", &SkinnedMesh::clip_range, py::arg("clip"))
      .def(
          "skinning_matrices",
          [](const SkinnedMesh& s, int clip, double t) { return matrices_array(s.skinning_matrices(clip, t)); },
          py::arg("clip"), py::arg("t"), "The file's own skinning matrices (J, 4, 4) at time t of a clip")
      .def_property_readonly(
          "vertex_joints",
          [](const SkinnedMesh& s) { return table_array(s.vertex_joint.data()->data(), s.vertex_joint.size(), 4); })
      .def_property_readonly("vertex_weights", [](const SkinnedMesh& s) {
        return table_array(s.vertex_weight.data()->data(), s.vertex_weight.size(), 4);
      });
  m.def(
      "load_skinned_mesh",
      [](const std::string& path) {
        py::gil_scoped_release release;
        return load_skinned_mesh(path);
      },
      py::arg("path"));
  m.def(
      "load_skeleton",
      [](const std::string& path, const py::object& mesh) {
        if (mesh.is_none()) {
          py::gil_scoped_release release;
          return load_skeleton(path);
        }
        const SurfaceMesh& for_mesh = mesh.cast<const SurfaceMesh&>();
        SkeletonFile file;
        {
          py::gil_scoped_release release;
          file = read_skeleton_file(path, for_mesh);
        }
        // The note `curvenet --skeleton` prints when it takes the scene's placing.
        if (!file.note.empty() && PyErr_WarnEx(PyExc_UserWarning, file.note.c_str(), 1) != 0)
          throw py::error_already_set(); // warnings turned into errors
        return file.joints;
      },
      py::arg("path"), py::arg("mesh") = py::none(),
      "The joints of a rig or skinned file, as bound; with `mesh`, placed for it as the CLI's --skeleton places "
      "them (a Blender glTF whose scene places its skeleton, for a mesh in the scene's space), with a "
      "UserWarning saying so when the scene's placing is taken");
  m.def(
      "with_skeleton",
      [](const Rig& rig, const py::object& skeleton, const std::string& source) {
        return with_skeleton(checked(rig), joints_from(skeleton), source);
      },
      py::arg("rig"), py::arg("skeleton"), py::arg("source") = "skeleton");
  m.def("read_pose", &read_pose, py::arg("path"));
  m.def(
      "skinning_matrices",
      [](const py::object& skeleton, const py::object& pose) {
        return matrices_array(skinning_matrices(joints_from(skeleton), pose_from(pose), "pose"));
      },
      py::arg("skeleton"), py::arg("pose"),
      "Skinning matrices (J, 4, 4) for a pose (a pose file, a dict of entries, or a pose file's dict)");
  m.def("pose_from_clip", &pose_from_clip, py::arg("skin"), py::arg("clip"), py::arg("t"));
  m.def(
      "clip_skinning_matrices",
      [](const py::object& skeleton, const SkinnedMesh& clips, int clip, double t) {
        if (clip < 0 || clip >= clips.num_clips())
          throw py::index_error("clip " + std::to_string(clip) + " out of range");
        return matrices_array(clip_skinning_matrices(joints_from(skeleton), clips, clip, t));
      },
      py::arg("skeleton"), py::arg("clips"), py::arg("clip"), py::arg("t"));
  m.def(
      "clip_notes",
      [](const py::object& skeleton, const SkinnedMesh& clips) { return clip_notes(joints_from(skeleton), clips); },
      py::arg("skeleton"), py::arg("clips"),
      "What `curvenet animate` and `bake` note of a clip file against the skeleton, one line each: the joints it "
      "lacks, and a skeleton that is not this one (a bone 5 % longer or shorter, or turned more than 10 degrees)");
  m.def(
      "clip_frames",
      [](const SkinnedMesh& clips, int clip, double fps) {
        if (clip < 0 || clip >= clips.num_clips())
          throw py::index_error("clip " + std::to_string(clip) + " out of range");
        if (!(fps > 0 && fps <= 10000))
          throw py::value_error("fps: expected a number in (0, 10000]");
        return clip_frames(clips, clip, fps);
      },
      py::arg("clips"), py::arg("clip"), py::arg("fps") = 24.0);
  m.def(
      "animate",
      [](const PyBinding& b, const SkinnedMesh& clips, int clip, const std::string& path, double fps,
         const std::string& frames, long long max_frames) {
        if (clip < 0 || clip >= clips.num_clips())
          throw py::index_error("clip " + std::to_string(clip) + " out of range");
        if (!(fps > 0 && fps <= 10000))
          throw py::value_error("fps: expected a number in (0, 10000]");
        const FrameRange range = frame_range(clips, clip, fps, frames, max_frames);
        (void)clip_skinning_matrices(b.binding.joints(), clips, clip, range.time(range.first)); // joints match
        // What `curvenet animate` prints as notes, as Python warnings.
        for (const std::string& note : clip_notes(b.binding.joints(), clips))
          if (PyErr_WarnEx(PyExc_UserWarning, note.c_str(), 1) != 0)
            throw py::error_already_set(); // warnings turned into errors
        {
          py::gil_scoped_release release;
          OutputFiles files;
          Pc2Sink pc2(files, path, b.binding.num_input_vertices(), range, clips.source);
          FrameSink* sinks[] = {&pc2};
          animate(b.binding, clips, clip, range, sinks);
          files.commit();
        }
        return std::make_pair(range.first, range.last);
      },
      py::arg("binding"), py::arg("clips"), py::arg("clip"), py::arg("path"), py::kw_only(), py::arg("fps") = 24.0,
      py::arg("frames") = "", py::arg("max_frames") = 100000LL,
      "Writes clip `clip` deformed through the binding as a PC2 cache at `path`, streamed in blocks (the same "
      "frames as `curvenet animate`); returns the (first, last) frame. Each of clip_notes(binding, clips) is first "
      "given as a UserWarning, as the CLI prints it as a note");

  m.def(
      "animate_poses",
      [](const py::object& deformer, const py::function& pose, int first, int last, const std::string& path,
         double fps) {
        if (last < first)
          throw InputError("frames", std::to_string(first) + ":" + std::to_string(last),
                           "the last frame comes before the first");
        const FrameRange range{first, last, fps};
        const bool is_layer = py::isinstance<CurveLayer>(deformer);
        if (!is_layer && !py::isinstance<PyBinding>(deformer))
          throw py::type_error("animate_poses: expected a Binding or a CurveLayer");
        const Binding* binding = is_layer ? nullptr : &deformer.cast<const PyBinding&>().binding;
        const CurveLayer* layer = is_layer ? &deformer.cast<const CurveLayer&>() : nullptr;
        const size_t nj = is_layer ? layer->joints().size() : binding->joints().size();
        // pose(frame): matrices; for a layer, or (matrices, envelope, offsets).
        auto frame_pose = [&](int frame) {
          py::gil_scoped_acquire acquire; // the caller's function runs with the interpreter
          const std::string name = "pose(" + std::to_string(frame) + ")";
          LayerFrame f;
          py::object m = pose(frame);
          if (is_layer && py::isinstance<py::tuple>(m)) {
            const auto t = m.cast<py::tuple>();
            if (t.size() != 3)
              throw py::value_error(name + ": expected matrices, or (matrices, envelope, offsets)");
            f.envelope = t[1].cast<double>();
            if (!t[2].is_none())
              f.offsets = t[2].cast<NodeOffsets>();
            m = t[0];
          }
          const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(m);
          if (!a || a.ndim() != 3 || static_cast<size_t>(a.shape(0)) != nj || a.shape(1) != 4 || a.shape(2) != 4)
            throw py::value_error(name + ": expected a (" + std::to_string(nj) + ", 4, 4) array");
          matrices_into(a, f.skinning);
          return f;
        };
        py::gil_scoped_release release;
        OutputFiles files;
        Pc2Sink pc2(files, path, is_layer ? layer->num_input_vertices() : binding->num_input_vertices(), range);
        FrameSink* sinks[] = {&pc2};
        if (is_layer)
          animate(*layer, frame_pose, range, sinks, "pose");
        else
          animate(
              *binding, [&](int frame) { return frame_pose(frame).skinning; }, range, sinks, "pose");
        files.commit();
      },
      py::arg("deformer"), py::arg("pose"), py::arg("first"), py::arg("last"), py::arg("path"), py::kw_only(),
      py::arg("fps") = 24.0,
      "Writes frames first..last as a PC2 cache at `path`, `pose(frame)` giving each frame's (J, 4, 4) skinning "
      "matrices: the frame job `animate` runs, in blocks of bounded memory, all or nothing. The deformer is a "
      "Binding, or a CurveLayer, whose pose(frame) may give (matrices, envelope, offsets) instead");

  // The layer (layer.hpp): over the mesh's own skin, node offsets.
  py::class_<CurveLayer>(m, "CurveLayer",
                         "The net as a layer over the mesh's own skin, or over its own deformation (docs/deform.md)")
      .def_property_readonly("joint_names",
                             [](const CurveLayer& l) {
                               std::vector<std::string> names;
                               for (const auto& j : l.joints())
                                 names.push_back(j.name);
                               return names;
                             })
      .def_property_readonly("joints", &CurveLayer::joints)
      .def_property_readonly("num_input_vertices", &CurveLayer::num_input_vertices)
      .def_property_readonly("over_skin", &CurveLayer::over_skin)
      .def(
          "with_mask",
          [](const CurveLayer& l, const std::optional<std::vector<double>>& mask) {
            return l.with_mask(mask ? *mask : std::vector<double>());
          },
          py::arg("mask"),
          "The same layer (its binding shared, nothing solved again) with another mask: one value from 0 to 1 per "
          "input vertex, or None for all of the correction")
      .def(
          "region_mask",
          [](const CurveLayer& l, const std::map<std::string, double>& values, double others, double falloff) {
            const std::vector<double> m = l.region_mask(values, others, falloff);
            return py::array_t<double>(static_cast<py::ssize_t>(m.size()), m.data());
          },
          py::arg("values"), py::arg("others") = 1.0, py::arg("falloff") = 0.0,
          "A mask by region, for with_mask: {region key: 0 to 1} (the keys of binding.embedding.report, "
          "\"profile:L|profile:R\"), every other region `others`; a vertex takes the largest value around it. "
          "`falloff` (a fraction of the diagonal): a region's value rises smoothly towards a larger one over that "
          "distance from their curves")
      .def_property_readonly(
          "mask",
          [](const CurveLayer& l) {
            return py::array_t<double>(static_cast<py::ssize_t>(l.mask().size()), l.mask().data());
          },
          "(n,) per input vertex, or empty: all of the correction")
      .def_property_readonly(
          "binding",
          [](const CurveLayer& l) {
            return PyBinding{l.binding(), {}, {}};
          },
          "The net's own binding")
      .def(
          "deform",
          [](const CurveLayer& l, const py::array_t<double, py::array::c_style | py::array::forcecast>& skinning,
             double envelope, const std::optional<std::map<std::string, Vec3>>& offsets) {
            return layer_positions(l, skinning, envelope, offsets, &CurveLayer::deform);
          },
          py::arg("skinning"), py::kw_only(), py::arg("envelope") = 1.0, py::arg("offsets") = py::none(),
          "Positions (n, 3), one per input vertex: the base moved by skinning matrices (J, 4, 4), plus envelope times "
          "the masked correction; offsets: node id -> (3,) offset in rest space")
      .def(
          "rest_correction",
          [](const CurveLayer& l, const py::array_t<double, py::array::c_style | py::array::forcecast>& skinning,
             double envelope, const std::optional<std::map<std::string, Vec3>>& offsets) {
            return layer_positions(l, skinning, envelope, offsets, &CurveLayer::rest_correction);
          },
          py::arg("skinning"), py::kw_only(), py::arg("envelope") = 1.0, py::arg("offsets") = py::none(),
          "Over a skin: (n, 3) displacements in rest space that the skin moves to the layered result (a corrective "
          "shape key under Blender's Armature modifier)");
  m.def(
      "bind_layer",
      [](const SurfaceMesh& mesh, const Rig& rig, const std::optional<SkinnedMesh>& skin, const std::string& skinning,
         const std::optional<std::vector<double>>& mask, const std::string& method) {
        LayerOptions o;
        if (!parse_deform_method(method, o.bind.method))
          throw py::value_error("method: expected 'dq', 'harmonic' or 'gradient', got '" + method + "'");
        if (skinning != "linear" && skinning != "dq")
          throw py::value_error("skinning: expected 'linear' or 'dq'");
        o.skinning = skinning == "dq" ? Skinning::DualQuaternion : Skinning::Linear;
        if (mask)
          o.mask = *mask;
        validate_rig(rig, "rig");
        py::gil_scoped_release release;
        return bind_layer(mesh, rig, skin ? &*skin : nullptr, o);
      },
      py::arg("mesh"), py::arg("rig"), py::kw_only(), py::arg("skin") = py::none(), py::arg("skinning") = "linear",
      py::arg("mask") = py::none(), py::arg("method") = "dq",
      "Binds the rig as a layer over `skin` (the mesh's own SkinnedMesh: linear or dq skinning with its weights), or "
      "over the net's own deformation; mask: one value from 0 to 1 per input vertex");
  m.def(
      "read_pose_nodes", [](const std::string& path) { return read_pose_file(path).nodes; }, py::arg("path"),
      "The node offsets of a pose file (version 2): node id -> (3,) offset in rest space");

  // The farm (farm.hpp): a Slurm array job of animate's shards, for pipeline tools.
  m.def(
      "farm_submit",
      [](const std::string& mesh, const std::string& rig, const std::string& clip_file, const std::string& folder,
         const std::string& output, const std::string& obj_sequence, const std::string& clip, const std::string& frames,
         double fps, int shard_frames, const std::string& skeleton, const std::string& method,
         const std::vector<std::string>& sbatch_options, const std::string& executable, bool dry_run) {
        FarmJob job;
        job.animate.scene = {mesh, rig, skeleton, ""};
        if (!parse_deform_method(method, job.animate.options.method))
          throw py::value_error("method: expected dq, harmonic or gradient");
        job.animate.clip_file = clip_file;
        job.animate.clip = clip;
        job.animate.frames = frames;
        job.animate.fps = fps;
        job.animate.pc2 = output;
        job.animate.obj_sequence = obj_sequence;
        job.folder = folder;
        job.shard_frames = shard_frames;
        job.sbatch_options = sbatch_options;
        job.executable = executable;
        const FarmPlan plan = prepare_farm(job);
        if (!dry_run)
          (void)submit_farm(plan);
        return plan.folder;
      },
      py::arg("mesh"), py::arg("rig"), py::arg("clip_file"), py::arg("folder"), py::kw_only(), py::arg("output") = "",
      py::arg("obj_sequence") = "", py::arg("clip") = "", py::arg("frames") = "", py::arg("fps") = 24.0,
      py::arg("shard_frames") = 100, py::arg("skeleton") = "", py::arg("method") = "dq",
      py::arg("sbatch_options") = std::vector<std::string>{}, py::arg("executable") = "", py::arg("dry_run") = false,
      "Writes a farm job folder for `curvenet animate`'s inputs (a PC2 `output` or an `obj_sequence` folder) and "
      "submits it to Slurm with sbatch, unless `dry_run`; returns the job folder");
  m.def(
      "bake",
      [](const std::string& mesh, const std::string& rig, const std::string& output, const std::string& weights_csv,
         const std::string& clip_file, const std::vector<std::string>& clip_names, const std::string& fit,
         const std::string& weights, int max_influences, double fps, long long max_frames, const std::string& up,
         const std::string& skeleton, const std::string& method, const std::string& interior, bool over_skin,
         const std::string& skinning, double envelope, const std::string& mask, int helpers) {
        using namespace py::literals;
        if (output.empty() && weights_csv.empty())
          throw py::value_error("bake: give an output GLB path, a weights_csv path, or both");
        BakeJob job{{mesh, rig, skeleton, ""}, {}, output, weights_csv, clip_file, clip_names, fit};
        if (!parse_deform_method(method, job.options.method))
          throw py::value_error("method: expected dq, harmonic or gradient, got '" + method + "'");
        if (!parse_interior_weights(interior, job.options.interior))
          throw py::value_error("interior: expected 'bone-heat' or 'harmonic', got '" + interior + "'");
        if (weights != "harmonic" && weights != "fitted")
          throw py::value_error("weights: expected 'harmonic' or 'fitted', got '" + weights + "'");
        job.weights = weights == "fitted" ? BakeJob::Weights::Fitted : BakeJob::Weights::Harmonic;
        if (up != "y" && up != "z")
          throw py::value_error("up: expected 'y' or 'z', got '" + up + "'");
        job.up = up == "z" ? GltfBakeOptions::Up::Z : GltfBakeOptions::Up::Y;
        if (!(fps > 0 && fps <= 10000))
          throw py::value_error("fps: expected a number in (0, 10000]");
        job.fps = fps;
        job.max_influences = max_influences;
        job.max_frames = max_frames;
        job.helpers = helpers;
        if (skinning != "linear" && skinning != "dq")
          throw py::value_error("skinning: expected 'linear' or 'dq', got '" + skinning + "'");
        job.layer.over_skin = over_skin;
        job.layer.skinning = skinning == "dq" ? Skinning::DualQuaternion : Skinning::Linear;
        job.layer.envelope = envelope;
        job.layer.mask = mask;
        BakeSummary r;
        {
          py::gil_scoped_release release;
          r = run(job);
        }
        py::list fidelity;
        for (const auto& f : r.fidelity)
          fidelity.append(py::dict("clip"_a = f.clip, "index"_a = f.index, "frames"_a = f.frames, "mean"_a = f.mean,
                                   "max"_a = f.max, "worst_vertex"_a = f.worst_vertex,
                                   "worst_rest"_a = py::make_tuple(f.worst_rest.x(), f.worst_rest.y(), f.worst_rest.z()),
                                   "worst_joint"_a = f.worst_joint, "worst_time"_a = f.worst_time,
                                   "worst_floor"_a = f.worst_floor, "worst_joints"_a = f.worst_joints));
        return py::dict("notes"_a = r.notes, "vertices"_a = r.vertices, "bind"_a = from_json(report_to_json(r.bind)),
                        "joints"_a = r.joints, "helpers"_a = r.helpers, "helper_joints"_a = r.helper_joints,
                        "influences"_a = r.influences,
                        "mean_joints"_a = r.mean_joints,
                        "most_joints"_a = r.most_joints, "clips"_a = r.clips, "training_poses"_a = r.training_poses,
                        "fidelity"_a = fidelity);
      },
      py::arg("mesh"), py::arg("rig"), py::kw_only(), py::arg("output") = "", py::arg("weights_csv") = "",
      py::arg("clip_file") = "", py::arg("clip_names") = std::vector<std::string>{}, py::arg("fit") = "",
      py::arg("weights") = "harmonic", py::arg("max_influences") = 4, py::arg("fps") = 24.0,
      py::arg("max_frames") = 100000LL, py::arg("up") = "y", py::arg("skeleton") = "", py::arg("method") = "dq",
      py::arg("interior") = "bone-heat", py::arg("over_skin") = false, py::arg("skinning") = "linear",
      py::arg("envelope") = 1.0, py::arg("mask") = "", py::arg("helpers") = 0,
      "The job `curvenet bake` runs, from files to files (all or nothing): the GLB and/or the weights CSV, and a "
      "dict of what the CLI prints (notes, the bind report, the weights' joints per vertex, and with a clip file "
      "each carried clip's fidelity, worst first, as fractions of the diagonal)");
  m.def(
      "farm_merge",
      [](const std::string& folder) {
        using namespace py::literals;
        const FarmMerge r = merge_farm(folder);
        return py::dict("output"_a = r.output, "frames"_a = r.frames, "vertices"_a = r.vertices, "parts"_a = r.parts);
      },
      py::arg("folder"),
      "Checks every part of a farm job and writes its output, bit for bit one `animate`; raises naming the parts "
      "to rerun");
  m.def(
      "farm_status",
      [](const std::string& folder) {
        using namespace py::literals;
        py::list out;
        for (const auto& s : farm_status(folder).shards)
          out.append(py::dict("task"_a = s.shard.index, "first"_a = s.shard.first, "last"_a = s.shard.last,
                              "state"_a = s.state, "detail"_a = s.detail));
        return out;
      },
      py::arg("folder"), "Each farm task's state: from squeue and sacct where they answer, else its part file");

  // Baking to a linear-blend skin.
  py::class_<SkinWeights>(m, "SkinWeights", "A linear-blend skin: `influences` (joint, weight) slots per input vertex")
      .def(py::init([](const std::vector<std::string>& joints, const py::object& joint, const py::object& weight,
                       const std::vector<std::array<int, 2>>& helpers) {
             const Indices j = Indices::ensure(joint);
             const Points w = Points::ensure(weight);
             if (!j || !w || j.ndim() != 2 || w.ndim() != 2 || j.shape(0) != w.shape(0) || j.shape(1) != w.shape(1) ||
                 j.shape(1) < 1 || j.shape(1) > 8)
               throw py::value_error("joint and weight: expected two (n, k) arrays, k from 1 to 8");
             SkinWeights s;
             s.influences = static_cast<int>(j.shape(1));
             s.joints = joints;
             s.joint.assign(j.data(), j.data() + j.size());
             s.weight.assign(w.data(), w.data() + w.size());
             s.helpers = helpers;
             if (helpers.size() > joints.size())
               throw InputError("weights", "helpers", "more helpers than joints");
             for (const auto& [a, b] : helpers)
               if (a < 0 || b < 0 || a >= s.rig_joints() || b >= s.rig_joints() || a == b)
                 throw InputError("weights", "helper (" + std::to_string(a) + ", " + std::to_string(b) + ")",
                                  "names no two rig joints");
             for (size_t i = 0; i < s.joint.size(); ++i) {
               if (s.joint[i] < -1 || s.joint[i] >= static_cast<int>(joints.size()))
                 throw InputError("weights", "slot " + std::to_string(i), "names no joint");
               if (!std::isfinite(s.weight[i]) || s.weight[i] < 0)
                 throw InputError("weights", "slot " + std::to_string(i), "is not a finite non-negative weight");
             }
             return s;
           }),
           py::arg("joints"), py::arg("joint"), py::arg("weight"),
           py::arg("helpers") = std::vector<std::array<int, 2>>{})
      .def_readonly("influences", &SkinWeights::influences)
      .def_readonly("joints", &SkinWeights::joints)
      .def_readonly("helpers", &SkinWeights::helpers)
      .def_property_readonly("rig_joints", &SkinWeights::rig_joints)
      .def_property_readonly("num_vertices", &SkinWeights::num_vertices)
      .def_property_readonly("joint",
                             [](const SkinWeights& s) {
                               return table_array(s.joint.data(), static_cast<size_t>(s.num_vertices()),
                                                  static_cast<size_t>(s.influences));
                             })
      .def_property_readonly("weight", [](const SkinWeights& s) {
        return table_array(s.weight.data(), static_cast<size_t>(s.num_vertices()), static_cast<size_t>(s.influences));
      });
  m.def(
      "bake_weights",
      [](const PyBinding& b, int max_influences) {
        py::gil_scoped_release release;
        return bake_weights(b.binding, max_influences);
      },
      py::arg("binding"), py::arg("max_influences") = 4);
  m.def(
      "fit_weights",
      [](const PyBinding& b, const py::array_t<double, py::array::c_style | py::array::forcecast>& poses,
         int max_influences, int helpers) {
        const size_t nj = b.binding.joints().size();
        if (poses.ndim() != 4 || static_cast<size_t>(poses.shape(1)) != nj || poses.shape(2) != 4 ||
            poses.shape(3) != 4)
          throw py::value_error("poses: expected a (P, " + std::to_string(nj) + ", 4, 4) array");
        std::vector<Mat4> all;
        matrices_into(poses, all);
        std::vector<std::vector<Mat4>> per(static_cast<size_t>(poses.shape(0)));
        for (size_t p = 0; p < per.size(); ++p)
          per[p].assign(all.begin() + static_cast<std::ptrdiff_t>(p * nj),
                        all.begin() + static_cast<std::ptrdiff_t>((p + 1) * nj));
        py::gil_scoped_release release;
        return fit_weights(b.binding, per, max_influences, helpers);
      },
      py::arg("binding"), py::arg("poses"), py::arg("max_influences") = 4, py::arg("helpers") = 0);
  m.def(
      "training_poses",
      [](const PyBinding& b, const std::vector<double>& bends, double twist, int random_poses, double random_bend,
         double random_twist, unsigned seed) {
        if (random_poses < 0)
          throw py::value_error("random_poses: must not be negative");
        TrainingPoses o;
        o.bends = bends;
        o.twist = twist;
        o.random_poses = random_poses;
        o.random_bend = random_bend;
        o.random_twist = random_twist;
        o.seed = seed;
        const auto poses = training_poses(b.binding.joints(), o);
        const size_t nj = b.binding.joints().size();
        py::array_t<double> a({static_cast<py::ssize_t>(poses.size()), static_cast<py::ssize_t>(nj), py::ssize_t{4},
                               py::ssize_t{4}});
        auto r = a.mutable_unchecked<4>();
        for (size_t p = 0; p < poses.size(); ++p)
          for (size_t j = 0; j < nj; ++j)
            for (int i = 0; i < 4; ++i)
              for (int k = 0; k < 4; ++k)
                r(p, j, i, k) = poses[p][j](i, k);
        return a;
      },
      // The defaults are the library's (the stub's are checked against these).
      py::arg("binding"), py::arg("bends") = TrainingPoses{}.bends, py::arg("twist") = TrainingPoses{}.twist,
      py::arg("random_poses") = TrainingPoses{}.random_poses, py::arg("random_bend") = TrainingPoses{}.random_bend,
      py::arg("random_twist") = TrainingPoses{}.random_twist, py::arg("seed") = TrainingPoses{}.seed);
  m.def(
      "skin_positions",
      [](const SkinWeights& w, const py::object& rest,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& skinning) {
        // One matrix per joint of the weights, or per rig joint (the helpers' follow).
        const bool per_rig_joint = !w.helpers.empty() && skinning.ndim() == 3 &&
                                   static_cast<int>(skinning.shape(0)) == w.rig_joints();
        if (skinning.ndim() != 3 || (static_cast<size_t>(skinning.shape(0)) != w.joints.size() && !per_rig_joint) ||
            skinning.shape(1) != 4 || skinning.shape(2) != 4)
          throw py::value_error("skinning: expected a (" + std::to_string(w.joints.size()) + ", 4, 4) array");
        std::vector<Mat4> M;
        matrices_into(skinning, M);
        const std::vector<Vec3> X = points_from(rest, "rest");
        if (static_cast<int>(X.size()) != w.num_vertices())
          throw py::value_error("rest: expected " + std::to_string(w.num_vertices()) + " positions");
        return points_array(skin_positions(w, X, M));
      },
      py::arg("weights"), py::arg("rest"), py::arg("skinning"), "Linear blend skinning with baked weights");
  m.def(
      "helper_matrix",
      [](const py::array_t<double, py::array::c_style | py::array::forcecast>& a,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& b) {
        if (a.ndim() != 2 || b.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4 || b.shape(0) != 4 || b.shape(1) != 4)
          throw py::value_error("helper_matrix: expected two (4, 4) arrays");
        Mat4 x, y;
        for (int i = 0; i < 4; ++i)
          for (int k = 0; k < 4; ++k) {
            x(i, k) = a.at(i, k);
            y(i, k) = b.at(i, k);
          }
        const Mat4 h = helper_matrix(x, y);
        py::array_t<double> out({py::ssize_t{4}, py::ssize_t{4}});
        auto r = out.mutable_unchecked<2>();
        for (int i = 0; i < 4; ++i)
          for (int k = 0; k < 4; ++k)
            r(i, k) = h(i, k);
        return out;
      },
      py::arg("a"), py::arg("b"),
      "A helper joint's skinning matrix: the dual-quaternion mean of two joints' skinning matrices (4, 4)");
  m.def("weights_csv", &weights_csv, py::arg("weights"));
  m.def(
      "skinned_glb",
      [](const std::string& mesh_path, const py::object& skeleton, const SkinWeights& w, const SkinnedMesh* clips,
         const std::string& up, double fps, std::vector<std::string> clip_names) {
        GltfBakeOptions o;
        if (up != "y" && up != "z")
          throw py::value_error("up: expected 'y' or 'z'");
        o.up = up == "z" ? GltfBakeOptions::Up::Z : GltfBakeOptions::Up::Y;
        o.fps = fps;
        o.clips = std::move(clip_names);
        const std::vector<Joint> joints = joints_from(skeleton);
        std::string bytes;
        {
          py::gil_scoped_release release;
          bytes = skinned_glb(mesh_path, joints, w, clips, o);
        }
        return py::bytes(bytes);
      },
      py::arg("mesh_path"), py::arg("skeleton"), py::arg("weights"), py::arg("clips") = nullptr, py::kw_only(),
      py::arg("up") = "y", py::arg("fps") = 24.0, py::arg("clip_names") = std::vector<std::string>{},
      "A skinned glTF 2.0 binary (bytes) of the mesh file, with the skeleton, the weights and the clips");
  m.def(
      "write_file", [](const std::string& path, const py::bytes& data) { write_file_atomic(path, std::string(data)); },
      py::arg("path"), py::arg("data"), "Writes bytes to a file atomically (all or nothing)");

  // Output.
  m.def(
      "write_pc2",
      [](const std::string& path, const py::array_t<double, py::array::c_style | py::array::forcecast>& frames,
         double start_frame) {
        if (frames.ndim() != 3 || frames.shape(2) != 3)
          throw py::value_error("frames: expected an (F, n, 3) array");
        if (!std::isfinite(static_cast<float>(start_frame)))
          throw InputError(path, "start_frame", "is not a finite number in single precision; nothing was written");
        std::vector<float> data(static_cast<size_t>(frames.size()));
        const double* p = frames.data();
        for (size_t i = 0; i < data.size(); ++i) {
          data[i] = static_cast<float>(p[i]);
          if (!std::isfinite(data[i]))
            throw InputError(path,
                             "frame " + std::to_string(i / 3 / frames.shape(1)) + " vertex " +
                                 std::to_string(i / 3 % frames.shape(1)),
                             "is out of the range of a PC2 cache (single precision); nothing was written");
        }
        write_file_atomic(path, pc2_cache(static_cast<int>(frames.shape(1)), static_cast<int>(frames.shape(0)),
                                          static_cast<float>(start_frame), data));
      },
      py::arg("path"), py::arg("frames"), py::arg("start_frame") = 0.0,
      "Writes a PC2 point cache (Blender's Mesh Cache modifier), all or nothing");
}
