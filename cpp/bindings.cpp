// The one file that knows Python: pybind11 bindings of the compiled engine.
//
// Everything else under cpp/ is plain C++17 over contiguous arrays. Arrays cross here as
// numpy arrays of the exact dtype and layout the engine reads (never converted or copied:
// an in-place buffer that needed a copy would silently lose its writes), and errors cross as
// ValueError with a message naming the argument.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "bounding_volumes.hpp"

#include "obb_tree.hpp"

#include "query.hpp"

#include "distance.hpp"

#include <climits>
#include <memory>
#include <string>

namespace py = pybind11;
namespace cs = collision_sensor;

namespace {

template <class T>
using Array = py::array_t<T, py::array::c_style>;

// The array's extents, checked against the expected ones (-1: any); ValueError names it.
template <class T>
void expect_shape(const char* name, const Array<T>& a, std::initializer_list<py::ssize_t> dims) {
    bool ok = a.ndim() == py::ssize_t(dims.size());
    py::ssize_t k = 0;
    for (py::ssize_t d : dims) {
        if (ok && d >= 0 && a.shape(k) != d) ok = false;
        ++k;
    }
    if (!ok) {
        std::string want, got;
        for (py::ssize_t d : dims)
            want += (want.empty() ? "" : ", ") + (d < 0 ? std::string("n") : std::to_string(d));
        for (py::ssize_t i = 0; i < a.ndim(); ++i)
            got += (i ? ", " : "") + std::to_string(a.shape(i));
        throw py::value_error(std::string(name) + ": expected shape (" + want + "), got (" + got +
                              ")");
    }
}

template <class T>
T* writable(const char* name, Array<T>& a) {
    if (!a.writeable()) throw py::value_error(std::string(name) + ": the array is read-only");
    return a.mutable_data();
}

//: Engine.query's answer for an argument that is not a C-contiguous float64 array of J values.
constexpr int64_t NOT_AN_ARRAY = INT64_MIN;

// The checker's engine: the C++ Engine over the two packed buffers, which it keeps alive.
struct PyEngine {
    Array<double> F;
    Array<int64_t> I;
    std::unique_ptr<cs::Engine> engine;

    PyEngine(Array<double> F_, Array<int64_t> I_) : F(std::move(F_)), I(std::move(I_)) {
        expect_shape("F", F, {-1});
        expect_shape("I", I, {-1});
        try {
            engine = std::make_unique<cs::Engine>(writable("F", F), F.shape(0), writable("I", I),
                                                  I.shape(0));
        } catch (const std::invalid_argument& error) {
            throw py::value_error(error.what());
        }
    }

    // q: any object. The checker passes what its caller gave; only a C-contiguous float64
    // array of J values is taken as it is (checked here on numpy's own struct, cheaper than a
    // caster), anything else answers NOT_AN_ARRAY and the checker converts it first.
    int64_t query(py::handle q, bool full) {
        if (!py::isinstance<py::array>(q)) return NOT_AN_ARRAY;
        const auto* array = py::detail::array_proxy(q.ptr());
        const auto* descr = py::detail::array_descriptor_proxy(array->descr);
        constexpr int required = py::detail::npy_api::NPY_ARRAY_C_CONTIGUOUS_ |
                                 py::detail::npy_api::NPY_ARRAY_ALIGNED_;
        if (descr->type_num != py::detail::npy_api::NPY_DOUBLE_ || array->nd != 1 ||
            array->dimensions[0] != engine->n_joints() || (array->flags & required) != required)
            return NOT_AN_ARRAY;
        const double* data = reinterpret_cast<const double*>(array->data);
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(engine->lock());
        return engine->query(data, full);
    }

    // T: any object; only a C-contiguous float64 (4, 4) array is taken (checked as query
    // checks q), anything else answers MOVE_REFUSED.
    int64_t move_world_body(int64_t b, py::handle T, double max_coordinate,
                            double rotation_tolerance) {
        if (!py::isinstance<py::array>(T)) return cs::MOVE_REFUSED;
        const auto* array = py::detail::array_proxy(T.ptr());
        const auto* descr = py::detail::array_descriptor_proxy(array->descr);
        constexpr int required = py::detail::npy_api::NPY_ARRAY_C_CONTIGUOUS_ |
                                 py::detail::npy_api::NPY_ARRAY_ALIGNED_;
        if (descr->type_num != py::detail::npy_api::NPY_DOUBLE_ || array->nd != 2 ||
            array->dimensions[0] != 4 || array->dimensions[1] != 4 ||
            (array->flags & required) != required)
            return cs::MOVE_REFUSED;
        const double* data = reinterpret_cast<const double*>(array->data);
        std::lock_guard<std::mutex> hold(engine->lock());
        return engine->move_world_body(b, data, max_coordinate, rotation_tolerance);
    }

