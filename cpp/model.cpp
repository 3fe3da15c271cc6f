// The model cut from the packed buffers and checked (model.hpp).
#include "model.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "convex_sweep.hpp"
#include "tolerances.hpp"

namespace collision_sensor {

namespace {

void require(bool ok, const char* array, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("packed array '") + array + "': " + what);
}

// Check every index of the model that a query follows unchecked.
void check_indices(const Model& m, int64_t n_joint_pairs, int64_t n_joint_links) {
    for (int64_t b = 0; b < m.n_bodies; ++b)
        require(m.padding[b] >= 0.0 && std::isfinite(m.padding[b]), "padding",
                "not a finite value >= 0");
    const KinematicTree& kin = m.kin;
    for (int64_t i = 0; i < m.n_links; ++i) {
        const int64_t parent = kin.parent[i];
        require(!(parent >= i || (i > 0 && parent < 0) || (i == 0 && parent >= 0)), "parent",
                "links are not parents first");
        require(kin.joint_type[i] >= JOINT_FIXED && kin.joint_type[i] <= JOINT_FLOATING,
                "joint_type", "unknown joint type");
        require(kin.joint_type[i] == JOINT_FIXED ||   // a multi-DOF joint's variables all in q
                    (kin.q_index[i] >= 0 && kin.q_index[i] +
                     joint_variable_count(kin.joint_type[i]) <= m.n_joints),
                "q_index", "index out of range");
    }
    for (int64_t b = 0; b < m.n_bodies; ++b)
        require(m.elem_start[b] >= 0 && m.elem_end[b] >= m.elem_start[b] &&
                    m.elem_end[b] <= m.n_elements,
                "body_elem_*", "out of range");
    for (int64_t p = 0; p < m.n_pairs; ++p)
        require(m.pair_a[p] >= 0 && m.pair_a[p] < m.n_links && m.pair_b[p] >= 0 &&
                    m.pair_b[p] < m.n_bodies,
                "pair_*", "body out of range");
    for (int64_t e = 0; e < m.n_elements; ++e)
        require(m.roots[e] >= 0 && m.roots[e] < m.n_nodes, "roots", "node out of range");
    for (int64_t n = 0; n < m.n_nodes; ++n) {
        const int64_t* node = m.forest.node(n);
        require(!(node[NODE_LEFT] >= m.n_nodes || node[NODE_RIGHT] >= m.n_nodes ||
                  (node[NODE_LEFT] >= 0 && node[NODE_RIGHT] < 0) || node[NODE_FIRST] < 0 ||
                  node[NODE_COUNT] < 0 || node[NODE_FIRST] + node[NODE_COUNT] > m.n_triangles),
                "nodes", "index out of range");
    }
    // The variables' lists: cut in order, each entry a pair or a link.
    const std::pair<const int64_t*, const int64_t*> lists[2] = {
        {m.joint_pairs_start, m.joint_pairs}, {m.joint_links_start, m.joint_links}};
    const int64_t bounds[2] = {m.n_pairs, m.n_links};
    const int64_t lengths[2] = {n_joint_pairs, n_joint_links};
    for (int k = 0; k < 2; ++k) {
        const int64_t* start = lists[k].first;
        require(start[0] == 0 && start[m.n_joints] == lengths[k], "joint_*_start",
                "does not cut its list from start to end");
        for (int64_t j = 0; j < m.n_joints; ++j)
            require(start[j + 1] >= start[j], "joint_*_start", "not increasing");
        for (int64_t t = 0; t < start[m.n_joints]; ++t)
            require(lists[k].second[t] >= 0 && lists[k].second[t] < bounds[k], "joint_*",
                    "entry out of range");
    }
}

// Each tree's triangle range and depth, walking it from its root (a node reached twice is
// a cycle, not a tree, or a node of two trees: each tree's nodes are its own, which the
// caches keyed by node rely on, e.g. cloud_filter.cpp's world boxes at one body's pose).
void derive_trees(Model& m) {
    m.elem_tris.assign(2 * m.n_elements, 0);
    m.depth = 1;
    std::vector<std::pair<int64_t, int64_t>> pending;  // (node, its depth)
    std::vector<uint8_t> reached(m.n_nodes, 0);
    for (int64_t e = 0; e < m.n_elements; ++e) {
        int64_t lo = m.n_triangles, hi = 0;
        pending.assign(1, {m.roots[e], 1});
        for (int64_t visits = 0; !pending.empty(); ++visits) {
            require(visits <= m.n_nodes, "nodes", "not a tree");
            const auto [n, level] = pending.back();
            pending.pop_back();
            require(!reached[n], "nodes", "a node reached twice (a cycle, or two trees share it)");
            reached[n] = 1;
            m.depth = std::max(m.depth, level);
            const int64_t* node = m.forest.node(n);
            if (node[NODE_LEFT] >= 0) {
                pending.push_back({node[NODE_LEFT], level + 1});
                pending.push_back({node[NODE_RIGHT], level + 1});
            } else if (node[NODE_COUNT] > 0) {
                lo = std::min(lo, node[NODE_FIRST]);
                hi = std::max(hi, node[NODE_FIRST] + node[NODE_COUNT]);
            }
        }
        m.elem_tris[2 * e] = lo < hi ? lo : 0;
        m.elem_tris[2 * e + 1] = lo < hi ? hi : 0;
    }
}

void derive_bodies(Model& m) {
    m.body_solid.assign(m.n_bodies, 0);
    m.body_reach.assign(m.n_bodies, 0.0);
    for (int64_t b = 0; b < m.n_bodies; ++b) {
        for (int64_t e = m.elem_start[b]; e < m.elem_end[b]; ++e)
            if (m.elem_solid[SOLID_WIDTH * e] != SOLID_NONE) m.body_solid[b] = 1;
        const double* B = m.body_box(b);
        const double* c = B + BOX_CENTER;
        m.body_reach[b] = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) + B[BOX_RADIUS];
    }
    m.body_pairs_start.assign(m.n_bodies + 1, 0);
    for (int64_t p = 0; p < m.n_pairs; ++p) ++m.body_pairs_start[m.pair_b[p] + 1];
    for (int64_t b = 0; b < m.n_bodies; ++b) m.body_pairs_start[b + 1] += m.body_pairs_start[b];
    m.body_pairs.assign(m.n_pairs, 0);
    std::vector<int64_t> next(m.body_pairs_start.begin(), m.body_pairs_start.end() - 1);
    for (int64_t p = 0; p < m.n_pairs; ++p) m.body_pairs[next[m.pair_b[p]]++] = p;
    std::vector<uint8_t> moving(m.n_pairs, 0);
    for (int64_t t = 0; t < m.joint_pairs_start[m.n_joints]; ++t) moving[m.joint_pairs[t]] = 1;
    m.moving_pairs.clear();
    m.static_pairs.clear();
    for (int64_t p = 0; p < m.n_pairs; ++p)
        (moving[p] ? m.moving_pairs : m.static_pairs).push_back(p);
    m.clouds.assign(m.n_bodies, nullptr);
    m.most_seeds = 1;
    for (int64_t p = 0; p < m.n_pairs; ++p)
        m.most_seeds = std::max(m.most_seeds, m.elements(m.pair_a[p]) * m.elements(m.pair_b[p]));
}

}  // namespace

