// Bindings of the query engine (engine.hpp: Engine, its result structs) and of the point
// clouds it shows (voxel_cloud.hpp: VoxelCloud).
//
// The calls a stream of joint states makes at every message, query, update_motion and motion,
// are methods of Engine in CPython's fast calling convention (METH_FASTCALL, added with
// PyDescr_NewMethod): each reads its arguments itself, without pybind11's general dispatch
// (type casters over an argument tuple), which would cost as much as a still robot's whole
// incremental query. Every answer is a result struct read by field name: QueryResult and
// MotionStep as Python struct sequences, a motion's as the checker's own type (name_pairs). A
// value the engine refuses raises JointStateError with its row and variable.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "binding.hpp"
#include "cloud_filter.hpp"
#include "engine.hpp"
#include "kinematics.hpp"
#include "ray_cast.hpp"
#include "tolerances.hpp"
#include "voxel_cloud.hpp"
#include "workers.hpp"

namespace collision_sensor {
namespace binding {

namespace cs = collision_sensor;

namespace {

// A new reference as a py::object; a null one (a failed CPython call) throws its error.
py::object owned(PyObject* object) {
    if (!object) throw py::error_already_set();
    return py::reinterpret_steal<py::object>(object);
}

// The result structs' Python types (struct sequences: fields by name, and tuples).
PyStructSequence_Field query_fields[] = {
    {"rechecked", "pairs re-checked"},
    {"changed", "True iff some pair's status changed"},
    {"status_version", "Engine.status_version after the query: an answer built from the "
                       "statuses at one version holds while it is the same"},
    {nullptr, nullptr}};
PyStructSequence_Desc query_desc = {
    "collision_sensor.engine._engine.QueryResult",
    "What Engine.query did (cpp/engine.hpp: QueryResult).", query_fields, 3};

PyStructSequence_Field step_fields[] = {
    {"motion", "the motion's answer (name_pairs: the free answer, or result_type(True, t, "
               "the names of the pairs met))"},
    {"rechecked", "the query's: pairs re-checked"},
    {"changed", "the query's: True iff some pair's status changed"},
    {"status_version", "the query's: Engine.status_version after it"},
    {nullptr, nullptr}};
PyStructSequence_Desc step_desc = {
    "collision_sensor.engine._engine.MotionStep",
    "What Engine.update_motion found and did (cpp/engine.hpp: StepResult).", step_fields, 4};

PyStructSequence_Field path_fields[] = {
    {"segment", "the first segment not free (-1: none)"},
    {"motion", "its motion's answer, as Engine.motion's"},
    {nullptr, nullptr}};
PyStructSequence_Desc path_desc = {
    "collision_sensor.engine._engine.PathAnswer",
    "What Engine.path or Engine.spline found (cpp/engine.hpp: MotionResult).", path_fields, 2};

struct ResultTypes {
    PyTypeObject *query, *step, *path;
};

const ResultTypes& result_types() {
    static const ResultTypes types = [] {
        ResultTypes t;
        t.query = PyStructSequence_NewType(&query_desc);
        t.step = PyStructSequence_NewType(&step_desc);
        t.path = PyStructSequence_NewType(&path_desc);
        if (!t.query || !t.step || !t.path) throw py::error_already_set();
        return t;
    }();
    return types;
}

// Fill field k of a new struct sequence (a new reference, or its error).
void set_field(PyObject* answer, Py_ssize_t k, PyObject* value) {
    if (!value) throw py::error_already_set();
    PyStructSequence_SetItem(answer, k, value);
}

py::object query_answer(const cs::QueryResult& r) {
    py::object answer = owned(PyStructSequence_New(result_types().query));
    set_field(answer.ptr(), 0, PyLong_FromLongLong(r.rechecked));
    set_field(answer.ptr(), 1, PyBool_FromLong(r.changed));
    set_field(answer.ptr(), 2, PyLong_FromUnsignedLongLong(r.status_version));
    return answer;
}

// An answer object kept for reuse: a query whose answer has the same fields as the last one
// gets the last one's object again (answers are immutable), so the commonest answer, nothing
// changed, is no new object, and a caller that kept the object it settled tells it apart by
// identity.
struct KeptAnswer {
    int64_t rechecked = -1;
    bool changed = false;
    uint64_t status_version = 0;
    PyObject* motion = nullptr;  // MotionStep's motion answer (borrowed: held by object)
    py::object object;