    int64_t batch(const Array<double>& Q, bool full, Array<uint8_t> statuses,
                  Array<int64_t> codes) {
        expect_shape("Q", Q, {-1, engine->n_joints()});
        const py::ssize_t n = Q.shape(0);
        expect_shape("statuses", statuses, {n, engine->n_pairs()});
        expect_shape("codes", codes, {n});
        const double* data = Q.data();
        uint8_t* out = writable("statuses", statuses);
        int64_t* out_codes = writable("codes", codes);
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(engine->lock());
        return engine->batch(data, n, full, out, out_codes);
    }

    void poses() {
        std::lock_guard<std::mutex> hold(engine->lock());
        engine->refresh_all_poses();
    }
};

cs::KinematicTree kinematic_tree(const Array<int64_t>& parent, const Array<int64_t>& joint_type,
                                 const Array<double>& T_parent_joint, const Array<double>& axis,
                                 const Array<int64_t>& q_index, const Array<double>& multiplier,
                                 const Array<double>& offset, py::ssize_t n_joints) {
    const py::ssize_t L = parent.size();
    expect_shape("parent", parent, {L});
    expect_shape("joint_type", joint_type, {L});
    expect_shape("T_parent_joint", T_parent_joint, {L, 4, 4});
    expect_shape("axis", axis, {L, 3});
    expect_shape("q_index", q_index, {L});
    expect_shape("multiplier", multiplier, {L});
    expect_shape("offset", offset, {L});
    for (py::ssize_t i = 0; i < L; ++i) {
        const int64_t p = parent.data()[i];
        if ((i == 0) != (p < 0) || p >= i)
            throw py::value_error("parent: links must come root first, parents before children");
        const int64_t kind = joint_type.data()[i];
        if (kind < cs::JOINT_FIXED || kind > cs::JOINT_FLOATING)
            throw py::value_error("joint_type: unknown joint type " + std::to_string(kind));
        if (kind != cs::JOINT_FIXED &&
            (q_index.data()[i] < 0 ||
             q_index.data()[i] + cs::joint_variable_count(kind) > n_joints))
            throw py::value_error("q_index: index out of range for " + std::to_string(n_joints) +
                                  " joint values");
    }
    return {int64_t(L), parent.data(), joint_type.data(), T_parent_joint.data(), axis.data(),
            q_index.data(), multiplier.data(), offset.data()};
}

// A kinematic tree whose arrays are checked and held once, for Python callers of FK.
struct PyKinematics {
    Array<int64_t> parent, joint_type, q_index;
    Array<double> T_parent_joint, axis, multiplier, offset;
    py::ssize_t n_joints;
    cs::KinematicTree kin;

    PyKinematics(Array<int64_t> parent_, Array<int64_t> joint_type_,
                 Array<double> T_parent_joint_, Array<double> axis_, Array<int64_t> q_index_,
                 Array<double> multiplier_, Array<double> offset_, py::ssize_t n_joints_)
        : parent(std::move(parent_)), joint_type(std::move(joint_type_)),
          q_index(std::move(q_index_)), T_parent_joint(std::move(T_parent_joint_)),
          axis(std::move(axis_)), multiplier(std::move(multiplier_)),
          offset(std::move(offset_)), n_joints(n_joints_),
          kin(kinematic_tree(parent, joint_type, T_parent_joint, axis, q_index, multiplier,
                             offset, n_joints_)) {}

    // Every link's pose for q (J,) as a new (L, 4, 4) array, or for Q (n, J) as (n, L, 4, 4).
    // A value the engine cannot honour raises ValueError naming its index ("variable j").
    py::array forward(const Array<double>& q) {
        if (q.ndim() < 1 || q.ndim() > 2 || q.shape(q.ndim() - 1) != n_joints)
            throw py::value_error("q: expected (J,) or (n, J) values, J = " +
                                  std::to_string(n_joints));
        const py::ssize_t n = q.ndim() == 2 ? q.shape(0) : 1;
        const py::ssize_t L = kin.n_links;
        const double* Q = q.data();
        for (py::ssize_t k = 0; k < n; ++k) {
            const int64_t bad = cs::unusable_variable(kin, Q + n_joints * k, n_joints);
            if (bad >= 0)
                throw py::value_error("variable " + std::to_string(bad) + " of row " +
                                      std::to_string(k));
        }
        Array<double> out = q.ndim() == 2 ? Array<double>({n, L, py::ssize_t(4), py::ssize_t(4)})
                                          : Array<double>({L, py::ssize_t(4), py::ssize_t(4)});
        double* T = out.mutable_data();
        if (n == 1) {
            cs::forward_kinematics(kin, Q, T);
        } else {
            py::gil_scoped_release release;
            for (py::ssize_t k = 0; k < n; ++k)
                cs::forward_kinematics(kin, Q + n_joints * k, T + 16 * L * k);
        }
        return std::move(out);
    }
};

// One box pair as the box tests take it: ha, hb (3,), R (3, 3), t (3,).
struct BoxPair {
    const double *ha, *hb, *R, *t;
};

void expect_box_pairs(const Array<double>& ha, const Array<double>& hb, const Array<double>& R,
                      const Array<double>& t) {
    const py::ssize_t n = ha.shape(0);
    expect_shape("ha", ha, {n, 3});
    expect_shape("hb", hb, {n, 3});
    expect_shape("R", R, {n, 3, 3});
    expect_shape("t", t, {n, 3});
}

}  // namespace