Model make_model(const ResolvedLayout& r) {
    Model m;
    m.n_links = r.dims[DIM_LINKS];
    m.n_bodies = r.dims[DIM_BODIES];
    m.n_joints = r.dims[DIM_JOINTS];
    m.n_pairs = r.dims[DIM_PAIRS];
    m.n_elements = r.dims[DIM_ELEMENTS];
    m.n_nodes = r.dims[DIM_NODES];
    m.n_triangles = r.dims[DIM_TRIANGLES];
    m.kin = {m.n_links,         r.i[slot::parent],     r.i[slot::joint_type],
             r.f[slot::T_parent_joint], r.f[slot::axis], r.i[slot::q_index],
             r.f[slot::multiplier],     r.f[slot::offset]};
    m.forest = {r.f[slot::boxes], r.i[slot::nodes], r.f[slot::volume], r.f[slot::gain],
                r.f[slot::tris]};
    m.body_boxes = r.f[slot::body_boxes];
    m.padding = r.f[slot::padding];
    m.elem_start = r.i[slot::body_elem_start];
    m.elem_end = r.i[slot::body_elem_end];
    m.roots = r.i[slot::roots];
    m.elem_solid = r.f[slot::elem_solid];
    m.pair_a = r.i[slot::pair_a];
    m.pair_b = r.i[slot::pair_b];
    m.reach = r.f[slot::reach];
    m.reach_ext = r.f[slot::reach_ext];
    m.joint_pairs_start = r.i[slot::joint_pairs_start];
    m.joint_pairs = r.i[slot::joint_pairs];
    m.joint_links_start = r.i[slot::joint_links_start];
    m.joint_links = r.i[slot::joint_links];
    m.joint_prismatic = r.i[slot::joint_prismatic];
    m.motion_kind = r.i[slot::motion_kind];
    require(m.n_links >= 1, "parent", "the robot has no links");
    for (int64_t j = 0; j < m.n_joints; ++j)
        require(m.motion_kind[j] >= MOTION_LINEAR && m.motion_kind[j] <= MOTION_QUATERNION_REST,
                "motion_kind", "not one of MOTION_*");
    check_indices(m, r.dims[DIM_JOINT_PAIRS], r.dims[DIM_JOINT_LINKS]);
    derive_trees(m);
    derive_bodies(m);
    return m;
}


