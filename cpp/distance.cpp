// The proximity query: every checked pair's padded distance and nearest points (distance.hpp).
#include <algorithm>
#include <cmath>
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

// Pair p's nearest points (body a's frame, on the triangles, best.distance the padded
// distance) as the padded bodies' (world frame) into row (point on a, point on b). Apart: each
// point moved along the nearest direction by its body's padding, onto the padded surface, so
// that the two are the padded distance apart. In contact: one point, in both padded bodies:
// where the triangles meet (the midpoint of the two, equal up to rounding) or, padded, the
// point of the segment between the nearest points that splits it in the ratio of the two
// paddings (within pad_a of body a and pad_b of body b).
void Engine::write_nearest_points(int64_t a, double pad_a, double pad_b,
                                  const NearestPoints& best, double* row) const {
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
    const double* T = T_world_body_ + 16 * a;
    for (int i = 0; i < 3; ++i) {
        row[i] = T[4 * i] * x[0] + T[4 * i + 1] * x[1] + T[4 * i + 2] * x[2] + T[4 * i + 3];
        row[3 + i] = T[4 * i] * y[0] + T[4 * i + 1] * y[1] + T[4 * i + 2] * y[2] + T[4 * i + 3];
    }
}

// Seed best with triangles ia (body a) and ib (body b at pose) if they are nearer than it:
// an upper bound the traversal then only has to prove or improve.
void Engine::seed_nearest(int64_t ia, int64_t ib, const double* pose, double pad,
                          NearestPoints& best) const {
    if (ia < 0 || ib < 0 || ia >= n_tris_ || ib >= n_tris_) return;
    Triangle Q;
    double x[3], y[3];
    triangle_in_a(forest_.tris, ib, pose, Q);
    const double d = triangle_distance(triangle_at(forest_.tris, ia), Q, x, y) - pad;
    if (d < best.distance) best.take(d, ia, ib, x, y);
}

// For each pair, the padded distance (the triangles' distance minus the two bodies'
// paddings) if it is below max_distance (else INF), and the nearest points of the padded
// bodies (write_nearest_points) in the world (root) frame, each pair's row (point on body a,
// point on body b), bodies as pair_a, pair_b.
//
// A pair the query found in contact (status 1) has a padded distance <= 0: without padding 0
// and a point where the triangles meet (its witness triangles) or a vertex inside a solid
// element; with padding, the triangles' distance minus the padding (exact: the traversal runs
// from the witness down to 0 distance) or, for a body inside a solid without surfaces
// within the padding, -padding at that vertex. A pair apart: its body boxes are tried first
// (a pair whose boxes are max_distance apart costs one bound), then the triangles nearest
// last time seed the traversal (under coherent motion nearly the answer, so the traversal
// mostly only proves it).
int64_t Engine::proximity(const double* q, double max_distance, double* distance,
                          double* points) {
    const int64_t code = query(q, false);
    if (code < 0) return code;
    refresh_all_poses();
    const int64_t n_nodes = header_[H_I_LAYOUT + LAYOUT_WIDTH * IntSlot::nodes + 2];  // d0
    if (int64_t(placed_stamp_.size()) != n_nodes) {  // the first call only
        placed_rows_.assign(PLACED_WIDTH * n_nodes, 0.0);
        placed_stamp_.assign(n_nodes, -1);
        support_rows_.assign(n_nodes, 0.0);
        support_stamp_.assign(n_nodes, -1);
        placed_tag_ = support_tag_ = 0;
    }
    DistanceWork work = {placed_rows_.data(), placed_stamp_.data(), support_rows_.data(),
                         support_stamp_.data(), placed_tag_, support_tag_};
    double pose[POSE_WIDTH];
    for (int64_t p = 0; p < n_pairs_; ++p) {
        const int64_t a = pair_a_[p], b = pair_b_[p];
        const double pad_a = padding_[a], pad_b = padding_[b], pad = pad_a + pad_b;
        distance[p] = INF;
        write_pair_pose(a, b, pose);
        NearestPoints best;
        best.found = false;
        best.ia = best.ib = -1;
        const bool contact = status_[p] != 0;
        if (contact) {
            best.distance = INF;
            const int64_t wa = witness_[2 * p], wb = witness_[2 * p + 1];
            seed_nearest(wa, wb, pose, pad, best);
            if (best.found && pad == 0.0) best.distance = 0.0;  // they meet: nothing nearer
        } else {
            const double* A = body_boxes_ + BOX_WIDTH * a;
            const double* B = body_boxes_ + BOX_WIDTH * b;
            if (!(box_pair_gap(A, B, pose) < max_distance)) continue;
            best.distance = max_distance;
            seed_nearest(nearest_[2 * p], nearest_[2 * p + 1], pose, pad, best);
        }
        if (!(contact && pad == 0.0 && best.found)) {
            for (int64_t ea = body_elem_start_[a]; ea < body_elem_end_[a]; ++ea)
                for (int64_t eb = body_elem_start_[b]; eb < body_elem_end_[b]; ++eb)
                    trees_distance(roots_[ea], roots_[eb], pose, pad_a, pad_b, forest_, stack_,
                                   counters_, best, work);
        }
        if (best.found) {
            nearest_[2 * p] = best.ia;
            nearest_[2 * p + 1] = best.ib;
        }
        if (contact && !(best.found && best.distance <= 0.0)) {
            // In contact with no triangles within the padding: a body inside a solid (else,
            // not expected, the surfaces' nearest points stand).
            double v[3];
            if (contained_vertex(a, b, pose, v)) {
                std::memcpy(best.x, v, sizeof v);
                std::memcpy(best.y, v, sizeof v);
                best.found = true;
            }
            best.distance = -pad;
        }
        if (!best.found) continue;
        if (contact) best.distance = std::min(best.distance, 0.0);
        distance[p] = best.distance;
        write_nearest_points(a, pad_a, pad_b, best, points + 6 * p);
    }
    placed_tag_ = work.placed_tag;
    support_tag_ = work.support_tag;
    return code;
}

}  // namespace collision_sensor