    bool same(const cs::QueryResult& r, PyObject* motion_answer = nullptr) const {
        return object && r.rechecked == rechecked && r.changed == changed &&
               r.status_version == status_version && motion_answer == motion;
    }
    void keep(const cs::QueryResult& r, py::object answer, PyObject* motion_answer = nullptr) {
        rechecked = r.rechecked;
        changed = r.changed;
        status_version = r.status_version;
        motion = motion_answer;
        object = std::move(answer);
    }
};

// Raise JointStateError for a value the engine refused.
[[noreturn]] void raise_refused(const cs::BadValue& bad) {
    raise_joint_state("row " + std::to_string(bad.row) + ", variable " +
                          std::to_string(bad.variable) + ": not usable",
                      bad.row, bad.variable);
}

// The checker's engine: the C++ Engine over the two packed buffers, which it keeps alive.
struct PyEngine {
    Array<double> F;
    Array<int64_t> I;
    std::unique_ptr<cs::Engine> engine;
    // name_pairs: the pairs' names (one tuple each) and the motion answers' type and free one.
    py::tuple pair_names;
    py::object result_type, free_result;
    KeptAnswer kept_query, kept_step;  // query's and update_motion's last answers
    KeptArea<cs::MotionResult> motion_area;
    KeptArea<cs::StepResult> step_area;

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

    int64_t n_joints() const { return engine->model().n_joints; }

    void name_pairs(const py::tuple& names, py::object type, py::object free) {
        if (!PyType_Check(type.ptr()) ||
            !PyType_IsSubtype(reinterpret_cast<PyTypeObject*>(type.ptr()), &PyTuple_Type))
            throw std::invalid_argument("result_type: a subclass of tuple");
        std::vector<cs::PairName> cpp_names;
        cpp_names.reserve(names.size());
        for (const py::handle pair : names) {
            const auto two = pair.cast<std::pair<std::string, std::string>>();
            cpp_names.push_back({two.first, two.second});
        }
        {
            std::lock_guard<std::mutex> hold(engine->lock());
            engine->name_pairs(std::move(cpp_names));
        }
        pair_names = names;
        result_type = std::move(type);
        free_result = std::move(free);
    }

    // A motion's answer: free_result, or result_type(True, t, the names of the pairs met, in
    // the pairs' order).
    py::object motion_answer(const cs::MotionResult& r) const {
        if (!result_type) throw std::logic_error("name the pairs first (name_pairs)");
        if (!r.contact) return free_result;
        py::ssize_t count = 0;
        for (const uint8_t hit : r.pairs) count += hit != 0;
        py::tuple names(count);
        py::ssize_t k = 0;
        for (size_t p = 0; p < r.pairs.size(); ++p)
            if (r.pairs[p]) names[k++] = pair_names[p];
        // What tuple.__new__(result_type, fields) makes, without a NamedTuple's own __new__.
        auto* type = reinterpret_cast<PyTypeObject*>(result_type.ptr());
        py::object made = owned(type->tp_alloc(type, 3));
        PyTuple_SET_ITEM(made.ptr(), 0, py::bool_(true).release().ptr());
        PyTuple_SET_ITEM(made.ptr(), 1, owned(PyFloat_FromDouble(r.t)).release().ptr());
        PyTuple_SET_ITEM(made.ptr(), 2, names.release().ptr());
        return made;
    }

