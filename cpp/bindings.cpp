// The one file that knows Python: pybind11 bindings of the compiled engine.
//
// Everything else under cpp/ is plain C++17 over contiguous arrays. Arrays cross here as
// numpy arrays of the exact dtype and layout the engine reads: inputs are converted by
// pybind11 when they are not (a copy is harmless for them), arrays written in place are
// taken only as they are (.noconvert(): a buffer that needed a copy would silently lose its
// writes). Every shape is checked by one function (expect_shape). Errors cross as the
// package's own exceptions (collision_sensor/errors.py): EngineInputError for an argument the
// engine cannot take, EngineBuildError for packed buffers whose layout is not the engine's,
// JointStateError for joint values it cannot honour, EngineWorkerError for a batch whose worker
// thread failed.
//
// The engine's constants and the layout of its packed arrays (layout.hpp) are exported here
// under their C++ names: the Python side reads them, and writes none of them again.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <structmember.h>

#include <algorithm>
#include <climits>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "bounding_volumes.hpp"
#include "cloud_queries.hpp"
#include "engine.hpp"
#include "number_table.hpp"
#include "obb_tree.hpp"
#include "proximity.hpp"
#include "ray_cast.hpp"
#include "triangle_box.hpp"
#include "voxel_cloud.hpp"

namespace py = pybind11;
namespace cs = collision_sensor;

namespace {

template <class T>
using Array = py::array_t<T, py::array::c_style>;

// The package's exception types, looked up once (and kept for the interpreter's life).
struct PackageErrors {
    py::handle input, build, joint_state, worker;
};

const PackageErrors& errors() {
    static const PackageErrors e = [] {
        py::module_ m = py::module_::import("collision_sensor.errors");
        return PackageErrors{py::object(m.attr("EngineInputError")).release(),
                             py::object(m.attr("EngineBuildError")).release(),
                             py::object(m.attr("JointStateError")).release(),
                             py::object(m.attr("EngineWorkerError")).release()};
    }();
    return e;
}

// Raise JointStateError(message) with attributes row and variable (the index into q).
[[noreturn]] void raise_joint_state(const std::string& message, py::ssize_t row,
                                    int64_t variable) {
    py::object error = errors().joint_state(message);
    error.attr("row") = row;
    error.attr("variable") = variable;
    PyErr_SetObject(errors().joint_state.ptr(), error.ptr());
    throw py::error_already_set();
}

// numpy's byte order character of this machine's own order, as dtype.byteorder may give it.
const char native_order = [] {
    const uint16_t one = 1;
    return *reinterpret_cast<const uint8_t*>(&one) == 1 ? '<' : '>';
}();

// True iff array a has the extents dims (-1: any): the one shape check of the binding.
bool has_shape(const py::array& a, std::initializer_list<py::ssize_t> dims) {
    if (a.ndim() != py::ssize_t(dims.size())) return false;
    py::ssize_t k = 0;
    for (py::ssize_t d : dims) {
        if (d >= 0 && a.shape(k) != d) return false;
        ++k;
    }
    return true;
}

// has_shape, or EngineInputError naming the array, the shape expected and the one given.
void expect_shape(const char* name, const py::array& a, std::initializer_list<py::ssize_t> dims) {
    if (has_shape(a, dims)) return;
    std::string want, got;
    for (py::ssize_t d : dims)
        want += (want.empty() ? "" : ", ") + (d < 0 ? std::string("n") : std::to_string(d));
    for (py::ssize_t i = 0; i < a.ndim(); ++i) got += (i ? ", " : "") + std::to_string(a.shape(i));
    throw std::invalid_argument(std::string(name) + ": expected shape (" + want + "), got (" +
                                got + ")");
}

template <class T>
T* writable(const char* name, Array<T>& a) {
    if (!a.writeable())
        throw std::invalid_argument(std::string(name) + ": the array is read-only");
    return a.mutable_data();
}

// The data of h if it is already an array the engine takes as it is (C-contiguous, aligned
// float64 of the extents dims), else nullptr: the check of every joint-state message, which
// costs less than converting.
const double* exact_doubles(py::handle h, std::initializer_list<py::ssize_t> dims) {
    // On every query: the array's own fields only, read as py::array's accessors read them
    // (isinstance<Array<double>> would build a dtype and compare it, about 0.1 us a call).
    if (!py::array::check_(h)) return nullptr;
    const auto* a = py::detail::array_proxy(h.ptr());
    const auto* type = py::detail::array_descriptor_proxy(a->descr);
    if (type->type_num != py::detail::npy_api::NPY_DOUBLE_ ||
        (type->byteorder != '=' && type->byteorder != native_order) ||
        !(a->flags & py::detail::npy_api::NPY_ARRAY_C_CONTIGUOUS_) ||
        a->nd != int(dims.size()))
        return nullptr;
    int k = 0;
    for (const py::ssize_t d : dims) {
        if (d >= 0 && a->dimensions[k] != d) return nullptr;
        ++k;
    }
    const auto* data = reinterpret_cast<const double*>(a->data);
    if (reinterpret_cast<std::uintptr_t>(data) % alignof(double) != 0) return nullptr;
    return data;
}

//: Engine.query's answer for an argument that is not a C-contiguous float64 array of J values.
constexpr int64_t NOT_AN_ARRAY = INT64_MIN;

// The checker's engine: the C++ Engine over the two packed buffers, which it keeps alive.
struct PyEngine {
    Array<double> F;
    Array<int64_t> I;
    std::unique_ptr<cs::Engine> engine;

    PyEngine(Array<double> F_, const Array<int64_t>& F_layout, Array<int64_t> I_,
             const Array<int64_t>& I_layout, int box_test, int expansion,
             double motion_tolerance, int64_t threads, double min_chunk_us)
        : F(std::move(F_)), I(std::move(I_)) {
        expect_shape("F", F, {-1});
        expect_shape("I", I, {-1});
        expect_shape("F_layout", F_layout, {cs::N_FLOAT_SLOTS, cs::LAYOUT_WIDTH});
        expect_shape("I_layout", I_layout, {cs::N_INT_SLOTS, cs::LAYOUT_WIDTH});
        cs::Options options;
        options.box_test = box_test;
        options.expansion = expansion;
        options.motion_tolerance = motion_tolerance;
        options.threads = threads;
        options.min_chunk_us = min_chunk_us;
        engine = std::make_unique<cs::Engine>(writable("F", F), F.shape(0), F_layout.data(),
                                              writable("I", I), I.shape(0), I_layout.data(),
                                              options);
    }

    // q: any object. The checker passes what its caller gave; only an array the engine takes
    // as it is (exact_doubles) is run, anything else answers NOT_AN_ARRAY and the checker
    // converts it first.
    int64_t query(py::handle q, bool full) {
        const double* data = exact_doubles(q, {engine->model().n_joints});
        if (!data) return NOT_AN_ARRAY;
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(engine->lock());
        return engine->query(data, full);
    }

    // T: any object; only a (4, 4) array the engine takes as it is is used, anything else
    // answers MOVE_REFUSED.
    int64_t move_world_body(int64_t b, py::handle T) {
        const double* data = exact_doubles(T, {4, 4});
        if (!data) return cs::MOVE_REFUSED;
        std::lock_guard<std::mutex> hold(engine->lock());
        return engine->move_world_body(b, data);
    }