//: Bumped whenever the binding's functions or the packed layouts change; the Python side
//: refuses an extension built from other sources (collision_sensor/compiled.py).
constexpr int ENGINE_API = 2;

PYBIND11_MODULE(_engine, m) {
    m.doc() = "collision_sensor's compiled engine (C++17); see collision_sensor.compiled";
    m.attr("ENGINE_API") = ENGINE_API;
#if defined(__clang__)
    m.attr("COMPILER") = "clang " __clang_version__;
#elif defined(__GNUC__)
    m.attr("COMPILER") = "g++ " __VERSION__;
#else
    m.attr("COMPILER") = "unknown compiler";
#endif
#ifdef COLLISION_SENSOR_SOURCE_DIGEST
    m.attr("SOURCE_DIGEST") = COLLISION_SENSOR_SOURCE_DIGEST;
#else
    m.attr("SOURCE_DIGEST") = "";
#endif

    // ---- query engine (query.hpp, box_test.hpp, triangle_test.hpp, kinematics.hpp)
    py::list float_slots, int_slots;
    for (const char* name : cs::FLOAT_SLOT_NAMES) float_slots.append(name);
    for (const char* name : cs::INT_SLOT_NAMES) int_slots.append(name);
    m.attr("FLOAT_SLOTS") = py::tuple(float_slots);
    m.attr("INT_SLOTS") = py::tuple(int_slots);
    m.attr("HEADER_SIZE") = cs::HEADER_SIZE;
    m.attr("NOT_AN_ARRAY") = NOT_AN_ARRAY;
    m.attr("MOVE_REFUSED") = cs::MOVE_REFUSED;
    m.attr("SOLID_WIDTH") = cs::SOLID_WIDTH;
    m.attr("LAYOUT_WIDTH") = cs::LAYOUT_WIDTH;
    m.attr("N_SCALARS") = cs::N_SCALARS;
    m.attr("S_TOLERANCE") = cs::S_TOLERANCE;
    m.attr("H_N_LINKS") = cs::H_N_LINKS;
    m.attr("H_BOX_METHOD") = cs::H_BOX_METHOD;
    m.attr("H_EXPANSION") = cs::H_EXPANSION;
    m.attr("H_CHECKED_ONCE") = cs::H_CHECKED_ONCE;
    m.attr("H_RESYNC_COUNTDOWN") = cs::H_RESYNC_COUNTDOWN;
    m.attr("H_FORCED") = cs::H_FORCED;
    m.attr("H_LAYOUTS") = cs::H_LAYOUTS;
    m.attr("H_I_LAYOUT") = cs::H_I_LAYOUT;
    m.attr("TRAVEL_RESYNC_CALLS") = cs::TRAVEL_RESYNC_CALLS;
    m.attr("FRONT_POOL_ROWS") = cs::FRONT_POOL_ROWS;
    m.attr("FRONT_ROWS_MIN") = cs::FRONT_ROWS_MIN;
    m.attr("FRONT_ROWS_MAX") = cs::FRONT_ROWS_MAX;
    m.attr("N_COUNTERS") = int(cs::N_COUNTERS);
    m.attr("POSE_WIDTH") = cs::POSE_WIDTH;
    m.attr("PRISMATIC_VALUE_MAX") = cs::PRISMATIC_VALUE_MAX;
    m.attr("QUATERNION_NORM_MIN") = cs::QUATERNION_NORM_MIN;
    m.attr("BOX_EPS_REL") = cs::BOX_EPS_REL;
    m.attr("BOX_EPS_PARALLEL") = cs::BOX_EPS_PARALLEL;
    m.attr("TRIANGLE_EPS_REL") = cs::TRIANGLE_EPS_REL;
    m.attr("SPHERE_EPS_REL") = cs::SPHERE_EPS_REL;

    py::class_<PyEngine>(m, "Engine",
                         "The query engine over a checker's packed buffers F (float64) and I "
                         "(int64); see cpp/query.hpp. Not for use outside CollisionChecker.")
        .def(py::init<Array<double>, Array<int64_t>>(), py::arg("F").noconvert(),
             py::arg("I").noconvert())
        .def("query", &PyEngine::query, py::arg("q"), py::arg("full"),
             "Bring the statuses up to date with q (a C-contiguous float64 array of J values; "
             "anything else answers NOT_AN_ARRAY and changes nothing); return 2 * rechecked + "
             "changed, or -1 - j "
             "when q[j] is not usable: not finite, or beyond the engine's range (nothing "
             "changed then).")
        .def("move_world_body", &PyEngine::move_world_body, py::arg("b"), py::arg("T"),
             py::arg("max_coordinate"), py::arg("rotation_tolerance"),
             "Give world object b the pose T ((4, 4) C-contiguous float64) and force its pairs, "
             "if T is a rigid transform within range; return 0, or MOVE_REFUSED (nothing "
             "changed then, also for anything but such an array).")
        .def("batch", &PyEngine::batch, py::arg("Q"), py::arg("full"),
             py::arg("statuses").noconvert(), py::arg("codes").noconvert(),
             "query() on each row of Q; statuses (n, P) uint8 and codes (n,) written; return n, "
             "or -1 - (J i + j) when row i's value j is not usable (nothing changed then).")
        .def("poses", &PyEngine::poses, "Bring every link pose up to date.");

    py::class_<PyKinematics>(m, "Kinematics",
                             "A kinematic tree's arrays (kinematics.py: KinematicTree), checked "
                             "once; forward(q) gives every link's pose.")
        .def(py::init<Array<int64_t>, Array<int64_t>, Array<double>, Array<double>,
                      Array<int64_t>, Array<double>, Array<double>, py::ssize_t>(),
             py::arg("parent"), py::arg("joint_type"), py::arg("T_parent_joint"),
             py::arg("axis"), py::arg("q_index"), py::arg("multiplier"), py::arg("offset"),
             py::arg("n_joints"))
        .def("forward", &PyKinematics::forward, py::arg("q"),
             "Every link's pose: (L, 4, 4) for q (J,), (n, L, 4, 4) for q (n, J).");

    m.def("forward_kinematics",
          [](const Array<double>& q, const Array<int64_t>& parent,
             const Array<int64_t>& joint_type, const Array<double>& T_parent_joint,
             const Array<double>& axis, const Array<int64_t>& q_index,
             const Array<double>& multiplier, const Array<double>& offset,
             Array<double> T_out) {
              const py::ssize_t n = q.ndim() == 2 ? q.shape(0) : 1;
              const py::ssize_t J = q.shape(q.ndim() - 1);
              const cs::KinematicTree kin = kinematic_tree(
                  parent, joint_type, T_parent_joint, axis, q_index, multiplier, offset, J);
              if (q.ndim() == 2)
                  expect_shape("T_out", T_out, {n, kin.n_links, 4, 4});
              else
                  expect_shape("T_out", T_out, {kin.n_links, 4, 4});
              double* out = writable("T_out", T_out);
              const double* Q = q.data();
              py::gil_scoped_release release;
              for (py::ssize_t k = 0; k < n; ++k)
                  cs::forward_kinematics(kin, Q + J * k, out + 16 * kin.n_links * k);
          },
          py::arg("q"), py::arg("parent"), py::arg("joint_type"), py::arg("T_parent_joint"),
          py::arg("axis"), py::arg("q_index"), py::arg("multiplier"), py::arg("offset"),
          py::arg("T_out").noconvert(),
          "Write every link's pose for q (J,) into T_out (L, 4, 4), or for each row of q "
          "(n, J) into T_out (n, L, 4, 4).");

    m.def("boxes_disjoint",
          [](int method, const Array<double>& ha, const Array<double>& hb,
             const Array<double>& R, const Array<double>& t) {
              expect_box_pairs(ha, hb, R, t);
              const py::ssize_t n = ha.shape(0);
              Array<bool> out(n);
              bool* o = out.mutable_data();
              const double *a = ha.data(), *b = hb.data(), *r = R.data(), *c = t.data();
              py::gil_scoped_release release;
              if (method == cs::BOX_TEST_PAPER)
                  for (py::ssize_t i = 0; i < n; ++i)
                      o[i] = cs::boxes_disjoint_paper(a + 3 * i, b + 3 * i, r + 9 * i, c + 3 * i);
              else
                  for (py::ssize_t i = 0; i < n; ++i)
                      o[i] = cs::boxes_disjoint_sat(a + 3 * i, b + 3 * i, r + 9 * i, c + 3 * i);
              return out;
          },
          py::arg("method"), py::arg("ha"), py::arg("hb"), py::arg("R"), py::arg("t"),
          "For each of n box pairs (ha, hb (n, 3), R (n, 3, 3), t (n, 3)): True iff the test "
          "(BOX_TEST_PAPER 0 or BOX_TEST_SAT 1) separates them.");

    m.def("separating_axis",
          [](const Array<double>& ha, const Array<double>& hb, const Array<double>& R,
             const Array<double>& t) {
              expect_box_pairs(ha, hb, R, t);
              const py::ssize_t n = ha.shape(0);
              Array<int64_t> out(n);
              int64_t* o = out.mutable_data();
              for (py::ssize_t i = 0; i < n; ++i) {
                  const double *a = ha.data() + 3 * i, *b = hb.data() + 3 * i,
                               *r = R.data() + 9 * i, *c = t.data() + 3 * i;
                  o[i] = cs::separating_axis(a[0], a[1], a[2], b[0], b[1], b[2], r[0], r[1],
                                             r[2], r[3], r[4], r[5], r[6], r[7], r[8], c[0],
                                             c[1], c[2]);
              }
              return out;
          },
          py::arg("ha"), py::arg("hb"), py::arg("R"), py::arg("t"),
          "For each of n box pairs: the first axis of the 15-axis test that separates them "
          "(0-2 A's faces, 3-5 B's, 6 + 3 i + j edge i of A x edge j of B), or -1.");

    m.def("axis_gap",
          [](int64_t k, const Array<double>& A, const Array<double>& B, const Array<double>& P) {
              expect_shape("A", A, {cs::BOX_WIDTH});
              expect_shape("B", B, {cs::BOX_WIDTH});
              expect_shape("P", P, {cs::POSE_WIDTH});
              if (k < 0 || k > 14) throw py::value_error("k: an axis 0 to 14");
              const cs::AxisGap g = cs::axis_gap(k, A.data(), B.data(), P.data());
              return py::make_tuple(g.separated, g.gap);
          },
          py::arg("k"), py::arg("A"), py::arg("B"), py::arg("P"),
          "(separated, gap) along axis k of separating_axis alone, for box rows A (body a) and "
          "B (body b at pose P: R_ab row-major, t_ab).");

    m.def("triangles_intersect",
          [](const Array<double>& P, const Array<double>& Q) {
              const py::ssize_t n = P.ndim() == 3 ? P.shape(0) : 1;
              if (P.ndim() == 3) {
                  expect_shape("P", P, {n, 3, 3});
                  expect_shape("Q", Q, {n, 3, 3});
              } else {
                  expect_shape("P", P, {3, 3});
                  expect_shape("Q", Q, {3, 3});
              }
              Array<bool> out(n);
              bool* o = out.mutable_data();
              const double *p = P.data(), *q = Q.data();
              {
                  py::gil_scoped_release release;
                  for (py::ssize_t i = 0; i < n; ++i)
                      o[i] = cs::triangles_intersect(cs::triangle_at(p, i), cs::triangle_at(q, i));
              }
              if (P.ndim() == 2) return py::object(py::bool_(o[0]));
              return py::object(out);
          },
          py::arg("P"), py::arg("Q"),
          "True iff the closed triangles P and Q (3, 3: rows the vertices) touch or cross; for "
          "(n, 3, 3) arrays, one answer per row.");

    {  // proximity (distance.hpp, distance.cpp): issue 15
        py::reinterpret_borrow<py::class_<PyEngine>>(m.attr("Engine"))
            .def("proximity",
                 [](PyEngine& self, const Array<double>& q, double max_distance,
                    Array<double> distance, Array<double> points) {
                     cs::Engine& engine = *self.engine;
                     expect_shape("q", q, {engine.n_joints()});
                     expect_shape("distance", distance, {engine.n_pairs()});
                     expect_shape("points", points, {engine.n_pairs(), 6});
                     const double* data = q.data();
                     double* d = writable("distance", distance);
                     double* x = writable("points", points);
                     py::gil_scoped_release release;
                     std::lock_guard<std::mutex> hold(engine.lock());
                     return engine.proximity(data, max_distance, d, x);
                 },
                 py::arg("q"), py::arg("max_distance"), py::arg("distance").noconvert(),
                 py::arg("points").noconvert(),
                 "update(q), then each pair's distance (P,) (inf when not below max_distance, 0 "
                 "when colliding) and nearest points (P, 6), world frame, written in place; "
                 "return query()'s code.");
        m.def("triangle_distance",
              [](const Array<double>& P, const Array<double>& Q) {
                  const py::ssize_t n = P.ndim() == 3 ? P.shape(0) : 1;
                  expect_shape("P", P, {n, 3, 3});
                  expect_shape("Q", Q, {n, 3, 3});
                  Array<double> d(n), x({n, py::ssize_t(3)}), y({n, py::ssize_t(3)});
                  double *o = d.mutable_data(), *ox = x.mutable_data(), *oy = y.mutable_data();
                  const double *p = P.data(), *r = Q.data();
                  {
                      py::gil_scoped_release release;
                      for (py::ssize_t i = 0; i < n; ++i)
                          o[i] = cs::triangle_distance(cs::triangle_at(p, i),
                                                       cs::triangle_at(r, i), ox + 3 * i,
                                                       oy + 3 * i);
                  }
                  return py::make_tuple(d, x, y);
              },
              py::arg("P"), py::arg("Q"),
              "Distances (n,) between the closed triangles P[i] and Q[i] ((n, 3, 3), rows the "
              "vertices) and nearest points x (n, 3) on P[i], y (n, 3) on Q[i].");
    }
    {  // motion checks (motion.hpp, motion.cpp): issue 25
        m.attr("MOTION_LINEAR") = cs::MOTION_LINEAR;
        m.attr("MOTION_WRAP") = cs::MOTION_WRAP;
        m.attr("MOTION_QUATERNION") = cs::MOTION_QUATERNION;
        m.attr("MOTION_QUATERNION_REST") = cs::MOTION_QUATERNION_REST;
        m.attr("MOTION_TOUCH_TOLERANCE") = cs::MOTION_TOUCH_TOLERANCE;
        py::reinterpret_borrow<py::class_<PyEngine>>(m.attr("Engine"))
            .def("set_motion_kinds",
                 [](PyEngine& self, const Array<int64_t>& kinds) {
                     cs::Engine& engine = *self.engine;
                     expect_shape("kinds", kinds, {engine.n_joints()});
                     for (py::ssize_t j = 0; j < kinds.shape(0); ++j) {
                         const int64_t k = kinds.data()[j];
                         if (k < cs::MOTION_LINEAR || k > cs::MOTION_QUATERNION_REST)
                             throw py::value_error("kinds: unknown motion kind " +
                                                   std::to_string(k));
                     }
                     std::lock_guard<std::mutex> hold(engine.lock());
                     engine.set_motion_kinds(kinds.data());
                 },
                 py::arg("kinds").noconvert(),
                 "How each variable moves along a straight motion (MOTION_*), (J,) int64.")
            .def("motion",
                 [](PyEngine& self, const Array<double>& q0, const Array<double>& q1,
                    Array<uint8_t> pairs) {
                     cs::Engine& engine = *self.engine;
                     expect_shape("q0", q0, {engine.n_joints()});
                     expect_shape("q1", q1, {engine.n_joints()});
                     expect_shape("pairs", pairs, {engine.n_pairs()});
                     const double* a = q0.data();
                     const double* b = q1.data();
                     uint8_t* out = writable("pairs", pairs);
                     double t = -1.0;
                     int64_t code;
                     {
                         py::gil_scoped_release release;
                         std::lock_guard<std::mutex> hold(engine.lock());
                         code = engine.motion(a, b, &t, out);
                     }
                     return py::make_tuple(code, t);
                 },
                 py::arg("q0"), py::arg("q1"), py::arg("pairs").noconvert(),
                 "The straight motion q0 -> q1, carried state untouched: (code, t), code 0 "
                 "free, 1 contact (t its fraction, pairs (P,) uint8 written), or -1 - j for an "
                 "unusable value (j >= J: q1's).")
            .def("update_motion",
                 [](PyEngine& self, const Array<double>& q, Array<uint8_t> pairs) {
                     cs::Engine& engine = *self.engine;
                     expect_shape("q", q, {engine.n_joints()});
                     expect_shape("pairs", pairs, {engine.n_pairs()});
                     const double* data = q.data();
                     uint8_t* out = writable("pairs", pairs);
                     double t = -1.0;
                     int64_t code, query_code = 0;
                     {
                         py::gil_scoped_release release;
                         std::lock_guard<std::mutex> hold(engine.lock());
                         code = engine.update_motion(data, &t, out, &query_code);
                     }
                     return py::make_tuple(code, t, query_code);
                 },
                 py::arg("q"), py::arg("pairs").noconvert(),
                 "The motion from the carried state to q, then query(q, full=False): (code, t, "
                 "query's code), code as motion.")
            .def("path",
                 [](PyEngine& self, const Array<double>& Q, Array<uint8_t> pairs) {
                     cs::Engine& engine = *self.engine;
                     expect_shape("Q", Q, {-1, engine.n_joints()});
                     expect_shape("pairs", pairs, {engine.n_pairs()});
                     const double* data = Q.data();
                     const int64_t n = Q.shape(0);
                     uint8_t* out = writable("pairs", pairs);
                     double t = -1.0;
                     int64_t segment = -1, code;
                     {
                         py::gil_scoped_release release;
                         std::lock_guard<std::mutex> hold(engine.lock());
                         code = engine.path(data, n, &segment, &t, out);
                     }
                     return py::make_tuple(code, segment, t);
                 },
                 py::arg("Q"), py::arg("pairs").noconvert(),
                 "The straight motions between consecutive rows of Q until one is not free: "
                 "(code, segment, t), code as motion (-1 - (J i + j) for row i's value j).")
            .def("spline",
                 [](PyEngine& self, const Array<double>& coef, Array<uint8_t> pairs) {
                     cs::Engine& engine = *self.engine;
                     expect_shape("coef", coef, {-1, engine.n_joints(), 6});
                     expect_shape("pairs", pairs, {engine.n_pairs()});
                     const double* data = coef.data();
                     const int64_t n = coef.shape(0);
                     uint8_t* out = writable("pairs", pairs);
                     double t = -1.0;
                     int64_t segment = -1, code;
                     {
                         py::gil_scoped_release release;
                         std::lock_guard<std::mutex> hold(engine.lock());
                         code = engine.spline(data, n, &segment, &t, out);
                     }
                     return py::make_tuple(code, segment, t);
                 },
                 py::arg("coef"), py::arg("pairs").noconvert(),
                 "The polynomial segments coef (n, J, 6) (q_j(t) = sum_k coef[i, j, k] t^k, t in "
                 "[0, 1]) in turn until one is not free: (code, segment, t) as path; code -1 - i "
                 "for a segment i the engine refuses.");
    }

    // ---- end of query engine


    // ---- build-time kernels (bounding_volumes.hpp, obb_tree.hpp)

    {  // a block of its own, so that its helper names cannot clash with other sections
        // Arrays in: py::array_t<..., c_style> (a contiguous copy is made of other layouts or
        // dtypes, which is harmless for inputs); arrays written in place: .noconvert(), so that a
        // buffer needing a copy is refused instead of silently losing the writes. Shapes are
        // checked here, and a wrong one raises ValueError naming the argument.
        using Doubles = py::array_t<double, py::array::c_style>;
        using Int64s = py::array_t<int64_t, py::array::c_style>;
        struct Args {
            static std::string shape_of(const py::array& a) {
                std::string s = "(";
                for (py::ssize_t d = 0; d < a.ndim(); ++d) {
                    s += (d > 0 ? ", " : "") + std::to_string(a.shape(d));
                }
                return s + (a.ndim() == 1 ? ",)" : ")");
            }
            // Require a.shape == shape, where -1 matches any length; return a.shape(0).
            static py::ssize_t require(const py::array& a, const char* name,
                                       std::initializer_list<py::ssize_t> shape,
                                       const char* expected) {
                bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
                py::ssize_t d = 0;
                for (py::ssize_t want : shape) {
                    if (ok && want >= 0 && a.shape(d) != want) ok = false;
                    ++d;
                }
                if (!ok) {
                    throw py::value_error(std::string(name) + " must have shape " + expected +
                                          ", got " + shape_of(a));
                }
                return a.ndim() > 0 ? a.shape(0) : 0;
            }
            static py::ssize_t points(const Doubles& a, const char* name) {
                return require(a, name, {-1, 3}, "(n, 3)");
            }
            static void matrix3(const Doubles& a, const char* name) {
                require(a, name, {3, 3}, "(3, 3)");
            }
        };

        m.def("obb_volume", [](const Doubles& half) {
            Args::require(half, "half", {3}, "(3,)");
            return collision_sensor::obb_volume(half.data());
        }, py::arg("half"), "Volume 8 hx hy hz of a box with half extents half (3,).");

        m.def("sphere_volume", &collision_sensor::sphere_volume, py::arg("r"),
              "Volume 4/3 pi r^3 of a sphere of radius r.");

        m.def("check_points", [](const Doubles& points) {
            const auto n = Args::points(points, "points");
            collision_sensor::check_points(points.data(), n);
        }, py::arg("points"),
           "Raise ValueError if points (n, 3) is empty or holds NaN or infinity.");

        m.def("covariance", [](const Doubles& points) {
            const auto n = Args::points(points, "points");
            if (n == 0) throw py::value_error("points must hold at least one point");
            Doubles C({3, 3});
            collision_sensor::covariance(points.data(), n, C.mutable_data());
            return C;
        }, py::arg("points"), "(3, 3) covariance of points (n, 3), two-pass, 1/n normalised.");

        m.def("symmetric_eigen", [](const Doubles& C) {
            Args::matrix3(C, "C");
            Doubles w(3), V({3, 3});
            collision_sensor::symmetric_eigen3(C.data(), w.mutable_data(), V.mutable_data());
            return py::make_tuple(w, V);
        }, py::arg("C"),
           "(w (3,), V (3, 3)) with C = V diag(w) V^T for a symmetric C (3, 3), by cyclic Jacobi; "
           "eigenvalues unsorted, eigenvector k in column k.");

        m.def("frame_from_eigenvectors", [](const Doubles& V, const Int64s& order) {
            Args::matrix3(V, "V");
            Args::require(order, "order", {3}, "(3,)");
            for (py::ssize_t i = 0; i < 2; ++i) {
                if (order.at(i) < 0 || order.at(i) > 2) {
                    throw py::value_error("order must hold column indices 0, 1 or 2");
                }
            }
            Doubles axes({3, 3});
            collision_sensor::frame_from_eigenvectors(V.data(), order.data(), axes.mutable_data());
            return axes;
        }, py::arg("V"), py::arg("order"),
           "Box frame (3, 3) from columns order[0], order[1] of V: orthonormalised, signs fixed, "
           "third axis their cross product.");

        m.def("principal_frame", [](const Doubles& C) {
            Args::matrix3(C, "C");
            Doubles axes({3, 3});
            collision_sensor::principal_frame(C.data(), axes.mutable_data());
            return axes;
        }, py::arg("C"),
           "Box frame (3, 3) of a symmetric covariance C: eigenvectors, largest first.");

        m.def("box_on_axes", [](const Doubles& points, const Doubles& axes) {
            const auto n = Args::points(points, "points");
            if (n == 0) throw py::value_error("points must hold at least one point");
            Args::matrix3(axes, "axes");
            Doubles center(3), half(3);
            collision_sensor::box_on_axes(points.data(), n, axes.data(), center.mutable_data(),
                                          half.mutable_data());
            return py::make_tuple(center, half);
        }, py::arg("points"), py::arg("axes"),
           "(center (3,), half (3,)) of the smallest box with axes (3, 3) containing "
           "points (n, 3).");

        m.def("fit_obb_pca", [](const Doubles& points) {
            const auto n = Args::points(points, "points");
            Doubles center(3), axes({3, 3}), half(3);
            collision_sensor::fit_obb_pca(points.data(), n, center.mutable_data(),
                                          axes.mutable_data(), half.mutable_data());
            return py::make_tuple(center, axes, half);
        }, py::arg("points"),
           "(center (3,), axes (3, 3), half (3,)) of the principal-axes box of points (n, 3).");

        m.def("ritter_sphere", [](const Doubles& points) {
            const auto n = Args::points(points, "points");
            Doubles center(3);
            const double r =
                collision_sensor::ritter_sphere(points.data(), n, center.mutable_data());
            return py::make_tuple(center, r);
        }, py::arg("points"),
           "(center (3,), radius) of Ritter's bounding sphere of points (n, 3).");

        m.def("build_obb_tree",
              [](const Doubles& tris, int64_t leaf_size, Doubles& center, Doubles& axes,
                 Doubles& half, Int64s& left, Int64s& right, Int64s& first, Int64s& count,
                 Int64s& order) {
            const auto m = Args::require(tris, "tris", {-1, 3, 3}, "(m, 3, 3)");
            if (m < 1) throw py::value_error("tris must hold at least one triangle");
            if (leaf_size < 1) {
                throw py::value_error("leaf_size must be at least 1, got " +
                                      std::to_string(leaf_size));
            }
            const auto cap = Args::require(center, "center", {-1, 3}, "(cap, 3)");
            if (cap < 2 * m - 1) {
                throw py::value_error("center must hold 2 m - 1 = " + std::to_string(2 * m - 1) +
                                      " nodes, got " + std::to_string(cap));
            }
            Args::require(axes, "axes", {cap, 3, 3}, "(cap, 3, 3) with cap = len(center)");
            Args::require(half, "half", {cap, 3}, "(cap, 3) with cap = len(center)");
            Args::require(left, "left", {cap}, "(cap,) with cap = len(center)");
            Args::require(right, "right", {cap}, "(cap,) with cap = len(center)");
            Args::require(first, "first", {cap}, "(cap,) with cap = len(center)");
            Args::require(count, "count", {cap}, "(cap,) with cap = len(center)");
            Args::require(order, "order", {m}, "(m,) with m = len(tris)");
            const double* t = tris.data();
            double *c = center.mutable_data(), *a = axes.mutable_data(), *h = half.mutable_data();
            int64_t *l = left.mutable_data(), *r = right.mutable_data();
            int64_t *f = first.mutable_data(), *n = count.mutable_data();
            int64_t* o = order.mutable_data();
            collision_sensor::TreeSize size;
            {
                py::gil_scoped_release release;
                size = collision_sensor::build_obb_tree(t, m, leaf_size, c, a, h, l, r, f, n, o);
            }
            return py::make_tuple(size.nodes, size.depth);
        }, py::arg("tris"), py::arg("leaf_size"), py::arg("center").noconvert(),
           py::arg("axes").noconvert(), py::arg("half").noconvert(), py::arg("left").noconvert(),
           py::arg("right").noconvert(), py::arg("first").noconvert(),
           py::arg("count").noconvert(), py::arg("order").noconvert(),
           "Build one OBB tree over tris (m, 3, 3) into preallocated node arrays (2 m - 1 rows); "
           "return (nodes, depth). See collision_sensor.obb_tree.build_tree_kernel.");
    }

    // ---- end of build-time kernels
}