namespace {

// A closed mesh is taken for a hull after a test of every face plane against every vertex:
// up to this many triangles (primitives are convex by construction and not tested).
constexpr int64_t HULL_TEST_MAX_TRIANGLES = 2048;

// Is every vertex of the closed mesh on one side of each of its triangles' planes?
bool closed_mesh_convex(const Model& m, int64_t lo, int64_t hi,
                        const std::vector<std::array<double, 3>>& distinct) {
    const double inf = std::numeric_limits<double>::infinity();
    double lower[3] = {inf, inf, inf}, upper[3] = {-inf, -inf, -inf};
    for (const auto& x : distinct)
        for (int i = 0; i < 3; ++i) {
            lower[i] = std::min(lower[i], x[i]);
            upper[i] = std::max(upper[i], x[i]);
        }
    const double flat = HULL_FLAT_REL * std::max({upper[0] - lower[0], upper[1] - lower[1],
                                                  upper[2] - lower[2]});
    for (int64_t t = lo; t < hi; ++t) {
        const double* a = m.forest.tris + 9 * t;
        const double u[3] = {a[3] - a[0], a[4] - a[1], a[5] - a[2]};
        const double w[3] = {a[6] - a[0], a[7] - a[1], a[8] - a[2]};
        const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                             u[0] * w[1] - u[1] * w[0]};
        const double length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(length > 0.0)) continue;  // a degenerate triangle has no plane
        double above = 0.0, below = 0.0;
        for (const auto& x : distinct) {
            const double h =
                (n[0] * (x[0] - a[0]) + n[1] * (x[1] - a[1]) + n[2] * (x[2] - a[2])) / length;
            above = std::max(above, h);
            below = std::min(below, h);
        }
        if (above > flat && below < -flat) return false;
    }
    return true;
}

}  // namespace

