// Bindings of the engine's kernels, for Python callers outside a query: forward kinematics
// (Kinematics), the box, triangle and tree tests (the test oracles and the benchmarks run them
// alone), and the build-time kernels (bounding volumes, OBB trees, number tables).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "binding.hpp"
#include "bounding_volumes.hpp"
#include "box_test.hpp"
#include "kinematics.hpp"
#include "motion.hpp"
#include "number_table.hpp"
#include "obb_tree.hpp"
#include "traversal.hpp"
#include "triangle_box.hpp"
#include "triangle_distance.hpp"
#include "triangle_test.hpp"

namespace collision_sensor {
namespace binding {

namespace cs = collision_sensor;

namespace {

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

}  // namespace

void bind_kinematics(py::module_& m) {
    m.def(
        "interpolate",
        [](const Array<int64_t>& kinds, const Array<double>& q0, const Array<double>& q1,
           const Array<double>& t) {
            const py::ssize_t J = kinds.size();
            expect_shape("kinds", kinds, {J});
            expect_shape("q_from", q0, {J});
            expect_shape("q_to", q1, {J});
            expect_shape("t", t, {-1});
            const int64_t* kind = kinds.data();
            for (py::ssize_t j = 0; j < J; ++j) {
                const bool rest = kind[j] == cs::MOTION_QUATERNION_REST;
                const bool opens = kind[j] == cs::MOTION_QUATERNION;
                bool fits = kind[j] == cs::MOTION_LINEAR || kind[j] == cs::MOTION_WRAP;
                if (opens) {
                    fits = j + 3 < J;
                    for (py::ssize_t i = 1; i < 4 && fits; ++i)
                        fits = kind[j + i] == cs::MOTION_QUATERNION_REST;
                }
                if (!fits && !rest)
                    throw std::invalid_argument("kinds: variable " + std::to_string(j) +
                                                " is no MOTION_* kind, or a quaternion's "
                                                "rot_x without its three rest");
                if (!opens) continue;
                for (const auto* q : {q0.data(), q1.data()}) {
                    double x, y, z, w, n2;
                    if (!std::isfinite(q[j]) || !std::isfinite(q[j + 1]) ||
                        !std::isfinite(q[j + 2]) || !std::isfinite(q[j + 3]) ||
                        !cs::scaled_quaternion(q + j, &x, &y, &z, &w, &n2))
                        raise_joint_state("quaternion at variable " + std::to_string(j) +
                                              " is zero or not finite",
                                          q == q0.data() ? 0 : 1, j);
                }
                j += 3;
            }
            const py::ssize_t n = t.shape(0);
            Array<double> out({n, J});
            std::vector<double> delta(J), var(J), quat0(J);
            cs::StraightPath path{q0.data(), kind, int64_t(J), delta.data(), var.data(),
                                  quat0.data()};
            path.prepare(q1.data());
            for (py::ssize_t i = 0; i < n; ++i) path.at(t.data()[i], out.mutable_data() + J * i);
            return out;
        },
        py::arg("kinds"), py::arg("q_from"), py::arg("q_to"), py::arg("t"),
        "The states (n, J) of the straight motion q_from -> q_to (J,) at fractions t (n,), each "
        "variable as kinds (J,) MOTION_* says (cpp/motion.hpp: StraightPath, the motion "
        "checks' own); JointStateError (row 0: q_from, 1: q_to; variable) for a quaternion "
        "that is zero or not finite.");

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
              std::vector<int64_t> stack(cs::PAIR_ROW * (n + 8)), counters(cs::N_COUNTERS);
              cs::seed_pair(stack.data(), 0, root_a, root_b);
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

}  // namespace binding
}  // namespace collision_sensor
