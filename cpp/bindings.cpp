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