bool element_hull(const Model& m, int64_t e, Hull& out) {
    const int kind = int(m.elem_solid[SOLID_WIDTH * e]);
    const int64_t lo = m.elem_tris[2 * e], hi = m.elem_tris[2 * e + 1];
    if (kind == SOLID_NONE || hi - lo < 4) return false;
    if (kind == SOLID_CLOSED_MESH && hi - lo > HULL_TEST_MAX_TRIANGLES) return false;
    std::vector<std::array<double, 3>> corners;
    corners.reserve(3 * (hi - lo));
    for (int64_t t = lo; t < hi; ++t)
        for (int k = 0; k < 3; ++k) {
            const double* x = m.forest.tris + 9 * t + 3 * k;
            corners.push_back({x[0], x[1], x[2]});
        }
    std::vector<std::array<double, 3>> distinct(corners);
    std::sort(distinct.begin(), distinct.end());
    distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
    if (kind == SOLID_CLOSED_MESH && !closed_mesh_convex(m, lo, hi, distinct)) return false;
    const auto index = [&](const std::array<double, 3>& x) {
        return int64_t(std::lower_bound(distinct.begin(), distinct.end(), x) - distinct.begin());
    };
    std::vector<std::pair<int64_t, int64_t>> edges;
    for (size_t t = 0; t < corners.size(); t += 3)
        for (int k = 0; k < 3; ++k) {
            const int64_t i = index(corners[t + k]), j = index(corners[t + (k + 1) % 3]);
            if (i == j) continue;
            edges.push_back({i, j});
            edges.push_back({j, i});
        }
    std::sort(edges.begin(), edges.end());
    edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
    const int64_t n = int64_t(distinct.size());
    // Indices are int32 (hull_support reads half the bytes): a hull beyond that is not swept.
    if (edges.size() >= size_t(std::numeric_limits<int32_t>::max())) return false;
    out.vertices.clear();
    for (const auto& x : distinct) out.vertices.insert(out.vertices.end(), x.begin(), x.end());
    for (int i = 0; i < 3; ++i) {
        double sum = 0.0;
        for (const auto& x : distinct) sum += x[i];
        out.centre[i] = sum / double(distinct.size());
    }
    double far = 0.0;
    for (const auto& x : distinct) {
        const double r[3] = {x[0] - out.centre[0], x[1] - out.centre[1], x[2] - out.centre[2]};
        far = std::max(far, r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    }
    out.radius = std::sqrt(far) * (1.0 + 1e-12) + 1e-12;
    out.adj_start.assign(1, 0);
    out.adj.clear();
    size_t next = 0;
    for (int64_t i = 0; i < n; ++i) {
        while (next < edges.size() && edges[next].first == i) out.adj.push_back(int32_t(edges[next++].second));
        out.adj_start.push_back(int32_t(out.adj.size()));
    }
    // A box's corners by octant, each the vertex nearest where it should be (each one
    // distinct, and near: else the box is read as any hull).
    out.axes.clear();
    out.corner.clear();
    if (kind == SOLID_BOX && n == 8) {
        const double* row = m.elem_solid + SOLID_WIDTH * e;
        const double* R = row + 4;
        const double* t = row + 13;
        const double size = std::fabs(row[1]) + std::fabs(row[2]) + std::fabs(row[3]);
        std::vector<int32_t> corner(8, -1);
        bool found = true;
        for (int s = 0; s < 8 && found; ++s) {
            double x[3];
            for (int i = 0; i < 3; ++i) {
                x[i] = t[i];
                for (int k = 0; k < 3; ++k) x[i] += (s >> k & 1 ? 1.0 : -1.0) * row[1 + k] * R[3 * i + k];
            }
            int64_t best = 0;
            double gap = std::numeric_limits<double>::infinity();
            for (int64_t i = 0; i < n; ++i) {
                const auto& y = distinct[i];
                const double g = std::fabs(y[0] - x[0]) + std::fabs(y[1] - x[1]) + std::fabs(y[2] - x[2]);
                if (g < gap) {
                    gap = g;
                    best = i;
                }
            }
            found = gap <= 1e-9 * size && std::find(corner.begin(), corner.end(), best) == corner.end();
            corner[s] = int32_t(best);
        }
        if (found) {
            out.axes.assign(R, R + 9);
            out.corner = corner;
        }
    }
    out.seeds.assign(HULL_SEEDS, 0);
    for (int k = 0; k < HULL_SEEDS; ++k) {
        const double* u = hull_seed_direction(k);
        double top = -std::numeric_limits<double>::infinity();
        for (int64_t i = 0; i < n; ++i) {
            const double* x = out.vertices.data() + 3 * i;
            const double along = u[0] * x[0] + u[1] * x[1] + u[2] * x[2];
            if (along > top) {
                top = along;
                out.seeds[k] = int32_t(i);
            }
        }
    }
    return true;
}

}  // namespace collision_sensor
