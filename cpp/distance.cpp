// The proximity query: every checked pair's distance and nearest points (distance.hpp).
#include <cstring>
#include <vector>

#include "distance.hpp"
#include "query.hpp"

namespace collision_sensor {

// Like contained(), for a pair known to collide without meeting triangles: a vertex x (in body
// a's frame) of an element of one body that lies in a solid element of the other, a point of
// both bodies. False if there is none.
bool Engine::contained_vertex(int64_t a, int64_t b, const double* P, double* x) const {
    for (int64_t ea = body_elem_start_[a]; ea < body_elem_end_[a]; ++ea) {
        for (int64_t eb = body_elem_start_[b]; eb < body_elem_end_[b]; ++eb) {
            if (elem_tris_[2 * ea] == elem_tris_[2 * ea + 1] ||
                elem_tris_[2 * eb] == elem_tris_[2 * eb + 1])
                continue;
            if (elem_solid_[SOLID_WIDTH * ea] != SOLID_NONE) {  // eb's vertex, in body a
                const double* v = forest_.tris + 9 * elem_tris_[2 * eb];
                for (int i = 0; i < 3; ++i)
                    x[i] = P[3 * i] * v[0] + P[3 * i + 1] * v[1] + P[3 * i + 2] * v[2] + P[9 + i];
                if (inside_solid(ea, x)) return true;
            }
            if (elem_solid_[SOLID_WIDTH * eb] != SOLID_NONE) {  // ea's vertex, in body b
                const double* v = forest_.tris + 9 * elem_tris_[2 * ea];
                const double d0 = v[0] - P[9], d1 = v[1] - P[10], d2 = v[2] - P[11];
                const double y[3] = {P[0] * d0 + P[3] * d1 + P[6] * d2,
                                     P[1] * d0 + P[4] * d1 + P[7] * d2,
                                     P[2] * d0 + P[5] * d1 + P[8] * d2};
                if (inside_solid(eb, y)) {
                    std::memcpy(x, v, 3 * sizeof(double));
                    return true;
                }
            }
        }
    }
    return false;
}

// For each pair: colliding (status 1 after the query) -> distance 0 and a point of both
// bodies (on the meeting triangles, or a vertex inside a solid); apart -> the distance if it
// is below max_distance, else INF. The pair's body boxes are tried first: a pair whose boxes
// are max_distance apart or more costs one bound. Points come out in the world (root) frame,
// each pair's row (point on body a, point on body b), bodies as pair_a, pair_b.
int64_t Engine::proximity(const double* q, double max_distance, double* distance,
                          double* points) {
    const int64_t code = query(q, false);
    if (code < 0) return code;
    refresh_all_poses();
    const int64_t n_nodes = header_[H_I_LAYOUT + LAYOUT_WIDTH * IntSlot::nodes + 2];  // d0
    if (int64_t(placed_stamp_.size()) != n_nodes) {  // the first call only
        placed_rows_.assign(PLACED_WIDTH * n_nodes, 0.0);
        placed_stamp_.assign(n_nodes, -1);
        placed_tag_ = 0;
    }
    PlacedBoxes placed = {placed_rows_.data(), placed_stamp_.data(), placed_tag_};
    double pose[POSE_WIDTH];
    for (int64_t p = 0; p < n_pairs_; ++p) {
        const int64_t a = pair_a_[p], b = pair_b_[p];
        distance[p] = INF;
        write_pair_pose(a, b, pose);
        NearestPoints best;
        best.found = false;
        if (status_[p] != 0) {
            const int64_t wa = witness_[2 * p], wb = witness_[2 * p + 1];
            if (wa >= 0) {
                Triangle Q;
                triangle_in_a(forest_.tris, wb, pose, Q);
                triangle_distance(triangle_at(forest_.tris, wa), Q, best.x, best.y);
                best.found = true;
            } else if (contained_vertex(a, b, pose, best.x)) {
                std::memcpy(best.y, best.x, sizeof best.x);
                best.found = true;
            }
            if (best.found) {  // one point: the surfaces meet there (up to the tolerance)
                for (int i = 0; i < 3; ++i) best.x[i] = best.y[i] = 0.5 * (best.x[i] + best.y[i]);
                best.distance = 0.0;
            } else {
                best.distance = INF;  // not expected: measure the surfaces
            }
        } else {
            const double* A = body_boxes_ + BOX_WIDTH * a;
            const double* B = body_boxes_ + BOX_WIDTH * b;
            best.distance = max_distance;
            if (!(box_pair_gap(A, B, pose) < max_distance)) continue;
        }
        if (!best.found) {
            for (int64_t ea = body_elem_start_[a]; ea < body_elem_end_[a]; ++ea)
                for (int64_t eb = body_elem_start_[b]; eb < body_elem_end_[b]; ++eb)
                    trees_distance(roots_[ea], roots_[eb], pose, forest_, stack_, counters_,
                                   best, placed);
            if (!best.found) continue;
            if (status_[p] != 0) best.distance = 0.0;
        }
        distance[p] = best.distance;
        const double* T = T_world_body_ + 16 * a;
        double* row = points + 6 * p;
        for (int i = 0; i < 3; ++i) {
            row[i] = T[4 * i] * best.x[0] + T[4 * i + 1] * best.x[1] + T[4 * i + 2] * best.x[2] +
                     T[4 * i + 3];
            row[3 + i] = T[4 * i] * best.y[0] + T[4 * i + 1] * best.y[1] +
                         T[4 * i + 2] * best.y[2] + T[4 * i + 3];
        }
    }
    placed_tag_ = placed.tag;
    return code;
}

}  // namespace collision_sensor
