// The proximity query (proximity.hpp).
#include "proximity.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "cloud_queries.hpp"
#include "containment.hpp"
#include "distance.hpp"
#include "poses.hpp"

namespace collision_sensor {

namespace {

// A pair's nearest points (body a's frame, on the triangles, best.distance the padded distance) as
// the padded bodies' (world frame, body a at T_world_a) into row (point on a, point on b). Apart:
// each point moved along the nearest direction by its body's padding, onto the padded surface, so
// that the two are the padded distance apart. In contact: one point, in both padded bodies: where
// the triangles meet (the midpoint of the two, equal up to rounding) or, padded, the point of the
// segment between the nearest points that splits it in the ratio of the two paddings (within pad_a
// of body a and pad_b of body b).
void write_nearest_points(const double* T_world_a, double pad_a, double pad_b,
                          const NearestPoints& best, double* row) {
    const double pad = pad_a + pad_b;
    double x[3], y[3], w[3];
    double ww = 0.0;
    for (int i = 0; i < 3; ++i) {
        w[i] = best.y[i] - best.x[i];
        ww += w[i] * w[i];
    }
    const double gap = std::sqrt(ww);  // the triangles' distance
    if (best.distance > 0.0) {
        const double ka = gap > 0.0 ? pad_a / gap : 0.0, kb = gap > 0.0 ? pad_b / gap : 0.0;
        for (int i = 0; i < 3; ++i) {
            x[i] = best.x[i] + ka * w[i];
            y[i] = best.y[i] - kb * w[i];
        }
    } else {
        const double k = (pad > 0.0 && gap > 0.0) ? pad_a / pad : 0.5;
        for (int i = 0; i < 3; ++i) x[i] = y[i] = best.x[i] + k * w[i];
    }
    const double* T = T_world_a;
    for (int i = 0; i < 3; ++i) {
        row[i] = T[4 * i] * x[0] + T[4 * i + 1] * x[1] + T[4 * i + 2] * x[2] + T[4 * i + 3];
        row[3 + i] = T[4 * i] * y[0] + T[4 * i + 1] * y[1] + T[4 * i + 2] * y[2] + T[4 * i + 3];
    }
}

// Seed best with triangles ia (body a) and ib (body b at pose) if they are nearer than it:
// an upper bound the traversal then only has to prove or improve.
void seed_nearest(const Model& m, int64_t ia, int64_t ib, const double* pose, double pad,
                  NearestPoints& best) {
    if (ia < 0 || ib < 0 || ia >= m.n_triangles || ib >= m.n_triangles) return;
    Triangle Q;
    double x[3], y[3];
    triangle_in_a(m.forest.tris, ib, pose, Q);
    const double d = triangle_distance(triangle_at(m.forest.tris, ia), Q, x, y) - pad;
    if (d < best.distance) best.take(d, ia, ib, x, y);
}

}  // namespace

void measure_proximity(const EngineView& view, const ProximityRequest& request,
                       Scratch& scratch, const ProximityResult& result) {
    const Model& m = view.model;
    const State& s = view.state;
    const double max_distance = request.max_distance;
    const double* T_world_body = s.poses.T_world_body;
    int64_t* nearest = scratch.nearest;
    const TraversalWork work = scratch.traversal();
    DistanceWork& rows = scratch.distance_work(m);
    double pose[POSE_WIDTH];
    for (int64_t p = 0; p < m.n_pairs; ++p) {
        const int64_t a = m.pair_a[p], b = m.pair_b[p];
        const double pad_a = m.padding[a], pad_b = m.padding[b], pad = pad_a + pad_b;
        result.distance[p] = INF;
        write_pair_pose(T_world_body, a, b, pose);
        if (m.is_cloud(b)) {  // a point cloud's voxels (cloud_queries.hpp)
            measure_cloud_pair(m, s, p, pose, max_distance, result);
            continue;
        }
        NearestPoints best;
        best.found = false;
        best.ia = best.ib = -1;
        const bool contact = s.status[p] != 0;
        if (contact) {
            best.distance = INF;
            seed_nearest(m, s.witness[2 * p], s.witness[2 * p + 1], pose, pad, best);
            if (best.found && pad == 0.0) best.distance = 0.0;  // they meet: nothing nearer
        } else {
            if (!(box_pair_gap(m.body_box(a), m.body_box(b), pose) < max_distance)) continue;
            best.distance = max_distance;
            seed_nearest(m, nearest[2 * p], nearest[2 * p + 1], pose, pad, best);
        }
        if (!(contact && pad == 0.0 && best.found)) {
            const DistanceTraversal node = {m.forest, pose, pad_a, pad_b, work, rows};
            for (int64_t ea = m.elem_start[a]; ea < m.elem_end[a]; ++ea)
                for (int64_t eb = m.elem_start[b]; eb < m.elem_end[b]; ++eb)
                    trees_distance(node, m.roots[ea], m.roots[eb], best);
        }
        if (best.found) {
            nearest[2 * p] = best.ia;
            nearest[2 * p + 1] = best.ib;
        }
        if (contact && !(best.found && best.distance <= 0.0)) {
            // In contact with no triangles within the padding: a body inside a solid (else,
            // not expected, the surfaces' nearest points stand).
            double v[3];
            if (contained_vertex(m, a, b, pose, v)) {
                std::memcpy(best.x, v, sizeof v);
                std::memcpy(best.y, v, sizeof v);
                best.found = true;
            }
            best.distance = -pad;
        }
        if (!best.found) continue;
        if (contact) best.distance = std::min(best.distance, 0.0);
        result.distance[p] = best.distance;
        write_nearest_points(T_world_body + 16 * a, pad_a, pad_b, best, result.points + 6 * p);
    }
}

}  // namespace collision_sensor
