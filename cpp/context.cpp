// The state and the work areas of a query (context.hpp).
#include "context.hpp"

#include <algorithm>

namespace collision_sensor {

void Fronts::size_for(int64_t n_pairs) {
    capacity = std::clamp(FRONT_POOL_ROWS / std::max<int64_t>(n_pairs, 1), FRONT_ROWS_MIN,
                          FRONT_ROWS_MAX);
    pairs.assign(3 * n_pairs * capacity, 0);
    until.assign(n_pairs * capacity, 0.0);
    state.assign(2 * n_pairs, 0);
    travel.assign(n_pairs, 0.0);
}

State make_state(const ResolvedLayout& r, const Model& model) {
    State s;
    s.q_last = r.f[slot::q_last];
    s.q_ref = r.f[slot::q_ref];
    s.extension = r.f[slot::extension];
    s.poses = {r.f[slot::T_world_body], r.i[slot::stale]};
    s.flags = r.i[slot::query_flags];
    s.status = r.i[slot::status];
    s.witness = r.i[slot::witness];
    s.forced = r.i[slot::forced];
    s.clearance = r.f[slot::clearance];
    s.q_eval = r.f[slot::q_eval];
    s.travel = r.f[slot::travel];
    s.fronts.size_for(model.n_pairs);
    // The checker lists no forced pair: the first query looks at every one.
    s.forced_mode = std::any_of(s.forced, s.forced + model.n_pairs, [](int64_t f) { return f; })
                        ? FORCED_SCAN
                        : FORCED_NONE;
    return s;
}

Scratch::Scratch(const Model& model, int64_t front_capacity, int64_t* counters_rows,
                 int64_t* scene_culled_rows, int64_t* nearest_rows) {
    const int64_t L = model.n_links, P = model.n_pairs;
    if (!counters_rows) {
        own_counters_.assign(N_COUNTERS, 0);
        counters_rows = own_counters_.data();
    }
    if (!scene_culled_rows) {
        own_scene_culled_.assign((model.n_bodies - L) * L, 0);
        scene_culled_rows = own_scene_culled_.data();
    }
    if (!nearest_rows) {
        own_nearest_.assign(2 * P, -1);
        nearest_rows = own_nearest_.data();
    }
    counters = counters_rows;
    scene_culled = scene_culled_rows;
    nearest = nearest_rows;
    // A traversal's seeds (a front's node pairs, or a pair's root pairs), then a descent.
    const int64_t rows = std::max(front_capacity, model.most_seeds) + 2 * model.depth + 8;
    stack.assign(PAIR_ROW * rows, 0);
    todo.assign(P, 0);
    pending.assign(P, 0);
    moved.assign(model.n_joints, 0);
    chain.assign(L, 0);
    subtree_boxes.assign(BOX_WIDTH * L, 0.0);
    front_pairs.assign(3 * front_capacity, 0);
    front_until.assign(front_capacity, 0.0);
}

DistanceWork& Scratch::distance_work(const Model& model) {
    if (int64_t(placed_stamp.size()) != model.n_nodes) {
        placed.assign(PLACED_WIDTH * model.n_nodes, 0.0);
        placed_stamp.assign(model.n_nodes, -1);
        support.assign(model.n_nodes, 0.0);
        support_stamp.assign(model.n_nodes, -1);
        distance_rows = {placed.data(), placed_stamp.data(), support.data(),
                         support_stamp.data(), 0, 0};
    }
    return distance_rows;
}

}  // namespace collision_sensor