    int64_t place_attached_body(int64_t b, const Array<double>& T, const Array<int64_t>& pairs,
                                const Array<double>& reach, const Array<double>& reach_ext) {
        const py::ssize_t n = pairs.size(), J = engine->model().n_joints;
        expect_shape("T", T, {4, 4});
        expect_shape("pairs", pairs, {n});
        expect_shape("reach", reach, {n, J});
        expect_shape("reach_ext", reach_ext, {n, J});
        std::lock_guard<std::mutex> hold(engine->lock());
        return engine->place_attached_body(b, T.data(), pairs.data(), n, reach.data(),
                                           reach_ext.data());
    }

    int64_t batch(const Array<double>& Q, bool full, Array<uint8_t> statuses,
                  Array<int64_t> codes) {
        expect_shape("Q", Q, {-1, engine->model().n_joints});
        const py::ssize_t n = Q.shape(0);
        expect_shape("statuses", statuses, {n, engine->model().n_pairs});
        expect_shape("codes", codes, {n});
        const double* data = Q.data();
        uint8_t* out = writable("statuses", statuses);
        int64_t* out_codes = writable("codes", codes);
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(engine->lock());
        return engine->batch(data, n, full, out, out_codes);
    }

    int64_t proximity(const Array<double>& q, double max_distance, Array<double> distance,
                      Array<double> points) {
        const cs::Model& model = engine->model();
        expect_shape("q", q, {model.n_joints});
        expect_shape("distance", distance, {model.n_pairs});
        expect_shape("points", points, {model.n_pairs, 6});
        const double* data = q.data();
        const cs::ProximityRequest request = {max_distance};
        const cs::ProximityResult result = {writable("distance", distance),
                                            writable("points", points)};
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(engine->lock());
        return engine->read_at(data, [&](const cs::EngineView& view, cs::Scratch& scratch) {
            cs::measure_proximity(view, request, scratch, result);
        });
    }

    void poses() {
        std::lock_guard<std::mutex> hold(engine->lock());
        engine->refresh_all_poses();
    }

    // The motion checks (engine.hpp): each answer's pairs and t are kept, for last_motion.
    std::vector<uint8_t> motion_pairs;
    double motion_t = 0.0;

    uint8_t* motion_rows() {
        motion_pairs.assign(engine->model().n_pairs, 0);
        return motion_pairs.data();
    }

    // q0, q1 as query takes them (NOT_AN_ARRAY unless both are).
    int64_t motion(py::handle q0, py::handle q1) {
        const int64_t J = engine->model().n_joints;
        const double* from = exact_doubles(q0, {J});
        const double* to = from ? exact_doubles(q1, {J}) : nullptr;
        if (!to) return NOT_AN_ARRAY;
        uint8_t* out = motion_rows();
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(engine->lock());
        return engine->motion(from, to, &motion_t, out);
    }

    // q as query takes it (NOT_AN_ARRAY else). The answer is 2 * the query's code + the
    // motion's (1: it met contact), or the motion's -1 - j: one call on a stream's path.
    int64_t update_motion(py::handle q) {
        const double* data = exact_doubles(q, {engine->model().n_joints});
        if (!data) return NOT_AN_ARRAY;
        uint8_t* out = motion_rows();
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(engine->lock());
        int64_t query_code = 0;
        const int64_t code = engine->update_motion(data, &motion_t, out, &query_code);
        return code < 0 ? code : 2 * query_code + code;
    }

    py::tuple path(const Array<double>& Q) {
        expect_shape("Q", Q, {-1, engine->model().n_joints});
        if (Q.shape(0) < 1) throw std::invalid_argument("Q: no waypoint");
        uint8_t* out = motion_rows();
        int64_t segment = -1, code;
        {
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> hold(engine->lock());
            code = engine->path(Q.data(), Q.shape(0), &segment, &motion_t, out);
        }
        return py::make_tuple(code, segment);
    }

    py::tuple spline(const Array<double>& coef) {
        expect_shape("coef", coef, {-1, engine->model().n_joints, 6});
        uint8_t* out = motion_rows();
        int64_t segment = -1, code;
        {
            py::gil_scoped_release release;
            std::lock_guard<std::mutex> hold(engine->lock());
            code = engine->spline(coef.data(), coef.shape(0), &segment, &motion_t, out);
        }
        return py::make_tuple(code, segment);
    }

    // The checked pairs' names, one per pair (name_pairs), for last_motion's answer; the
    // answer's type (a tuple subclass: in_collision, first_contact, colliding_pairs) and its
    // free instance, for motion_answer's.
    py::tuple pair_names;
    py::object result_type, free_result;

    void name_pairs(py::tuple names, py::object type, py::object free) {
        if (py::ssize_t(names.size()) != py::ssize_t(engine->model().n_pairs))
            throw std::invalid_argument("names: one per checked pair");
        if (!PyType_Check(type.ptr()) ||
            !PyType_IsSubtype(reinterpret_cast<PyTypeObject*>(type.ptr()), &PyTuple_Type))
            throw std::invalid_argument("type: a subclass of tuple");
        pair_names = std::move(names);
        result_type = std::move(type);
        free_result = std::move(free);
    }

    // The names of the pairs the last motion check met, in the pairs' order.
    py::tuple contact_names() {
        if (py::ssize_t(pair_names.size()) != py::ssize_t(engine->model().n_pairs))
            throw std::logic_error("name the pairs first (name_pairs)");
        py::ssize_t count = 0;
        for (const uint8_t hit : motion_pairs) count += hit != 0;
        py::tuple names(count);
        py::ssize_t k = 0;
        for (size_t p = 0; p < motion_pairs.size(); ++p)
            if (motion_pairs[p]) names[k++] = pair_names[p];
        return names;
    }

    py::tuple last_motion() { return py::make_tuple(motion_t, contact_names()); }

    // motion's answer as the checker gives it, in one call: free_result, or a result_type
    // (True, t, the pairs' names as last_motion's); None for anything motion does not answer
    // 0 or 1 to (ask motion).
    py::object motion_answer(py::handle q0, py::handle q1) {
        const int64_t code = motion(q0, q1);
        if (code == 0) return free_result;
        if (code != 1) return py::none();
        py::tuple names = contact_names();
        py::float_ t(motion_t);
        // What tuple.__new__(result_type, fields) makes, without the NamedTuple's __new__.
        PyTypeObject* type = reinterpret_cast<PyTypeObject*>(result_type.ptr());
        PyObject* made = type->tp_alloc(type, 3);
        if (!made) throw py::error_already_set();
        PyTuple_SET_ITEM(made, 0, py::bool_(true).release().ptr());
        PyTuple_SET_ITEM(made, 1, t.release().ptr());
        PyTuple_SET_ITEM(made, 2, names.release().ptr());
        return py::reinterpret_steal<py::object>(made);
    }
};

// One source's point cloud (voxel_cloud.hpp), shared by the engines that show it: the
// checker's, and the next one a scene change lays out.
struct PyVoxelCloud {
    std::shared_ptr<cs::VoxelCloud> cloud = std::make_shared<cs::VoxelCloud>();

