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

namespace py = pybind11;

//: Bumped whenever the binding's functions or the packed layouts change; the Python side
//: refuses an extension built from other sources (collision_sensor/compiled.py).
constexpr int ENGINE_API = 1;

PYBIND11_MODULE(_engine, m) {
    m.doc() = "collision_sensor's compiled engine (C++17); see collision_sensor.compiled";
    m.attr("ENGINE_API") = ENGINE_API;
#ifdef COLLISION_SENSOR_SOURCE_DIGEST
    m.attr("SOURCE_DIGEST") = COLLISION_SENSOR_SOURCE_DIGEST;
#else
    m.attr("SOURCE_DIGEST") = "";
#endif

    // ---- query engine (query.hpp, box_test.hpp, triangle_test.hpp, kinematics.hpp)

    // ---- end of query engine


    // ---- build-time kernels (bounding_volumes.hpp, obb_tree.hpp)

    // ---- end of build-time kernels
}