    py::object path_answer(const cs::MotionResult& r) const {
        py::object answer = owned(PyStructSequence_New(result_types().path));
        set_field(answer.ptr(), 0, PyLong_FromLongLong(r.segment));
        set_field(answer.ptr(), 1, motion_answer(r).release().ptr());
        return answer;
    }
};

// The fast methods (METH_FASTCALL): query(q, full), update_motion(q), motion(q0, q1). A
// configuration is read in place only when it is an array the engine takes as it is
// (exact_doubles); anything else answers None, and the checker converts it first.

py::object engine_query(PyEngine& self, PyObject* const* args) {
    const double* q = exact_doubles(args[0], {self.n_joints()});
    if (!q) return py::none();
    const int full = PyObject_IsTrue(args[1]);
    if (full < 0) throw py::error_already_set();
    cs::QueryResult r;
    {
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(self.engine->lock());
        r = self.engine->query(q, full != 0);
    }
    if (r.refused()) raise_refused({0, r.bad_variable});
    if (!self.kept_query.same(r)) self.kept_query.keep(r, query_answer(r));
    return self.kept_query.object;
}

py::object engine_update_motion(PyEngine& self, PyObject* const* args) {
    const double* q = exact_doubles(args[0], {self.n_joints()});
    if (!q) return py::none();
    AreaLoan<cs::StepResult> area(self.step_area);
    cs::StepResult& r = *area;
    {
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(self.engine->lock());
        self.engine->update_motion(q, r);
    }
    if (r.query.refused()) raise_refused(r.motion.bad);
    py::object motion = self.motion_answer(r.motion);
    if (self.kept_step.same(r.query, motion.ptr())) return self.kept_step.object;
    py::object answer = owned(PyStructSequence_New(result_types().step));
    PyObject* motion_ptr = motion.ptr();
    set_field(answer.ptr(), 0, motion.release().ptr());
    set_field(answer.ptr(), 1, PyLong_FromLongLong(r.query.rechecked));
    set_field(answer.ptr(), 2, PyBool_FromLong(r.query.changed));
    set_field(answer.ptr(), 3, PyLong_FromUnsignedLongLong(r.query.status_version));
    self.kept_step.keep(r.query, answer, motion_ptr);
    return answer;
}

py::object engine_motion(PyEngine& self, PyObject* const* args) {
    const int64_t J = self.n_joints();
    const double* from = exact_doubles(args[0], {J});
    const double* to = from ? exact_doubles(args[1], {J}) : nullptr;
    if (!to) return py::none();
    AreaLoan<cs::MotionResult> area(self.motion_area);
    cs::MotionResult& r = *area;
    {
        py::gil_scoped_release release;
        std::lock_guard<std::mutex> hold(self.engine->lock());
        self.engine->motion(from, to, r);
    }
    if (r.refused()) raise_refused(r.bad);
    return self.motion_answer(r);
}

// Method(self, args) as a METH_FASTCALL function of N arguments.
template <Py_ssize_t N, py::object (*Method)(PyEngine&, PyObject* const*)>
PyObject* fast_method(PyObject* self, PyObject* const* args, Py_ssize_t nargs) {
    if (nargs != N) {
        PyErr_Format(PyExc_TypeError, "takes %zd positional arguments, got %zd", N, nargs);
        return nullptr;
    }
    try {
        return Method(py::handle(self).cast<PyEngine&>(), args).release().ptr();
    } catch (...) {
        set_python_error(std::current_exception());
        return nullptr;
    }
}

template <Py_ssize_t N, py::object (*Method)(PyEngine&, PyObject* const*)>
PyMethodDef fast_def(const char* name, const char* doc) {
    PyCFunction f = reinterpret_cast<PyCFunction>(
        reinterpret_cast<void (*)(void)>(&fast_method<N, Method>));
    return {name, f, METH_FASTCALL, doc};
}

// Add the METH_FASTCALL method def to class cls (a method descriptor, as a built-in type's).
void add_fast_method(py::handle cls, PyMethodDef* def) {
    py::object method =
        owned(PyDescr_NewMethod(reinterpret_cast<PyTypeObject*>(cls.ptr()), def));
    if (PyObject_SetAttrString(cls.ptr(), def->ml_name, method.ptr()) != 0)
        throw py::error_already_set();
}

// CollisionChecker.check_motion (collision_sensor/engine/checker.py) as a method of the
// checker's class in the fast calling convention: the checker's engine answers motion(q_from,
// q_to) when it reads both as they are; anything else (other forms of positions, keywords, a
// value the engine refuses) goes to the checker's own _check_motion, which merges the
// positions and names the joint at fault. A stream's check of each step is then one compiled
// call, without a Python frame.
PyObject* checker_check_motion(PyObject* checker, PyObject* const* args, Py_ssize_t nargs,
                               PyObject* kwnames) {
    static PyObject* const engine_name = PyUnicode_InternFromString("_engine");
    static PyObject* const fallback_name = PyUnicode_InternFromString("_check_motion");
    if (nargs == 2 && !kwnames) {
        try {
            const py::object engine = owned(PyObject_GetAttr(checker, engine_name));
            py::object answer = engine_motion(engine.cast<PyEngine&>(), args);
            if (!answer.is_none()) return answer.release().ptr();
        } catch (py::error_already_set& error) {
            if (!error.matches(errors().joint_state)) {
                error.restore();
                return nullptr;
            }
        } catch (...) {
            set_python_error(std::current_exception());
            return nullptr;
        }
    }
    PyObject* fallback = PyObject_GetAttr(checker, fallback_name);
    if (!fallback) return nullptr;
    PyObject* answer = PyObject_Vectorcall(fallback, args, size_t(nargs), kwnames);
    Py_DECREF(fallback);
    return answer;
}
}  // namespace

cs::Engine& engine_of(py::handle engine) { return *engine.cast<PyEngine&>().engine; }

void bind_engine(py::module_& m) {
    const ResultTypes& types = result_types();
    m.attr("QueryResult") = py::handle(reinterpret_cast<PyObject*>(types.query));
    m.attr("MotionStep") = py::handle(reinterpret_cast<PyObject*>(types.step));
    m.attr("PathAnswer") = py::handle(reinterpret_cast<PyObject*>(types.path));

    py::class_<PyEngine> engine(m, "Engine",
                                "The query engine over a checker's packed buffers F (float64) "
                                "and I (int64) and their layout rows (cpp/layout.hpp); see "
                                "cpp/engine.hpp. Not for use outside CollisionChecker.");
    engine
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
        .def_property_readonly(
            "status_version",
            [](PyEngine& e) {
                std::lock_guard<std::mutex> hold(e.engine->lock());
                return e.engine->status_version();
            },
            "How many times a query changed a status since the engine was made.")
        .def("name_pairs", &PyEngine::name_pairs, py::arg("names"), py::arg("result_type"),
             py::arg("free"),
             "Give the checked pairs' names (a tuple of (a, b), one per pair, in the pairs' "
             "order), and the motion answers' type (a tuple subclass of in_collision, "
             "first_contact, colliding_pairs) and free answer.")
        .def(
            "batch",
            [](PyEngine& self, const Array<double>& Q, bool full, Array<uint8_t> statuses,
               Array<int64_t> rechecked, Array<uint8_t> changed) {
                expect_shape("Q", Q, {-1, self.n_joints()});
                const py::ssize_t n = Q.shape(0);
                expect_shape("statuses", statuses, {n, self.engine->model().n_pairs});
                expect_shape("rechecked", rechecked, {n});
                expect_shape("changed", changed, {n});
                const cs::BatchRows rows = {writable("statuses", statuses),
                                            writable("rechecked", rechecked),
                                            writable("changed", changed)};
                cs::BatchResult r;
                {
                    py::gil_scoped_release release;
                    std::lock_guard<std::mutex> hold(self.engine->lock());
                    r = self.engine->batch(Q.data(), n, full, rows);
                }
                if (r.refused()) raise_refused(r.bad);
                return r.rows;
            },
            py::arg("Q"), py::arg("full"), py::arg("statuses").noconvert(),
            py::arg("rechecked").noconvert(), py::arg("changed").noconvert(),
            "query() on each row of Q (n, J); statuses (n, P) uint8, rechecked (n,) int64 and "
            "changed (n,) uint8 written; return n. JointStateError (row, variable) for a value "
            "that is not usable: nothing ran then.")
        .def(
            "proximity",
            [](PyEngine& self, const Array<double>& q, double max_distance,
               Array<double> distance, Array<double> points) {
                const cs::Model& model = self.engine->model();
                expect_shape("q", q, {model.n_joints});
                expect_shape("distance", distance, {model.n_pairs});
                expect_shape("points", points, {model.n_pairs, 6});
                const cs::ProximityRequest request = {max_distance};
                const cs::ProximityResult result = {writable("distance", distance),
                                                    writable("points", points)};
                cs::QueryResult r;
                {
                    py::gil_scoped_release release;
                    std::lock_guard<std::mutex> hold(self.engine->lock());
                    r = self.engine->proximity(q.data(), request, result);
                }
                if (r.refused()) raise_refused({0, r.bad_variable});
                return query_answer(r);
            },
            py::arg("q"), py::arg("max_distance"), py::arg("distance").noconvert(),
            py::arg("points").noconvert(),
            "query(q, False), then each pair's distance (P,) (inf when not below "
            "max_distance, <= 0 when in contact) and nearest points (P, 6), world frame, "
            "written in place; return the query's QueryResult.")
        .def(
            "poses",
            [](PyEngine& self) {
                std::lock_guard<std::mutex> hold(self.engine->lock());
                self.engine->refresh_all_poses();
            },
            "Bring every link pose up to date.")
        .def(
            "move_world_body",
            [](PyEngine& self, int64_t b, py::handle T) {
                const double* data = exact_doubles(T, {4, 4});
                if (!data) return false;
                std::lock_guard<std::mutex> hold(self.engine->lock());
                return self.engine->move_world_body(b, data);
            },
            py::arg("b"), py::arg("T"),
            "Give world object b the pose T ((4, 4) C-contiguous float64) and force its "
            "pairs, if T is a rigid transform within MAX_COORDINATE; return whether it did "
            "(False: nothing changed, also for anything but such an array).")
        .def(
            "place_attached_body",
            [](PyEngine& self, int64_t b, const Array<double>& T, const Array<int64_t>& pairs,
               const Array<double>& reach, const Array<double>& reach_ext) {
                const py::ssize_t n = pairs.size(), J = self.n_joints();
                expect_shape("T", T, {4, 4});
                expect_shape("pairs", pairs, {n});
                expect_shape("reach", reach, {n, J});
                expect_shape("reach_ext", reach_ext, {n, J});
                std::lock_guard<std::mutex> hold(self.engine->lock());
                return self.engine->place_attached_body(b, T.data(), pairs.data(), n,
                                                        reach.data(), reach_ext.data());
            },
            py::arg("b"), py::arg("T"), py::arg("pairs"), py::arg("reach"),
            py::arg("reach_ext"),
            "Give attached object b (a link on a fixed joint) the pose T (4, 4) in its link's "
            "frame, its pairs (n,) the reach rows reach, reach_ext (n, J), and force them; "
            "return whether it did (False: nothing changed).")
        .def(
            "path",
            [](PyEngine& self, const Array<double>& Q) {
                expect_shape("Q", Q, {-1, self.n_joints()});
                if (Q.shape(0) < 1) throw std::invalid_argument("Q: no waypoint");
                AreaLoan<cs::MotionResult> area(self.motion_area);
                cs::MotionResult& r = *area;
                {
                    py::gil_scoped_release release;
                    std::lock_guard<std::mutex> hold(self.engine->lock());
                    self.engine->path(Q.data(), Q.shape(0), r);
                }
                if (r.refused()) raise_refused(r.bad);
                return self.path_answer(r);
            },
            py::arg("Q"),
            "The straight motions between consecutive rows of Q (n >= 1, J) until one is not "
            "free: a PathAnswer; JointStateError (row, variable) for an unusable value.")
        .def(
            "spline",
            [](PyEngine& self, const Array<double>& coef) {
                expect_shape("coef", coef, {-1, self.n_joints(), 6});
                AreaLoan<cs::MotionResult> area(self.motion_area);
                cs::MotionResult& r = *area;
                {
                    py::gil_scoped_release release;
                    std::lock_guard<std::mutex> hold(self.engine->lock());
                    self.engine->spline(coef.data(), coef.shape(0), r);
                }
                if (r.refused()) raise_refused(r.bad);
                return self.path_answer(r);
            },
            py::arg("coef"),
            "The polynomial segments coef (n, J, 6) (q_j(t) = sum_k coef[i, j, k] t^k, t in "
            "[0, 1]) until one is not free: a PathAnswer; JointStateError (row: the segment, "
            "variable -1) for a segment the engine refuses.")
        .def(
            "attach_cloud",
            [](PyEngine& self, int64_t b, py::handle cloud) {
                std::shared_ptr<cs::VoxelCloud> shown = cloud_of(cloud);
                std::lock_guard<std::mutex> hold(self.engine->lock());
                return self.engine->attach_cloud(b, std::move(shown));
            },
            py::arg("b"), py::arg("cloud"),
            "Make world object b (a body without trees, at the identity) show cloud's current "
            "grid and force its pairs; return whether it did (False: nothing changed).")
        .def(
            "commit_cloud",
            [](PyEngine& self, int64_t b, int64_t ticket) {
                std::lock_guard<std::mutex> hold(self.engine->lock());
                return self.engine->commit_cloud(b, ticket);
            },
            py::arg("b"), py::arg("ticket"),
            "Make build `ticket` of body b's cloud current and force its pairs; return whether "
            "it did (False: not its last build to commit, nothing changed).")
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

    // The calls of every joint state, without pybind11's dispatch (fast_method).
    static PyMethodDef fast[] = {
        fast_def<2, engine_query>(
            "query",
            "query(q, full) -> QueryResult: bring the statuses up to date with q (a "
            "C-contiguous float64 array of J values; anything else answers None and changes "
            "nothing). JointStateError (variable) for a value that is not usable: not finite, "
            "or beyond the engine's range (nothing changed then)."),
        fast_def<1, engine_update_motion>(
            "update_motion",
            "update_motion(q) -> MotionStep: the motion from the carried state to q (as query "
            "takes it: None else), then query(q, False). JointStateError as query's."),
        fast_def<2, engine_motion>(
            "motion",
            "motion(q0, q1) -> the motion's answer (name_pairs): the straight motion q0 -> q1 "
            "(J,), carried state untouched; None unless both are arrays as query takes them. "
            "JointStateError (row 0: q0, 1: q1; variable) for an unusable value."),
    };
    for (PyMethodDef& def : fast) add_fast_method(engine, &def);

    m.def(
        "checker_motion_method",
        [](py::handle cls, const std::string& doc) {
            static std::string kept_doc;
            kept_doc = doc;
            static PyMethodDef def = {
                "check_motion",
                reinterpret_cast<PyCFunction>(
                    reinterpret_cast<void (*)(void)>(&checker_check_motion)),
                METH_FASTCALL | METH_KEYWORDS, nullptr};
            def.ml_doc = kept_doc.c_str();
            if (!PyType_Check(cls.ptr())) throw std::invalid_argument("cls: a class");
            return owned(PyDescr_NewMethod(reinterpret_cast<PyTypeObject*>(cls.ptr()), &def));
        },
        py::arg("cls"), py::arg("doc"),
        "check_motion(q_from, q_to) as a method of class cls (CollisionChecker), with "
        "docstring doc: its _engine's motion when it answers, else its _check_motion.");
}

}  // namespace binding
}  // namespace collision_sensor