    // The current grid's voxel centres (V, 3) and their seen stamps (V,), world frame.
    py::tuple voxels() const {
        std::lock_guard<std::mutex> hold(cloud->building);
        const cs::VoxelGrid& g = cloud->current();
        Array<double> centres({py::ssize_t(g.count), py::ssize_t(3)});
        Array<double> seen(py::ssize_t(g.count));
        for (int64_t v = 0; v < g.count; ++v) {
            g.centre(v, centres.mutable_data() + 3 * v);
            seen.mutable_data()[v] = g.seen[v];
        }
        return py::make_tuple(centres, seen, g.size);
    }
};

// (points, capped, invalid, out_of_range, self_filtered, kept_points, voxels, persisted).
py::tuple stats_tuple(const cs::CloudStats& s) {
    return py::make_tuple(s.points, s.capped, s.invalid, s.out_of_range, s.self_filtered,
                          s.kept_points, s.voxels, s.persisted);
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
          offset(std::move(offset_)), n_joints(n_joints_), kin(checked_tree()) {}

    cs::KinematicTree checked_tree() const {
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
                throw std::invalid_argument(
                    "parent: links must come root first, parents before children");
            const int64_t kind = joint_type.data()[i];
            if (kind < cs::JOINT_FIXED || kind > cs::JOINT_FLOATING)
                throw std::invalid_argument("joint_type: unknown joint type " +
                                            std::to_string(kind));
            if (kind != cs::JOINT_FIXED &&
                (q_index.data()[i] < 0 ||
                 q_index.data()[i] + cs::joint_variable_count(kind) > n_joints))
                throw std::invalid_argument("q_index: index out of range for " +
                                            std::to_string(n_joints) + " joint values");
        }
        return {int64_t(L), parent.data(), joint_type.data(), T_parent_joint.data(),
                axis.data(), q_index.data(), multiplier.data(), offset.data()};
    }

    // Every link's pose for q (J,) as a new (L, 4, 4) array, or for Q (n, J) as (n, L, 4, 4).
    // A value the engine cannot honour raises JointStateError with its row and variable.
    py::array forward(const Array<double>& q) {
        if (q.ndim() == 2)
            expect_shape("q", q, {-1, n_joints});
        else
            expect_shape("q", q, {n_joints});
        const py::ssize_t n = q.ndim() == 2 ? q.shape(0) : 1;
        const py::ssize_t L = kin.n_links;
        const double* Q = q.data();
        for (py::ssize_t k = 0; k < n; ++k) {
            const int64_t bad = cs::unusable_variable(kin, Q + n_joints * k, n_joints);
            if (bad >= 0)
                raise_joint_state("variable " + std::to_string(bad) + " of row " +
                                      std::to_string(k) + " is not usable",
                                  k, bad);
        }
        Array<double> out = q.ndim() == 2 ? Array<double>({n, L, py::ssize_t(4), py::ssize_t(4)})
                                          : Array<double>({L, py::ssize_t(4), py::ssize_t(4)});
        double* T = out.mutable_data();
        if (n == 1) {  // one configuration: cheaper than releasing the interpreter
            cs::forward_kinematics(kin, Q, T);
        } else {
            py::gil_scoped_release release;
            for (py::ssize_t k = 0; k < n; ++k)
                cs::forward_kinematics(kin, Q + n_joints * k, T + 16 * L * k);
        }
        return std::move(out);
    }
};

// The box pairs as the box tests take them: ha, hb (n, 3), R (n, 3, 3), t (n, 3).
py::ssize_t expect_box_pairs(const Array<double>& ha, const Array<double>& hb,
                             const Array<double>& R, const Array<double>& t) {
    const py::ssize_t n = ha.ndim() == 2 ? ha.shape(0) : -1;
    expect_shape("ha", ha, {n, 3});
    expect_shape("hb", hb, {n, 3});
    expect_shape("R", R, {n, 3, 3});
    expect_shape("t", t, {n, 3});
    return n;
}

// One or n triangles: P, Q (3, 3) or (n, 3, 3); returns n (1 for one).
py::ssize_t expect_triangles(const Array<double>& P, const Array<double>& Q) {
    if (P.ndim() == 2) {
        expect_shape("P", P, {3, 3});
        expect_shape("Q", Q, {3, 3});
        return 1;
    }
    const py::ssize_t n = P.ndim() == 3 ? P.shape(0) : -1;
    expect_shape("P", P, {n, 3, 3});
    expect_shape("Q", Q, {n, 3, 3});
    return n;
}

// (name, group, shape) of each slot, shape entries an int or a dimension's name ("joints+1").
py::tuple slot_table(const cs::SlotSpec* specs, int n) {
    py::list out;
    for (int k = 0; k < n; ++k) {
        const cs::SlotSpec& s = specs[k];
        py::list shape;
        for (int a = 0; a < s.shape.ndim; ++a) {
            const cs::Extent& e = s.shape.extent[a];
            if (e.dim == cs::DIM_NONE)
                shape.append(e.plus);
            else
                shape.append(std::string(cs::DIM_NAMES[e.dim]) +
                             (e.plus ? "+" + std::to_string(e.plus) : ""));
        }
        out.append(py::make_tuple(s.name, cs::GROUP_NAMES[s.group], py::tuple(shape)));
    }
    return py::tuple(out);
}

void export_constants(py::module_& m) {
#define CS_EXPORT(name) m.attr(#name) = cs::name;
    // layout.hpp: the packed arrays, and what their rows and flags hold
    m.attr("FLOAT_SLOTS") = slot_table(cs::FLOAT_SLOT_SPECS, cs::N_FLOAT_SLOTS);
    m.attr("INT_SLOTS") = slot_table(cs::INT_SLOT_SPECS, cs::N_INT_SLOTS);
    py::list dims;
    for (const char* name : cs::DIM_NAMES) dims.append(name);
    m.attr("DIMS") = py::tuple(dims);
    CS_EXPORT(LAYOUT_WIDTH)
    CS_EXPORT(QUERY_CHECKED_ONCE) CS_EXPORT(QUERY_CALLS) CS_EXPORT(N_QUERY_FLAGS)
    CS_EXPORT(SOLID_NONE) CS_EXPORT(SOLID_BOX) CS_EXPORT(SOLID_SPHERE) CS_EXPORT(SOLID_CYLINDER)
    CS_EXPORT(SOLID_CLOSED_MESH) CS_EXPORT(SOLID_PROBE) CS_EXPORT(SOLID_WIDTH)
    // obb_tree.hpp: the forest's tables
    CS_EXPORT(BOX_CENTER) CS_EXPORT(BOX_AXES) CS_EXPORT(BOX_HALF) CS_EXPORT(BOX_RADIUS)
    CS_EXPORT(BOX_WIDTH)
    CS_EXPORT(NODE_LEFT) CS_EXPORT(NODE_RIGHT) CS_EXPORT(NODE_FIRST) CS_EXPORT(NODE_COUNT)
    CS_EXPORT(NODE_WIDTH)
    // box_test.hpp, traversal.hpp
    CS_EXPORT(BOX_TEST_PAPER) CS_EXPORT(BOX_TEST_SAT)
    CS_EXPORT(EXPAND_SAME) CS_EXPORT(EXPAND_ALTERNATE) CS_EXPORT(EXPAND_LARGER)
    CS_EXPORT(EXPAND_PROMISING) CS_EXPORT(EXPAND_WIDER)
    CS_EXPORT(COUNT_BOX_TESTS) CS_EXPORT(COUNT_TRIANGLE_TESTS) CS_EXPORT(COUNT_SPHERE_SKIPS)
    CS_EXPORT(COUNT_FRONT_STARTS) CS_EXPORT(COUNT_FRONT_UNTESTED) CS_EXPORT(COUNT_SWEEPS)
    CS_EXPORT(COUNT_SWEEP_STEPS) CS_EXPORT(COUNT_MEASURES) CS_EXPORT(N_COUNTERS)
    CS_EXPORT(POSE_WIDTH)
    py::list hexagon;
    for (const auto& row : cs::box_detail::HEXAGON)
        hexagon.append(py::make_tuple(row[0], row[1], row[2], row[3], row[4], row[5]));
    m.attr("HEXAGON") = py::tuple(hexagon);
    // kinematics.hpp
    CS_EXPORT(JOINT_FIXED) CS_EXPORT(JOINT_REVOLUTE) CS_EXPORT(JOINT_PRISMATIC)
    CS_EXPORT(JOINT_PLANAR) CS_EXPORT(JOINT_FLOATING)
    CS_EXPORT(PRISMATIC_VALUE_MAX) CS_EXPORT(QUATERNION_NORM_MIN)
    CS_EXPORT(MOTION_LINEAR) CS_EXPORT(MOTION_WRAP) CS_EXPORT(MOTION_QUATERNION)
    CS_EXPORT(MOTION_QUATERNION_REST)
    // motion.hpp
    CS_EXPORT(MOTION_TOUCH_TOLERANCE) CS_EXPORT(MOTION_BOUND_REL) CS_EXPORT(MOTION_FRONT_MAX)
    m.attr("JOINT_VARIABLES") = py::make_tuple(cs::JOINT_VARIABLES[0], cs::JOINT_VARIABLES[1],
                                               cs::JOINT_VARIABLES[2], cs::JOINT_VARIABLES[3],
                                               cs::JOINT_VARIABLES[4]);
    // tolerances.hpp
    CS_EXPORT(BOX_EPS_REL) CS_EXPORT(BOX_EPS_PARALLEL) CS_EXPORT(TRIANGLE_EPS_REL)
    CS_EXPORT(SPHERE_EPS_REL)
    // engine.hpp: the scene methods
    CS_EXPORT(MOVE_REFUSED) CS_EXPORT(MAX_COORDINATE) CS_EXPORT(ROTATION_TOLERANCE)
    // voxel_grid.hpp, cloud_queries.hpp: point clouds
    CS_EXPORT(VOXEL_COORD_BITS) CS_EXPORT(VOXEL_COORD_LIMIT) CS_EXPORT(VOXEL_LEAF_SIZE)
    CS_EXPORT(MAX_CLOUD_CLEARANCE)
    m.attr("NOT_AN_ARRAY") = NOT_AN_ARRAY;
#undef CS_EXPORT
}

