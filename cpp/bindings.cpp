// The module definition of the compiled engine (collision_sensor.engine._engine), the
// helpers every binding file shares (binding.hpp), and the engine's constants.
//
// The engine's constants and the layout of its packed arrays (layout.hpp) are exported here
// under their C++ names: the Python side reads them, and writes none of them again.
#include <cstdint>
#include <string>

#include "binding.hpp"
#include "box_test.hpp"
#include "cloud_queries.hpp"
#include "engine.hpp"
#include "kinematics.hpp"
#include "layout.hpp"
#include "obb_tree.hpp"
#include "tolerances.hpp"
#include "voxel_grid.hpp"
#include "workers.hpp"

namespace collision_sensor {
namespace binding {

namespace cs = collision_sensor;

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

void set_python_error(std::exception_ptr thrown) {
    try {
        std::rethrow_exception(thrown);
    } catch (py::error_already_set& error) {
        error.restore();
    } catch (const cs::LayoutError& error) {
        PyErr_SetString(errors().build.ptr(), error.what());
    } catch (const cs::WorkerError& error) {
        PyErr_SetString(errors().worker.ptr(), error.what());
    } catch (const std::invalid_argument& error) {
        PyErr_SetString(errors().input.ptr(), error.what());
    } catch (const std::bad_alloc&) {
        PyErr_NoMemory();
    } catch (const std::exception& error) {
        PyErr_SetString(PyExc_RuntimeError, error.what());
    } catch (...) {
        PyErr_SetString(PyExc_RuntimeError, "unknown C++ exception");
    }
}

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

const double* exact_doubles(py::handle h, std::initializer_list<py::ssize_t> dims) {
    // On every query: the array's own fields through py::array's accessors. Native float64 is
    // numpy's one dtype object in practice (checked by identity); any other dtype object is
    // compared as numpy compares them (pybind11's array_t check: equivalent types only, so
    // another byte order is not taken).
    static const py::dtype float64 = py::dtype::of<double>();
    if (!py::isinstance<py::array>(h)) return nullptr;
    const auto a = py::reinterpret_borrow<py::array>(h);
    if (a.dtype().ptr() != float64.ptr() && !Array<double>::check_(h)) return nullptr;
    if (!(a.flags() & py::array::c_style) || a.ndim() != py::ssize_t(dims.size()))
        return nullptr;
    py::ssize_t k = 0;
    for (const py::ssize_t d : dims) {
        if (d >= 0 && a.shape(k) != d) return nullptr;
        ++k;
    }
    const auto* data = static_cast<const double*>(a.data());
    if (reinterpret_cast<std::uintptr_t>(data) % alignof(double) != 0) return nullptr;
    return data;
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
    CS_EXPORT(MOTION_LINEAR) CS_EXPORT(MOTION_WRAP) CS_EXPORT(MOTION_QUATERNION)
    CS_EXPORT(MOTION_QUATERNION_REST)
    // motion.hpp
    CS_EXPORT(MOTION_FRONT_MAX)
    m.attr("JOINT_VARIABLES") = py::make_tuple(cs::JOINT_VARIABLES[0], cs::JOINT_VARIABLES[1],
                                               cs::JOINT_VARIABLES[2], cs::JOINT_VARIABLES[3],
                                               cs::JOINT_VARIABLES[4]);
    // tolerances.hpp: every tolerance and limit
    CS_EXPORT(BOX_EPS_REL) CS_EXPORT(BOX_EPS_PARALLEL) CS_EXPORT(TRIANGLE_EPS_REL)
    CS_EXPORT(SPHERE_EPS_REL) CS_EXPORT(HULL_FLAT_REL) CS_EXPORT(BOUND_ROUNDING_REL)
    CS_EXPORT(CLEARANCE_EPS_REL) CS_EXPORT(TRAVEL_GUARD) CS_EXPORT(FRONT_GUARD_REL)
    CS_EXPORT(FRONT_GAP_REL) CS_EXPORT(MOTION_TOUCH_TOLERANCE) CS_EXPORT(MOTION_BOUND_REL)
    CS_EXPORT(SWEEP_EPS) CS_EXPORT(SLERP_HALF_ANGLE_MIN) CS_EXPORT(PRISMATIC_VALUE_MAX)
    CS_EXPORT(QUATERNION_NORM_MIN) CS_EXPORT(MAX_COORDINATE) CS_EXPORT(ROTATION_TOLERANCE)
    CS_EXPORT(MAX_CLOUD_CLEARANCE) CS_EXPORT(MAX_THREADS)
    // voxel_grid.hpp: point clouds
    CS_EXPORT(VOXEL_COORD_BITS) CS_EXPORT(VOXEL_COORD_LIMIT) CS_EXPORT(VOXEL_LEAF_SIZE)
#undef CS_EXPORT
}

}  // namespace binding
}  // namespace collision_sensor

namespace cs = collision_sensor;
using namespace collision_sensor::binding;

//: Bumped whenever the binding's functions or the packed layouts change; the Python side
//: refuses an extension built from other sources (collision_sensor/engine/compiled.py).
constexpr int ENGINE_API = 10;

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
        } catch (const cs::LayoutError&) {
            set_python_error(std::current_exception());
        } catch (const cs::WorkerError&) {
            set_python_error(std::current_exception());
        } catch (const std::invalid_argument&) {
            set_python_error(std::current_exception());
        }
    });
    // Each concern's bindings (binding.hpp), one function each.
    export_constants(m);
    bind_engine(m);
    bind_clouds(m);
    bind_sensor(m);
    bind_kinematics(m);
    bind_query_kernels(m);
    bind_build_kernels(m);
}