// CollisionChecker.check_motion as a plain callable (vectorcall): motion_answer, or, where
// that is None, the checker's own Python path (fallback). A primitive's whole sweep costs
// about as much as pybind11's dispatch of a method, or a Python method's frame, which this
// skips. It is aimed at one engine at a time (Engine.aim: the checker's current one, so a
// caller kept across a scene change answers for the new scene), which it keeps alive, as
// every call does the engine it started with.
struct MotionAnswer {
    PyObject_HEAD
    vectorcallfunc vectorcall;
    PyObject* owner;     // the Engine object
    PyEngine* engine;
    PyObject* fallback;  // (q0, q1) -> the answer, or nullptr
};

PyObject* motion_answer_call(PyObject* callable, PyObject* const* args, size_t nargsf,
                             PyObject* kwnames) {
    auto* self = reinterpret_cast<MotionAnswer*>(callable);
    const Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    if (nargs != 2 || (kwnames && PyTuple_GET_SIZE(kwnames) != 0)) {
        if (self->fallback)  // keywords, or a wrong count: the Python path says what is wrong
            return PyObject_Vectorcall(self->fallback, args, nargsf, kwnames);
        PyErr_SetString(PyExc_TypeError, "check_motion(q_from, q_to): two arguments");
        return nullptr;
    }
    PyObject* owner = self->owner;
    Py_INCREF(owner);  // an aim elsewhere during the call leaves this engine alive
    PyObject* answer = nullptr;
    try {
        answer = self->engine->motion_answer(args[0], args[1]).release().ptr();
    } catch (py::error_already_set& error) {
        error.restore();
    } catch (const std::exception& error) {
        PyErr_SetString(PyExc_RuntimeError, error.what());
    }
    Py_DECREF(owner);
    if (answer == Py_None && self->fallback) {
        Py_DECREF(answer);
        return PyObject_Vectorcall(self->fallback, args, nargsf, nullptr);
    }
    return answer;
}

int motion_answer_traverse(PyObject* object, visitproc visit, void* arg) {
    auto* self = reinterpret_cast<MotionAnswer*>(object);
    Py_VISIT(self->owner);
    Py_VISIT(self->fallback);
    Py_VISIT(Py_TYPE(object));
    return 0;
}

int motion_answer_clear(PyObject* object) {
    Py_CLEAR(reinterpret_cast<MotionAnswer*>(object)->fallback);  // the checker's cycle
    return 0;
}

void motion_answer_dealloc(PyObject* object) {
    PyTypeObject* type = Py_TYPE(object);  // a heap type: each instance holds it
    PyObject_GC_UnTrack(object);
    auto* self = reinterpret_cast<MotionAnswer*>(object);
    Py_CLEAR(self->fallback);
    Py_CLEAR(self->owner);
    type->tp_free(object);
    Py_DECREF(type);
}

PyTypeObject* motion_answer_type() {
    static PyMemberDef members[] = {
        {const_cast<char*>("__vectorcalloffset__"), T_PYSSIZET,
         Py_ssize_t(offsetof(MotionAnswer, vectorcall)), READONLY, nullptr},
        {nullptr, 0, 0, 0, nullptr}};
    static PyType_Slot slots[] = {
        {Py_tp_dealloc, reinterpret_cast<void*>(motion_answer_dealloc)},
        {Py_tp_traverse, reinterpret_cast<void*>(motion_answer_traverse)},
        {Py_tp_clear, reinterpret_cast<void*>(motion_answer_clear)},
        {Py_tp_call, reinterpret_cast<void*>(PyVectorcall_Call)},
        {Py_tp_members, members},
        {Py_tp_doc, const_cast<char*>(
                        "check_motion(q_from, q_to) -> MotionResult, compiled: see "
                        "CollisionChecker.check_motion.")},
        {0, nullptr}};
    static PyType_Spec spec = {"collision_sensor.engine._engine.MotionAnswer",
                               int(sizeof(MotionAnswer)), 0,
                               Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_VECTORCALL |
                                   Py_TPFLAGS_HAVE_GC,
                               slots};
    static PyObject* type = PyType_FromSpec(&spec);
    if (!type) throw py::error_already_set();
    return reinterpret_cast<PyTypeObject*>(type);
}

// Aim caller (a MotionAnswer) at engine self.
void aim_motion_answer(py::object self, py::handle caller) {
    if (Py_TYPE(caller.ptr()) != motion_answer_type())
        throw std::invalid_argument("aim: not a motion_caller() answer");
    auto* answer = reinterpret_cast<MotionAnswer*>(caller.ptr());
    PyObject* old = answer->owner;
    answer->engine = &self.cast<PyEngine&>();
    answer->owner = self.inc_ref().ptr();
    Py_XDECREF(old);
}

void bind_engine(py::module_& m) {
    py::class_<PyEngine>(m, "Engine",
                         "The query engine over a checker's packed buffers F (float64) and I "
                         "(int64) and their layout rows (cpp/layout.hpp); see cpp/engine.hpp. "
                         "Not for use outside CollisionChecker.")
        .def(py::init<Array<double>, const Array<int64_t>&, Array<int64_t>,
                      const Array<int64_t>&, int, int, double, int64_t, double>(),
             py::arg("F").noconvert(), py::arg("F_layout"), py::arg("I").noconvert(),
             py::arg("I_layout"), py::arg("box_test"), py::arg("expansion"),
             py::arg("motion_tolerance"), py::arg("threads") = 1,
             py::arg("min_chunk_us") = 0.0)
        .def_property_readonly(
            "threads", [](const PyEngine& e) { return e.engine->threads(); },
            "The threads batch, path and spline run on (the threads setting resolved: 0 "
            "asked for the machine's hardware threads).")
        .def("query", &PyEngine::query, py::arg("q"), py::arg("full"),
             "Bring the statuses up to date with q (a C-contiguous float64 array of J values; "
             "anything else answers NOT_AN_ARRAY and changes nothing); return 2 * rechecked + "
             "changed, or -1 - j when q[j] is not usable: not finite, or beyond the engine's "
             "range (nothing changed then).")
        .def("batch", &PyEngine::batch, py::arg("Q"), py::arg("full"),
             py::arg("statuses").noconvert(), py::arg("codes").noconvert(),
             "query() on each row of Q; statuses (n, P) uint8 and codes (n,) written; return n, "
             "or -1 - (J i + j) when row i's value j is not usable (nothing changed then).")
        .def("proximity", &PyEngine::proximity, py::arg("q"), py::arg("max_distance"),
             py::arg("distance").noconvert(), py::arg("points").noconvert(),
             "query(q, False), then each pair's distance (P,) (inf when not below "
             "max_distance, <= 0 when in contact) and nearest points (P, 6), world frame, "
             "written in place; return query()'s code.")
        .def("poses", &PyEngine::poses, "Bring every link pose up to date.")
        .def("move_world_body", &PyEngine::move_world_body, py::arg("b"), py::arg("T"),
             "Give world object b the pose T ((4, 4) C-contiguous float64) and force its pairs, "
             "if T is a rigid transform within MAX_COORDINATE; return 0, or MOVE_REFUSED "
             "(nothing changed then, also for anything but such an array).")
        .def("motion", &PyEngine::motion, py::arg("q0"), py::arg("q1"),
             "The straight motion q0 -> q1 (J,), carried state untouched: 0 free, 1 contact "
             "(last_motion() then), or -1 - j for an unusable value (j >= J: q1's); "
             "NOT_AN_ARRAY unless both are arrays as query takes them.")
        .def("update_motion", &PyEngine::update_motion, py::arg("q"),
             "The motion from the carried state to q (as query takes it: NOT_AN_ARRAY else), "
             "then query(q, False): 2 * query's code + 1 if the motion met contact "
             "(last_motion() then), or -1 - j for an unusable value (nothing changed then).")
        .def("path", &PyEngine::path, py::arg("Q"),
             "The straight motions between consecutive rows of Q (n >= 1, J) until one is not "
             "free: (code, segment), code as motion, -1 - (J i + j) for row i's value j.")
        .def("spline", &PyEngine::spline, py::arg("coef"),
             "The polynomial segments coef (n, J, 6) (q_j(t) = sum_k coef[i, j, k] t^k, t in "
             "[0, 1]) until one is not free: (code, segment) as path; -1 - i for a segment i "
             "the engine refuses.")
        .def("name_pairs", &PyEngine::name_pairs, py::arg("names"), py::arg("result_type"),
             py::arg("free"),
             "Give the checked pairs' names (a tuple, one per pair, in the pairs' order), "
             "which last_motion answers with, and motion_answer's type (a tuple subclass of "
             "in_collision, first_contact, colliding_pairs) and free answer.")
        .def("motion_caller",
             [](py::object self, py::object fallback) {
                 PyTypeObject* type = motion_answer_type();
                 auto* caller = PyObject_GC_New(MotionAnswer, type);
                 if (!caller) throw py::error_already_set();
                 caller->vectorcall = motion_answer_call;
                 caller->owner = self.inc_ref().ptr();
                 caller->engine = &self.cast<PyEngine&>();
                 caller->fallback = fallback.is_none() ? nullptr : fallback.inc_ref().ptr();
                 PyObject_GC_Track(reinterpret_cast<PyObject*>(caller));
                 return py::reinterpret_steal<py::object>(reinterpret_cast<PyObject*>(caller));
             },
             py::arg("fallback") = py::none(),
             "A plain callable of (q0, q1), without pybind11's dispatch, that answers "
             "motion(q0, q1) as the checker does: free (name_pairs), or result_type(True, t, "
             "names) as last_motion; where motion answers anything else, fallback(q0, q1) "
             "(None without one). It keeps the engine it is aimed at alive.")
        .def("aim", &aim_motion_answer, py::arg("caller"),
             "Aim a motion_caller() answer at this engine from now on.")
        .def("last_motion", &PyEngine::last_motion,
             "The last motion check's (t, pairs): its first contact's fraction and the "
             "names (name_pairs), in the pairs' order, of the pairs in contact (or within "
             "MOTION_TOUCH_TOLERANCE) there.")
        .def("place_attached_body", &PyEngine::place_attached_body, py::arg("b"), py::arg("T"),
             py::arg("pairs"), py::arg("reach"), py::arg("reach_ext"),
             "Give attached object b (a link on a fixed joint) the pose T (4, 4) in its link's "
             "frame, its pairs (n,) the reach rows reach, reach_ext (n, J), and force them; "
             "return 0, or MOVE_REFUSED (nothing changed then).")
        .def("attach_cloud",
             [](PyEngine& self, int64_t b, const PyVoxelCloud& cloud) {
                 std::lock_guard<std::mutex> hold(self.engine->lock());
                 return self.engine->attach_cloud(b, cloud.cloud);
             },
             py::arg("b"), py::arg("cloud"),
             "Make world object b (a body without trees, at the identity) show cloud's current "
             "grid and force its pairs; return 0, or MOVE_REFUSED (nothing changed then).")
        .def("commit_cloud",
             [](PyEngine& self, int64_t b, int64_t ticket) {
                 std::lock_guard<std::mutex> hold(self.engine->lock());
                 return self.engine->commit_cloud(b, ticket);
             },
             py::arg("b"), py::arg("ticket"),
             "Make build `ticket` of body b's cloud current and force its pairs; return 0, or "
             "MOVE_REFUSED (not its last build to commit: nothing changed then).")
        .def("cast_rays",
             [](PyEngine& self, const Array<double>& origin, const Array<double>& dirs,
                double max_range) {
                 expect_shape("origin", origin, {3});
                 expect_shape("dirs", dirs, {-1, 3});
                 const cs::Model& m = self.engine->model();
                 const py::ssize_t n = dirs.shape(0);
                 Array<double> t(n);
                 double* out = t.mutable_data();
                 const double* o = origin.data();
                 const double* d = dirs.data();
                 py::gil_scoped_release release;
                 std::vector<int64_t> roots;
                 std::vector<double> poses;
                 {
                     std::lock_guard<std::mutex> hold(self.engine->lock());
                     self.engine->refresh_all_poses();
                     const double* T = self.engine->view().state.poses.T_world_body;
                     for (int64_t b = 0; b < m.n_bodies; ++b) {
                         for (int64_t e = m.elem_start[b]; e < m.elem_end[b]; ++e) {
                             roots.push_back(m.roots[e]);
                             poses.insert(poses.end(), T + 16 * b, T + 16 * b + 16);
                         }
                     }
                 }
                 cs::cast_rays(m.forest, roots.data(), poses.data(), int64_t(roots.size()), o,
                               d, n, max_range, out);
                 return t;
             },
             py::arg("origin"), py::arg("dirs"), py::arg("max_range"),
             "Each ray origin + t dirs[i] (unit, world frame) against every tree at the last "
             "checked state (point clouds have none): the nearest t (n,), inf beyond max_range.");

    py::class_<PyVoxelCloud>(m, "VoxelCloud",
                             "One source's point cloud obstacle (cpp/voxel_cloud.hpp): its "
                             "current voxels, and the next cloud built off every lock.")
        .def(py::init<>())
        .def("voxels", &PyVoxelCloud::voxels,
             "(centres (V, 3), seen (V,), voxel size) of the current grid, world frame.")
        .def("prepare",
             [](PyVoxelCloud& self, PyEngine& owner, const py::array& points, int64_t frame,
                const Array<double>& q, double voxel_size, double filter_padding,
                double max_range, int64_t max_points, double stamp, double persistence,
                bool keep_points, int64_t threads) {
                 const cs::Model& model = owner.engine->model();
                 const bool f32 = py::isinstance<py::array_t<float>>(points);
                 if (!(f32 || py::isinstance<py::array_t<double>>(points)) || points.ndim() != 2 ||
                     points.shape(1) != 3)
                     throw std::invalid_argument(
                         "points: expected an (n, 3) float32 or float64 array");
                 expect_shape("q", q, {model.n_joints});
                 if (frame < -1 || frame >= model.n_links)
                     throw std::invalid_argument("frame: not a link of the engine");
                 if (!(voxel_size > 0.0 && std::isfinite(voxel_size) && filter_padding >= 0.0 &&
                       std::isfinite(filter_padding) && max_range > 0.0 && max_points > 0 &&
                       std::isfinite(stamp) && persistence >= 0.0 && std::isfinite(persistence) &&
                       threads >= 0 && threads <= cs::MAX_THREADS))
                     throw std::invalid_argument(
                         "voxel_size, filter_padding, max_range, max_points, stamp, "
                         "persistence, threads: out of range");
                 const int64_t bad = cs::unusable_variable(model.kin, q.data(), model.n_joints);
                 if (bad >= 0) raise_joint_state("joint value not usable", 0, bad);
                 cs::CloudPoints cloud = {static_cast<const char*>(points.data()),
                                          int64_t(points.shape(0)), int64_t(points.strides(0)),
                                          int64_t(points.strides(1)), f32};
                 const cs::CloudSettings settings = {voxel_size, filter_padding, max_range,
                                                     max_points,  stamp,          persistence,
                                                     frame,       keep_points,
                                                     cs::resolve_threads(threads)};
                 std::vector<double> T(16 * model.n_links);
                 {   // the link poses at q, with the engine's joint origins as they are now
                     std::lock_guard<std::mutex> hold(owner.engine->lock());
                     cs::forward_kinematics(model.kin, q.data(), T.data());
                 }
                 std::vector<float> kept;
                 int64_t ticket;
                 {
                     py::gil_scoped_release release;
                     ticket = self.cloud->build(model, T.data(), cloud, settings,
                                                keep_points ? &kept : nullptr);
                 }
                 py::object out = py::none();
                 if (keep_points) {
                     Array<float> array({py::ssize_t(kept.size() / 3), py::ssize_t(3)});
                     std::copy(kept.begin(), kept.end(), array.mutable_data());
                     out = std::move(array);
                 }
                 return py::make_tuple(ticket, stats_tuple(self.cloud->stats), out);
             },
             py::arg("engine"), py::arg("points"), py::arg("frame"), py::arg("q"),
             py::arg("voxel_size"), py::arg("filter_padding"), py::arg("max_range"),
             py::arg("max_points"), py::arg("stamp"), py::arg("persistence"),
             py::arg("keep_points"), py::arg("threads"),
             "Build the next grid from points (n, 3) float32/float64 in link `frame` (-1: the "
             "world), self-filtered at the joint values q against engine's robot "
             "(cpp/cloud_filter.hpp), on up to `threads` threads (0: every hardware thread; the "
             "same grid on any number); return (ticket, stats (points, capped, invalid, "
             "out_of_range, self_filtered, kept_points, voxels, persisted), the points kept "
             "(m, 3) float32 world frame or None). Runs without the interpreter lock.");

    py::class_<PyKinematics>(m, "Kinematics",
                             "A kinematic tree's arrays (kinematics.py: KinematicTree), checked "
                             "once; forward(q) gives every link's pose.")
        .def(py::init<Array<int64_t>, Array<int64_t>, Array<double>, Array<double>,
                      Array<int64_t>, Array<double>, Array<double>, py::ssize_t>(),
             py::arg("parent"), py::arg("joint_type"), py::arg("T_parent_joint"),
             py::arg("axis"), py::arg("q_index"), py::arg("multiplier"), py::arg("offset"),
             py::arg("n_joints"))
        .def("forward", &PyKinematics::forward, py::arg("q"),
             "Every link's pose: (L, 4, 4) for q (J,), (n, L, 4, 4) for q (n, J); "
             "JointStateError (with row and variable) for a value it cannot honour.");
}

void bind_query_kernels(py::module_& m) {
    m.def("boxes_disjoint",
          [](int method, const Array<double>& ha, const Array<double>& hb,
             const Array<double>& R, const Array<double>& t) {
              const py::ssize_t n = expect_box_pairs(ha, hb, R, t);
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
          "(BOX_TEST_PAPER or BOX_TEST_SAT) separates them.");

    m.def("separating_axis",
          [](const Array<double>& ha, const Array<double>& hb, const Array<double>& R,
             const Array<double>& t) {
              const py::ssize_t n = expect_box_pairs(ha, hb, R, t);
              Array<int64_t> out(n);
              int64_t* o = out.mutable_data();
              const double *a = ha.data(), *b = hb.data(), *r = R.data(), *c = t.data();
              for (py::ssize_t i = 0; i < n; ++i)
                  o[i] = cs::separating_axis(a + 3 * i, b + 3 * i, r + 9 * i, c + 3 * i);
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
              if (k < 0 || k > 14) throw std::invalid_argument("k: an axis 0 to 14");
              const cs::AxisGap g = cs::axis_gap(k, A.data(), B.data(), P.data());
              return py::make_tuple(g.separated, g.gap);
          },
          py::arg("k"), py::arg("A"), py::arg("B"), py::arg("P"),
          "(separated, gap) along axis k of separating_axis alone, for box rows A (body a) and "
          "B (body b at pose P: R_ab row-major, t_ab).");

    m.def("collide_trees",
          [](const Array<double>& boxes, const Array<int64_t>& nodes, const Array<double>& volume,
             const Array<double>& gain, const Array<double>& tris, int64_t root_a,
             int64_t root_b, const Array<double>& pose, int box_test, int expansion,
             double pad, double inflation) {
              expect_shape("boxes", boxes, {-1, cs::BOX_WIDTH});
              const py::ssize_t n = boxes.shape(0);
              expect_shape("nodes", nodes, {n, cs::NODE_WIDTH});
              expect_shape("volume", volume, {n});
              expect_shape("gain", gain, {n});
              expect_shape("tris", tris, {-1, 3, 3});
              expect_shape("pose", pose, {cs::POSE_WIDTH});
              const int64_t* node = nodes.data();
              for (py::ssize_t k = 0; k < n; ++k)
                  if (node[4 * k] >= n || node[4 * k + 1] >= n || node[4 * k + 2] < 0 ||
                      node[4 * k + 2] + node[4 * k + 3] > tris.shape(0))
                      throw std::invalid_argument("nodes: index out of range");
              if (root_a < 0 || root_a >= n || root_b < 0 || root_b >= n)
                  throw std::invalid_argument("root_a, root_b: not nodes");
              if (!(pad >= 0.0 && inflation >= 0.0))
                  throw std::invalid_argument("pad, inflation: not >= 0");
              if ((box_test != cs::BOX_TEST_PAPER && box_test != cs::BOX_TEST_SAT) ||
                  expansion < cs::EXPAND_SAME || expansion > cs::EXPAND_WIDER)
                  throw std::invalid_argument("box_test, expansion: not BOX_TEST_*, EXPAND_*");
              const cs::Forest forest = {boxes.data(), node, volume.data(), gain.data(),
                                         tris.data()};
              cs::TraversalRequest request;
              request.box_test = box_test;
              request.expansion = expansion;
              request.pad = pad;
              request.inflation = inflation;
              request.track = true;
              std::vector<int64_t> stack(3 * (n + 8)), counters(cs::N_COUNTERS);
              stack[0] = root_a;
              stack[1] = root_b;
              stack[2] = 0;
              const cs::TreePairTraversal traversal = {forest, pose.data(), request,
                                                       {stack.data(), counters.data()},
                                                       nullptr};
              const cs::TreesResult r = cs::collide_trees(traversal, 1);
              return py::make_tuple(r.hit, r.ia, r.ib, r.gap);
          },
          py::arg("boxes"), py::arg("nodes"), py::arg("volume"), py::arg("gain"),
          py::arg("tris"), py::arg("root_a"), py::arg("root_b"), py::arg("pose"),
          py::arg("box_test"), py::arg("expansion"), py::arg("pad"), py::arg("inflation"),
          "One traversal of two trees of a forest (tables as obb_tree.box_table, node_table): "
          "(hit, ia, ib, gap), gap a lower bound of the padded distance minus inflation when "
          "no triangles are within pad + inflation (cpp/traversal.hpp: collide_trees).");

    m.def("triangles_intersect",
          [](const Array<double>& P, const Array<double>& Q) {
              const py::ssize_t n = expect_triangles(P, Q);
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

    m.def("triangle_box_distance",
          [](const Array<double>& T, const Array<double>& lo, const Array<double>& hi) {
              expect_shape("T", T, {-1, 3, 3});
              const py::ssize_t n = T.shape(0);
              expect_shape("lo", lo, {n, 3});
              expect_shape("hi", hi, {n, 3});
              Array<double> d(n), x({n, py::ssize_t(3)}), y({n, py::ssize_t(3)});
              double *o = d.mutable_data(), *ox = x.mutable_data(), *oy = y.mutable_data();
              for (py::ssize_t i = 0; i < n; ++i)
                  o[i] = cs::triangle_box_distance(cs::triangle_at(T.data(), i),
                                                   lo.data() + 3 * i, hi.data() + 3 * i,
                                                   ox + 3 * i, oy + 3 * i);
              return py::make_tuple(d, x, y);
          },
          py::arg("T"), py::arg("lo"), py::arg("hi"),
          "Distances (n,) between the closed triangles T[i] ((n, 3, 3)) and the solid boxes "
          "[lo[i], hi[i]] ((n, 3)), nearest points x (n, 3) on T[i], y (n, 3) in the box.");

    m.def("triangle_box_within",
          [](const Array<double>& T, const Array<double>& lo, const Array<double>& hi,
             double pad) {
              expect_shape("T", T, {-1, 3, 3});
              const py::ssize_t n = T.shape(0);
              expect_shape("lo", lo, {n, 3});
              expect_shape("hi", hi, {n, 3});
              Array<bool> within(n);
              for (py::ssize_t i = 0; i < n; ++i) {
                  double d;
                  within.mutable_data()[i] = cs::triangle_box_within(
                      cs::triangle_at(T.data(), i), lo.data() + 3 * i, hi.data() + 3 * i, pad, &d);
              }
              return within;
          },
          py::arg("T"), py::arg("lo"), py::arg("hi"), py::arg("pad"),
          "True where the closed triangle T[i] comes within pad of the solid box [lo[i], hi[i]] "
          "(pad 0: meets it, touching counts).");

    m.def("triangle_distance",
          [](const Array<double>& P, const Array<double>& Q) {
              expect_shape("P", P, {-1, 3, 3});
              const py::ssize_t n = P.shape(0);
              expect_shape("Q", Q, {n, 3, 3});
              Array<double> d(n), x({n, py::ssize_t(3)}), y({n, py::ssize_t(3)});
              double *o = d.mutable_data(), *ox = x.mutable_data(), *oy = y.mutable_data();
              const double *p = P.data(), *r = Q.data();
              {
                  py::gil_scoped_release release;
                  for (py::ssize_t i = 0; i < n; ++i)
                      o[i] = cs::triangle_distance(cs::triangle_at(p, i), cs::triangle_at(r, i),
                                                   ox + 3 * i, oy + 3 * i);
              }
              return py::make_tuple(d, x, y);
          },
          py::arg("P"), py::arg("Q"),
          "Distances (n,) between the closed triangles P[i] and Q[i] ((n, 3, 3), rows the "
          "vertices) and nearest points x (n, 3) on P[i], y (n, 3) on Q[i].");
}

// Build-time kernels (bounding_volumes.hpp, obb_tree.hpp).
void bind_build_kernels(py::module_& m) {
    using Doubles = Array<double>;
    using Int64s = Array<int64_t>;
    auto points = [](const Doubles& a, const char* name) {
        expect_shape(name, a, {-1, 3});
        return a.shape(0);
    };
    auto nonempty = [](py::ssize_t n) {
        if (n == 0) throw std::invalid_argument("points must hold at least one point");
    };

    m.def("obb_volume", [](const Doubles& half) {
        expect_shape("half", half, {3});
        return cs::obb_volume(half.data());
    }, py::arg("half"), "Volume 8 hx hy hz of a box with half extents half (3,).");

    m.def("sphere_volume", &cs::sphere_volume, py::arg("r"),
          "Volume 4/3 pi r^3 of a sphere of radius r.");

    m.def("check_points", [points](const Doubles& p) {
        cs::check_points(p.data(), points(p, "points"));
    }, py::arg("points"), "Raise EngineInputError if points (n, 3) is empty or not finite.");

    m.def("covariance", [points, nonempty](const Doubles& p) {
        const py::ssize_t n = points(p, "points");
        nonempty(n);
        Doubles C({3, 3});
        cs::covariance(p.data(), n, C.mutable_data());
        return C;
    }, py::arg("points"), "(3, 3) covariance of points (n, 3), two-pass, 1/n normalised.");

    m.def("symmetric_eigen", [](const Doubles& C) {
        expect_shape("C", C, {3, 3});
        Doubles w(3), V({3, 3});
        cs::symmetric_eigen3(C.data(), w.mutable_data(), V.mutable_data());
        return py::make_tuple(w, V);
    }, py::arg("C"),
       "(w (3,), V (3, 3)) with C = V diag(w) V^T for a symmetric C (3, 3), by cyclic Jacobi; "
       "eigenvalues unsorted, eigenvector k in column k.");

    m.def("frame_from_eigenvectors", [](const Doubles& V, const Int64s& order) {
        expect_shape("V", V, {3, 3});
        expect_shape("order", order, {3});
        for (py::ssize_t i = 0; i < 2; ++i)
            if (order.at(i) < 0 || order.at(i) > 2)
                throw std::invalid_argument("order must hold column indices 0, 1 or 2");
        Doubles axes({3, 3});
        cs::frame_from_eigenvectors(V.data(), order.data(), axes.mutable_data());
        return axes;
    }, py::arg("V"), py::arg("order"),
       "Box frame (3, 3) from columns order[0], order[1] of V: orthonormalised, signs fixed, "
       "third axis their cross product.");

    m.def("principal_frame", [](const Doubles& C) {
        expect_shape("C", C, {3, 3});
        Doubles axes({3, 3});
        cs::principal_frame(C.data(), axes.mutable_data());
        return axes;
    }, py::arg("C"), "Box frame (3, 3) of a symmetric covariance C: eigenvectors, largest first.");

    m.def("box_on_axes", [points, nonempty](const Doubles& p, const Doubles& axes) {
        const py::ssize_t n = points(p, "points");
        nonempty(n);
        expect_shape("axes", axes, {3, 3});
        Doubles center(3), half(3);
        cs::box_on_axes(p.data(), n, axes.data(), center.mutable_data(), half.mutable_data());
        return py::make_tuple(center, half);
    }, py::arg("points"), py::arg("axes"),
       "(center (3,), half (3,)) of the smallest box with axes (3, 3) containing points (n, 3).");

    // A box fit's binding: (center (3,), axes (3, 3), half (3,)) of points (n, 3).
    using BoxFit = void (*)(const double*, int64_t, double*, double*, double*);
    const auto box_fit = [points](BoxFit fit) {
        return [points, fit](const Doubles& p) {
            const py::ssize_t n = points(p, "points");
            Doubles center(3), axes({3, 3}), half(3);
            fit(p.data(), n, center.mutable_data(), axes.mutable_data(), half.mutable_data());
            return py::make_tuple(center, axes, half);
        };
    };
    m.def("fit_obb_pca", box_fit(cs::fit_obb_pca), py::arg("points"),
          "(center (3,), axes (3, 3), half (3,)) of the principal-axes box of points (n, 3).");
    m.def("fit_obb_refined", box_fit(cs::fit_obb_refined), py::arg("points"),
          "(center (3,), axes (3, 3), half (3,)) of the principal-axes box of points (n, 3), "
          "tightened by the smallest-area rectangle around each principal axis.");

    m.def("parse_number_table", [](const py::bytes& text, int64_t columns) -> py::object {
        char* data = nullptr;
        Py_ssize_t size = 0;
        if (PyBytes_AsStringAndSize(text.ptr(), &data, &size) != 0) throw py::error_already_set();
        std::vector<double> values;
        int64_t rows;
        {
            py::gil_scoped_release release;  // the bytes are immutable and held by the caller
            rows = cs::parse_number_table(std::string_view(data, size_t(size)), columns, values);
        }
        if (rows < 0) return py::none();
        py::array_t<double> out({py::ssize_t(rows), py::ssize_t(columns)});
        std::copy(values.begin(), values.end(), out.mutable_data());
        return std::move(out);
    }, py::arg("text"), py::arg("columns"),
          "(rows, columns) float64 of text (bytes) holding lines of columns comma-separated "
          "plain decimal numbers, or None for anything else (number_table.hpp).");

    m.def("ritter_sphere", [points](const Doubles& p) {
        const py::ssize_t n = points(p, "points");
        Doubles center(3);
        const double r = cs::ritter_sphere(p.data(), n, center.mutable_data());
        return py::make_tuple(center, r);
    }, py::arg("points"), "(center (3,), radius) of Ritter's bounding sphere of points (n, 3).");

    m.def("build_obb_tree",
          [](const Doubles& tris, int64_t leaf_size, Doubles& center, Doubles& axes,
             Doubles& half, Int64s& left, Int64s& right, Int64s& first, Int64s& count,
             Int64s& order, bool refine) {
              expect_shape("tris", tris, {-1, 3, 3});
              const py::ssize_t m_tris = tris.shape(0);
              if (m_tris < 1) throw std::invalid_argument("tris must hold at least one triangle");
              if (leaf_size < 1)
                  throw std::invalid_argument("leaf_size must be at least 1, got " +
                                              std::to_string(leaf_size));
              expect_shape("center", center, {-1, 3});
              const py::ssize_t cap = center.shape(0);
              if (cap < 2 * m_tris - 1)
                  throw std::invalid_argument("center must hold 2 m - 1 = " +
                                              std::to_string(2 * m_tris - 1) + " nodes, got " +
                                              std::to_string(cap));
              expect_shape("axes", axes, {cap, 3, 3});
              expect_shape("half", half, {cap, 3});
              expect_shape("left", left, {cap});
              expect_shape("right", right, {cap});
              expect_shape("first", first, {cap});
              expect_shape("count", count, {cap});
              expect_shape("order", order, {m_tris});
              const cs::TreeArrays out = {
                  writable("center", center), writable("axes", axes),
                  writable("half", half),     writable("left", left),
                  writable("right", right),   writable("first", first),
                  writable("count", count),   cap,
                  writable("order", order)};
              const double* t = tris.data();
              cs::TreeSize size;
              {
                  py::gil_scoped_release release;
                  size = cs::build_obb_tree(t, m_tris, leaf_size, out, refine);
              }
              return py::make_tuple(size.nodes, size.depth);
          },
          py::arg("tris"), py::arg("leaf_size"), py::arg("center").noconvert(),
          py::arg("axes").noconvert(), py::arg("half").noconvert(), py::arg("left").noconvert(),
          py::arg("right").noconvert(), py::arg("first").noconvert(),
          py::arg("count").noconvert(), py::arg("order").noconvert(),
          py::arg("refine") = false,
          "Build one OBB tree over tris (m, 3, 3) into preallocated node arrays (2 m - 1 rows); "
          "return (nodes, depth). See collision_sensor.engine.obb_tree.build_tree_kernel.");
}

}  // namespace

//: Bumped whenever the binding's functions or the packed layouts change; the Python side
//: refuses an extension built from other sources (collision_sensor/engine/compiled.py).
constexpr int ENGINE_API = 9;

PYBIND11_MODULE(_engine, m) {
    m.doc() = "collision_sensor's compiled engine (C++17); see collision_sensor.engine.compiled";
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
    errors();  // the package's exceptions, imported now rather than at the first error
    py::register_exception_translator([](std::exception_ptr thrown) {
        try {
            if (thrown) std::rethrow_exception(thrown);
        } catch (const cs::LayoutError& error) {
            PyErr_SetString(errors().build.ptr(), error.what());
        } catch (const cs::WorkerError& error) {
            PyErr_SetString(errors().worker.ptr(), error.what());
        } catch (const std::invalid_argument& error) {
            PyErr_SetString(errors().input.ptr(), error.what());
        }
    });
    export_constants(m);
    bind_engine(m);
    bind_query_kernels(m);
    bind_build_kernels(m);
}
