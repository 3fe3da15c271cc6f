// One collision query over the whole robot and scene: see query.hpp.
#include "query.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace collision_sensor {

#define CS_SLOT_NAME(name) #name,
const char* const FLOAT_SLOT_NAMES[N_FLOAT_SLOTS] = {CS_FLOAT_SLOTS(CS_SLOT_NAME)};
const char* const INT_SLOT_NAMES[N_INT_SLOTS] = {CS_INT_SLOTS(CS_SLOT_NAME)};
#undef CS_SLOT_NAME

namespace {

struct Layout {
    int64_t offset, size, d0, d1, d2;
};

Layout layout_entry(const int64_t* header, int base, int k) {
    const int64_t* row = header + base + LAYOUT_WIDTH * k;
    return {row[0], row[1], row[2], row[3], row[4]};
}

}  // namespace

void Engine::check_shape(const char* name, const Shape& s, int64_t d0, int64_t d1,
                         int64_t d2) const {
    // -1: any extent. The packer pads shapes to 3 dimensions with 1.
    if ((d0 >= 0 && s.d0 != d0) || (d1 >= 0 && s.d1 != d1) || (d2 >= 0 && s.d2 != d2))
        throw std::invalid_argument(
            std::string("packed array '") + name + "' has shape (" + std::to_string(s.d0) + ", " +
            std::to_string(s.d1) + ", " + std::to_string(s.d2) + "), expected (" +
            std::to_string(d0) + ", " + std::to_string(d1) + ", " + std::to_string(d2) +
            ") (-1: any); the checker and the engine disagree on the layout: rebuild the engine");
}

Engine::Engine(double* F, int64_t f_size, int64_t* I, int64_t i_size) {
    if (i_size < HEADER_SIZE)
        throw std::invalid_argument("int buffer smaller than the engine's header");
    header_ = I;
    double* fp[N_FLOAT_SLOTS];
    int64_t* ip[N_INT_SLOTS];
    Shape fs[N_FLOAT_SLOTS], is[N_INT_SLOTS];
    for (int k = 0; k < N_FLOAT_SLOTS; ++k) {
        const Layout l = layout_entry(I, H_LAYOUTS, k);
        if (l.offset < 0 || l.size < 0 || l.offset + l.size > f_size ||
            l.d0 * l.d1 * l.d2 != l.size)
            throw std::invalid_argument(std::string("packed float array '") +
                                        FLOAT_SLOT_NAMES[k] + "' lies outside its buffer");
        fp[k] = F + l.offset;
        fs[k] = {l.size, l.d0, l.d1, l.d2};
    }
    for (int k = 0; k < N_INT_SLOTS; ++k) {
        const Layout l = layout_entry(I, H_I_LAYOUT, k);
        if (l.offset < 0 || l.size < 0 || l.offset + l.size > i_size ||
            l.d0 * l.d1 * l.d2 != l.size)
            throw std::invalid_argument(std::string("packed int array '") + INT_SLOT_NAMES[k] +
                                        "' lies outside its buffer");
        ip[k] = I + l.offset;
        is[k] = {l.size, l.d0, l.d1, l.d2};
    }
    n_links_ = header_[H_N_LINKS];
    n_bodies_ = is[is_scene].size;
    n_joints_ = fs[q_ref].size;
    n_pairs_ = is[status].size;
    n_scene_ = n_bodies_ - n_links_;
    const int64_t n_nodes = n_nodes_ = is[nodes].d0;
    const int64_t L1 = std::max<int64_t>(n_links_, 1);
    if (n_links_ < 1 || n_scene_ < 0)
        throw std::invalid_argument("the robot has no links, or more links than bodies");
    check_shape("scalars", fs[scalars], N_SCALARS, 1, 1);
    check_shape("q_last", fs[q_last], n_joints_, 1, 1);
    check_shape("T_parent_joint", fs[T_parent_joint], n_links_, 4, 4);
    check_shape("axis", fs[axis], n_links_, 3, 1);
    check_shape("multiplier", fs[multiplier], n_links_, 1, 1);
    check_shape("offset", fs[offset], n_links_, 1, 1);
    check_shape("T_world_body", fs[T_world_body], n_bodies_, 4, 4);
    check_shape("body_boxes", fs[body_boxes], n_bodies_, BOX_WIDTH, 1);
    check_shape("boxes", fs[boxes], n_nodes, BOX_WIDTH, 1);
    check_shape("volume", fs[volume], n_nodes, 1, 1);
    check_shape("gain", fs[gain], n_nodes, 1, 1);
    check_shape("tris", fs[tris], -1, 3, 3);
    check_shape("subtree_boxes", fs[subtree_boxes], L1, BOX_WIDTH, 1);
    check_shape("padding", fs[padding], n_bodies_, 1, 1);
    check_shape("elem_solid", fs[elem_solid], std::max<int64_t>(is[roots].size, 1), SOLID_WIDTH,
                1);
    check_shape("clearance", fs[clearance], n_pairs_, 1, 1);
    check_shape("q_eval", fs[q_eval], n_pairs_, n_joints_, 1);
    check_shape("reach", fs[reach], n_pairs_, n_joints_, 1);
    check_shape("reach_ext", fs[reach_ext], n_pairs_, n_joints_, 1);
    check_shape("travel", fs[travel], n_pairs_, 2, 1);
    check_shape("front_travel", fs[front_travel], n_pairs_, 1, 1);
    check_shape("parent", is[parent], n_links_, 1, 1);
    check_shape("joint_type", is[joint_type], n_links_, 1, 1);
    check_shape("q_index", is[q_index], n_links_, 1, 1);
    check_shape("body_elem_start", is[body_elem_start], n_bodies_, 1, 1);
    check_shape("body_elem_end", is[body_elem_end], n_bodies_, 1, 1);
    check_shape("nodes", is[nodes], n_nodes, NODE_WIDTH, 1);
    check_shape("pair_a", is[pair_a], n_pairs_, 1, 1);
    check_shape("pair_b", is[pair_b], n_pairs_, 1, 1);
    check_shape("joint_pairs_start", is[joint_pairs_start], n_joints_ + 1, 1, 1);
    check_shape("joint_links_start", is[joint_links_start], n_joints_ + 1, 1, 1);
    check_shape("joint_prismatic", is[joint_prismatic], n_joints_, 1, 1);
    check_shape("witness", is[witness], n_pairs_, 2, 1);
    check_shape("moved", is[moved], n_joints_, 1, 1);
    check_shape("stale", is[stale], n_bodies_, 1, 1);
    check_shape("chain", is[chain], L1, 1, 1);
    check_shape("pending", is[pending], n_pairs_, 1, 1);
    check_shape("todo", is[todo], n_pairs_, 1, 1);
    check_shape("scene_culled", is[scene_culled], n_scene_, L1, 1);
    check_shape("stack", is[stack], -1, 3, 1);
    check_shape("counters", is[counters], N_COUNTERS, 1, 1);
    check_shape("front", is[front], fs[front_until].size, 3, 1);
    check_shape("front_state", is[front_state], n_pairs_, 2, 1);
    check_shape("nearest", is[nearest], n_pairs_, 2, 1);
    check_shape("forced", is[forced], n_pairs_, 1, 1);
    culled_width_ = L1;
    stack_rows_ = is[stack].d0;
    front_capacity_ = fs[front_until].size / (n_pairs_ + 1);

    elem_solid_ = fp[elem_solid];
    scalars_ = fp[scalars];
    kin_ = {n_links_, ip[parent], ip[joint_type], fp[T_parent_joint], fp[axis], ip[q_index],
            fp[multiplier], fp[offset]};
    forest_ = {fp[boxes], ip[nodes], fp[volume], fp[gain], fp[tris]};
    q_last_ = fp[q_last];
    q_ref_ = fp[q_ref];
    T_world_body_ = fp[T_world_body];
    body_boxes_ = fp[body_boxes];
    subtree_boxes_ = fp[subtree_boxes];
    padding_ = fp[padding];
    clearance_ = fp[clearance];
    q_eval_ = fp[q_eval];
    reach_ = fp[reach];
    reach_ext_ = fp[reach_ext];
    travel_ = fp[travel];
    front_until_ = fp[front_until];
    front_travel_ = fp[front_travel];
    is_scene_ = ip[is_scene];
    body_elem_start_ = ip[body_elem_start];
    body_elem_end_ = ip[body_elem_end];
    roots_ = ip[roots];
    pair_a_ = ip[pair_a];
    pair_b_ = ip[pair_b];
    joint_pairs_start_ = ip[joint_pairs_start];
    joint_pairs_ = ip[joint_pairs];
    joint_links_start_ = ip[joint_links_start];
    joint_links_ = ip[joint_links];
    joint_prismatic_ = ip[joint_prismatic];
    status_ = ip[status];
    witness_ = ip[witness];
    moved_ = ip[moved];
    stale_ = ip[stale];
    chain_ = ip[chain];
    pending_ = ip[pending];
    todo_ = ip[todo];
    scene_culled_ = ip[scene_culled];
    stack_ = ip[stack];
    counters_ = ip[counters];
    front_ = ip[front];
    front_state_ = ip[front_state];
    nearest_ = ip[nearest];
    forced_ = ip[forced];

    // Indices the query follows without checking: validated once here.
    const int64_t n_tris = n_tris_ = fs[tris].d0;
    for (int64_t b = 0; b < n_bodies_; ++b)
        if (!(padding_[b] >= 0.0 && padding_[b] < INF))
            throw std::invalid_argument("packed array 'padding': not a finite value >= 0");
    for (int64_t i = 0; i < n_links_; ++i) {
        const int64_t parent = kin_.parent[i];
        if (parent >= i || (i > 0 && parent < 0) || (i == 0 && parent >= 0))
            throw std::invalid_argument("packed array 'parent': links are not parents first");
        if (kin_.joint_type[i] < JOINT_FIXED || kin_.joint_type[i] > JOINT_FLOATING)
            throw std::invalid_argument("packed array 'joint_type': unknown joint type");
        if (kin_.joint_type[i] != JOINT_FIXED &&   // a multi-DOF joint's variables all in q
            (kin_.q_index[i] < 0 ||
             kin_.q_index[i] + joint_variable_count(kin_.joint_type[i]) > n_joints_))
            throw std::invalid_argument("packed array 'q_index': index out of range");
    }
    for (int64_t b = 0; b < n_bodies_; ++b)
        if (body_elem_start_[b] < 0 || body_elem_end_[b] < body_elem_start_[b] ||
            body_elem_end_[b] > is[roots].size)
            throw std::invalid_argument("packed arrays 'body_elem_*': out of range");
    for (int64_t p = 0; p < n_pairs_; ++p)
        if (pair_a_[p] < 0 || pair_a_[p] >= n_links_ || pair_b_[p] < 0 || pair_b_[p] >= n_bodies_)
            throw std::invalid_argument("packed arrays 'pair_*': body out of range");
    for (int64_t n = 0; n < n_nodes; ++n) {
        const int64_t* node = forest_.node(n);
        if (node[NODE_LEFT] >= n_nodes || node[NODE_RIGHT] >= n_nodes ||
            (node[NODE_LEFT] >= 0 && node[NODE_RIGHT] < 0) || node[NODE_FIRST] < 0 ||
            node[NODE_COUNT] < 0 || node[NODE_FIRST] + node[NODE_COUNT] > n_tris)
            throw std::invalid_argument("packed array 'nodes': index out of range");
    }
    // Each tree's triangles (internal nodes carry no count): the range its leaves cover.
    const int64_t n_roots = is[roots].size;
    elem_tris_.assign(2 * n_roots, 0);
    std::vector<int64_t> pending_nodes;
    for (int64_t e = 0; e < n_roots; ++e) {
        int64_t lo = n_tris, hi = 0;
        pending_nodes.assign(1, roots_[e]);
        for (int64_t visits = 0; !pending_nodes.empty(); ++visits) {
            if (visits > n_nodes)  // a node reached twice: a cycle, not a tree
                throw std::invalid_argument("packed array 'nodes': not a tree");
            const int64_t* node = forest_.node(pending_nodes.back());
            pending_nodes.pop_back();
            if (node[NODE_LEFT] >= 0) {
                pending_nodes.push_back(node[NODE_LEFT]);
                pending_nodes.push_back(node[NODE_RIGHT]);
            } else if (node[NODE_COUNT] > 0) {
                lo = std::min(lo, node[NODE_FIRST]);
                hi = std::max(hi, node[NODE_FIRST] + node[NODE_COUNT]);
            }
        }
        elem_tris_[2 * e] = lo < hi ? lo : 0;
        elem_tris_[2 * e + 1] = lo < hi ? hi : 0;
    }
    body_solid_.assign(n_bodies_, 0);
    for (int64_t b = 0; b < n_bodies_; ++b)
        for (int64_t e = body_elem_start_[b]; e < body_elem_end_[b]; ++e)
            if (elem_solid_[SOLID_WIDTH * e] != SOLID_NONE) body_solid_[b] = 1;
    // |centre| + radius of each body box, for clearance_margin.
    body_reach_.assign(n_bodies_, 0.0);
    for (int64_t b = 0; b < n_bodies_; ++b) {
        const double* B = body_boxes_ + BOX_WIDTH * b;
        const double* c = B + BOX_CENTER;
        body_reach_[b] = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]) + B[BOX_RADIUS];
    }
    // Each body's pairs as body b (every world object's pairs: move_world_body forces them).
    body_pairs_start_.assign(n_bodies_ + 1, 0);
    for (int64_t p = 0; p < n_pairs_; ++p) ++body_pairs_start_[pair_b_[p] + 1];
    for (int64_t b = 0; b < n_bodies_; ++b) body_pairs_start_[b + 1] += body_pairs_start_[b];
    body_pairs_.assign(n_pairs_, 0);
    std::vector<int64_t> next(body_pairs_start_.begin(), body_pairs_start_.end() - 1);
    for (int64_t p = 0; p < n_pairs_; ++p) body_pairs_[next[pair_b_[p]]++] = p;
}

// ----------------------------------------------------------------------------- poses

// Bring body i's world pose up to date with q_ref: it and its stale ancestors, top down.
// Scene bodies are never stale.
void Engine::refresh_pose(int64_t i) {
    int64_t n = 0;
    for (int64_t k = i; k >= 0 && stale_[k]; k = kin_.parent[k]) chain_[n++] = k;
    for (int64_t t = n - 1; t >= 0; --t) {
        set_link_pose(kin_, chain_[t], q_ref_, T_world_body_);
        stale_[chain_[t]] = 0;
    }
}

void Engine::refresh_all_poses() {
    for (int64_t i = 0; i < n_links_; ++i) {
        if (stale_[i]) {
            set_link_pose(kin_, i, q_ref_, T_world_body_);
            stale_[i] = 0;
        }
    }
}

// Body b's pose in body a's frame (R_ab row-major, then t_ab):
// [R_ab, t_ab] = T_world_a^-1 T_world_b = [Ra' Rb, Ra' (tb - ta)].
void Engine::write_pair_pose(int64_t a, int64_t b, double* pose) const {
    const double* Ta = T_world_body_ + 16 * a;
    const double* Tb = T_world_body_ + 16 * b;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j)
            pose[3 * i + j] = Ta[i] * Tb[j] + Ta[4 + i] * Tb[4 + j] + Ta[8 + i] * Tb[8 + j];
        pose[9 + i] = Ta[i] * (Tb[3] - Ta[3]) + Ta[4 + i] * (Tb[7] - Ta[7]) +
                      Ta[8 + i] * (Tb[11] - Ta[11]);
    }
}

// CLEARANCE_EPS_REL times a bound of every coordinate the pair's tests see.
double Engine::clearance_margin(int64_t a, int64_t b, const double* pose) const {
    const double t = std::sqrt(pose[9] * pose[9] + pose[10] * pose[10] + pose[11] * pose[11]);
    return CLEARANCE_EPS_REL * (t + body_reach_[a] + body_reach_[b]);
}

// ----------------------------------------------------------------------------- culling

// For every link k, the world axis-aligned box around the boxes of all links in k's subtree
// (identity axes): the volumes spanning several links (sec. 2.2), rebuilt from the link boxes,
// never from geometry. Row 0 (the root) is the robot's root volume. A subtree without
// geometry gets half extents -1 (empty).
void Engine::subtree_volumes() {
    double* S = subtree_boxes_;
    for (int64_t k = 0; k < n_links_; ++k)
        for (int c = 0; c < 6; ++c) S[BOX_WIDTH * k + c] = c < 3 ? INF : -INF;  // lo, hi
    for (int64_t b = n_links_ - 1; b >= 0; --b) {  // children before parents
        double* row = S + BOX_WIDTH * b;
        if (body_elem_end_[b] > body_elem_start_[b]) {
            const double* T = T_world_body_ + 16 * b;
            const double* box = body_boxes_ + BOX_WIDTH * b;
            for (int i = 0; i < 3; ++i) {
                double c = T[4 * i + 3];
                double e = 0.0;
                for (int k = 0; k < 3; ++k) {
                    c += T[4 * i + k] * box[BOX_CENTER + k];
                    // |row i of R_world_box| . half: the box's half width along world axis i.
                    const double ax = T[4 * i] * box[BOX_AXES + k] +
                                      T[4 * i + 1] * box[BOX_AXES + 3 + k] +
                                      T[4 * i + 2] * box[BOX_AXES + 6 + k];
                    e += std::fabs(ax) * box[BOX_HALF + k];
                }
                row[i] = std::min(row[i], c - e);
                row[3 + i] = std::max(row[3 + i], c + e);
            }
        }
        const int64_t p = kin_.parent[b];
        if (p >= 0) {
            double* up = S + BOX_WIDTH * p;
            for (int i = 0; i < 3; ++i) {
                up[i] = std::min(up[i], row[i]);
                up[3 + i] = std::max(up[3 + i], row[3 + i]);
            }
        }
    }
    for (int64_t k = 0; k < n_links_; ++k) {  // lo/hi -> a box row
        double* row = S + BOX_WIDTH * k;
        const double lo[3] = {row[0], row[1], row[2]};
        const double hi[3] = {row[3], row[4], row[5]};
        for (int c = 0; c < BOX_WIDTH; ++c) row[c] = 0.0;
        row[BOX_AXES] = row[BOX_AXES + 4] = row[BOX_AXES + 8] = 1.0;
        if (!(lo[0] <= hi[0])) {
            row[BOX_HALF] = -1.0;  // no geometry below k
            continue;
        }
        double hh = 0.0;
        for (int i = 0; i < 3; ++i) {
            const double h = 0.5 * (hi[i] - lo[i]);
            row[BOX_CENTER + i] = 0.5 * (lo[i] + hi[i]);
            row[BOX_HALF + i] = h;
            hh += h * h;
        }
        row[BOX_RADIUS] = std::sqrt(hh);
    }
}

// True iff boxes A (body a) and B (at pose P in A's body) are apart.
bool Engine::boxes_apart(const double* A, const double* B, const double* P) const {
    if (spheres(A, B, P).apart) return true;
    double T[12];
    box_in_frame(A, B, P, T);
    if (header_[H_BOX_METHOD] == BOX_TEST_PAPER) return paper_separates(A, B, T);
    return sat_axis(A, B, T) >= 0;
}

// boxes_apart, and when apart their gap (box_pair_gap) into gap, the two sharing the work.
bool Engine::boxes_apart_gap(const double* A, const double* B, const double* P,
                             double* gap) const {
    const Spheres s = spheres(A, B, P);
    double T[12];
    box_in_frame(A, B, P, T);
    if (!s.apart && (header_[H_BOX_METHOD] == BOX_TEST_PAPER ? !paper_separates(A, B, T)
                                                               : sat_axis(A, B, T) < 0))
        return false;
    *gap = std::max(std::sqrt(s.dd) - s.radii, face_gap(A, B, T));
    return true;
}

// True iff scene object s's box is disjoint from the volume of link k's subtree.
bool Engine::scene_body_outside(int64_t s, int64_t k) {
    const double* A = subtree_boxes_ + BOX_WIDTH * k;
    if (A[BOX_HALF] < 0.0) return true;  // nothing with geometry below k
    const int64_t body = n_links_ + s;
    const double* T = T_world_body_ + 16 * body;
    const double P[12] = {T[0], T[1], T[2], T[4], T[5], T[6], T[8], T[9], T[10],
                          T[3], T[7], T[11]};
    return boxes_apart(A, body_boxes_ + BOX_WIDTH * body, P);
}

// First culling against the scene by the volumes spanning several links, top down: link k is
// culled for object s when its subtree's volume, or an ancestor's, misses s's box. Every link
// pose must be current. A link whose volume is its parent's (a link without geometry of its
// own and one child: every link of a chain above the first with geometry) takes the parent's
// verdict untested: the same two boxes give the same answer.
void Engine::refresh_culling() {
    subtree_volumes();
    for (int64_t s = 0; s < n_scene_; ++s) {
        int64_t* culled = scene_culled_ + culled_width_ * s;
        for (int64_t k = 0; k < n_links_; ++k) {
            const int64_t p = kin_.parent[k];
            if (p >= 0 && (culled[p] || same_volume(k, p)))
                culled[k] = culled[p];
            else
                culled[k] = scene_body_outside(s, k) ? 1 : 0;
        }
    }
}

// True iff the volumes of links k and p (subtree_volumes) are the same box.
bool Engine::same_volume(int64_t k, int64_t p) const {
    const double* K = subtree_boxes_ + BOX_WIDTH * k;
    const double* P = subtree_boxes_ + BOX_WIDTH * p;
    return std::equal(K + BOX_CENTER, K + BOX_CENTER + 3, P + BOX_CENTER) &&
           std::equal(K + BOX_HALF, K + BOX_HALF + 3, P + BOX_HALF);
}

// ----------------------------------------------------------------------------- planning

// E: the sum of |value| of the prismatic joints at q_ref (see plan_update).
double Engine::extension() const {
    double e = 0.0;
    for (int64_t i = 0; i < n_links_; ++i)
        if (kin_.joint_type[i] == JOINT_PRISMATIC)
            e += std::fabs(kin_.multiplier[i] * q_ref_[kin_.q_index[i]] + kin_.offset[i]);
    return e;
}

// Pair p's two travel sums from scratch: over variables j, |q_ref[j] - q_eval[p, j]| times
// reach[p, j] and times reach_ext[p, j] (both 0 off the pair's path).
void Engine::resync_travel(int64_t p) {
    double fixed = 0.0, ext = 0.0;
    const double* e = q_eval_ + n_joints_ * p;
    const double* r = reach_ + n_joints_ * p;
    const double* rx = reach_ext_ + n_joints_ * p;
    for (int64_t j = 0; j < n_joints_; ++j) {
        const double d = std::fabs(q_ref_[j] - e[j]);
        fixed += d * r[j];
        ext += d * rx[j];
    }
    travel_[2 * p] = fixed;
    travel_[2 * p + 1] = ext;
}

// Move pair p's travel sums by variable j's terms going from old_value to new_value.
void Engine::add_travel(int64_t p, int64_t j, double old_value, double new_value) {
    const double e = q_eval_[n_joints_ * p + j];
    const double d = std::fabs(new_value - e) - std::fabs(old_value - e);
    travel_[2 * p] += d * reach_[n_joints_ * p + j];
    travel_[2 * p + 1] += d * reach_ext_[n_joints_ * p + j];
}

// False iff pair p is known to be still apart: its travel is below its clearance. Every
// comparison is written so that a NaN (an infinite joint motion times a zero reach, an
// infinite extension times a zero sum) means "re-check": a NaN must never prove a pair apart.
bool Engine::needs_recheck(int64_t p, double extension) {
    if (status_[p] != 0 || !(clearance_[p] > 0.0)) return true;
    const double c = clearance_[p];
    if (travel_[2 * p] + extension * travel_[2 * p + 1] < TRAVEL_GUARD * c) {
        // A sum can only be trusted while each of its terms is: one huge joint motion added
        // and later taken away again leaves the rounding of the huge value behind (it
        // absorbed the small terms), so a sum that went past the clearance is recomputed.
        return false;
    }
    resync_travel(p);  // exact near the edge
    return !(travel_[2 * p] + extension * travel_[2 * p + 1] < c);
}

// Start a full check: take all of q, recompute every link pose and E.
void Engine::plan_full(const double* q) {
    for (int64_t j = 0; j < n_joints_; ++j) q_ref_[j] = q[j];
    for (int64_t i = 0; i < n_links_; ++i) stale_[i] = 1;
    refresh_all_poses();
    scalars_[S_EXTENSION] = extension();
}

// Take the joints of q that moved into q_ref; list the pairs to re-check in todo.
//
// Contract (paper sec. 4.2, taken further by the clearance):
//     moved = |q - q_ref| > tolerance;  q_ref[moved] = q[moved]
//     stale[links below a moved joint] = 1          (poses follow on demand)
//     todo = [p for p in pairs if moved[path(p)].any()
//             and not (status[p] == 0 and travel(p) < clearance[p])]
// A pair re-checked incrementally and found apart keeps clearance[p], a lower bound of the
// distance between its two bodies' triangles, and q_eval[p] = q_ref then (full checks record
// none). Moving variable j by dq moves no point of either body by more than
// |dq| (reach[p, j] + reach_ext[p, j] E) relative to the other (E: the sum of the prismatic
// joints' |value| at q_ref), so while the sum of these, travel(p) from q_eval[p] to q_ref,
// stays below clearance[p] the pair is still apart. Each pair keeps the two sums of |dq|
// times reach and times reach_ext, travel(p) = fixed + E ext, so a slider moving changes E
// without touching any sum. Only the pairs on a moved variable's list are visited, and their
// sums move by that variable's terms alone. The running sums are recomputed exactly when a
// pair's travel comes within TRAVEL_GUARD of its clearance, and every TRAVEL_RESYNC_CALLS
// calls.
//
// Running sums and huge motions: a skipped pair's sum is below its clearance, so every term
// in it is too, and its rounding is a few ulps of the clearance. A motion that takes a term
// past the clearance makes the pair due at once (needs_recheck then resyncs and re-checks
// it, which sets q_eval to the new state and restarts its sums), so no sum ever carries a
// huge term forward for a later motion to cancel. needs_recheck is NaN-safe for the same
// reason: without that, an infinite extension times a zero sum (a NaN) once let such pairs
// through unchecked, and the next motion back cancelled a huge term against itself.
int64_t Engine::plan_update(const double* q) {
    const double tolerance = scalars_[S_TOLERANCE];
    int64_t n_moved = 0;
    bool prismatic = false;
    for (int64_t j = 0; j < n_joints_; ++j) {
        if (std::fabs(q[j] - q_ref_[j]) > tolerance) {
            moved_[n_moved++] = j;
            prismatic |= joint_prismatic_[j] != 0;
        }
    }
    if (n_moved == 0) return 0;
    for (int64_t m = 0; m < n_moved; ++m) {
        const int64_t j = moved_[m];
        for (int64_t t = joint_links_start_[j]; t < joint_links_start_[j + 1]; ++t)
            stale_[joint_links_[t]] = 1;
    }
    header_[H_RESYNC_COUNTDOWN] -= 1;
    const bool resync = header_[H_RESYNC_COUNTDOWN] <= 0;
    double ext = scalars_[S_EXTENSION];
    const double ext_before = ext;
    int64_t n = 0;
    if (n_moved == 1 && !resync) {
        const int64_t j = moved_[0];
        const double old_value = q_ref_[j];
        const double new_value = q_ref_[j] = q[j];
        if (prismatic) scalars_[S_EXTENSION] = ext = extension();
        for (int64_t t = joint_pairs_start_[j]; t < joint_pairs_start_[j + 1]; ++t) {
            const int64_t p = joint_pairs_[t];
            if (motion_record_) record_gap(p, ext_before);
            if (clearance_[p] > 0.0) add_travel(p, j, old_value, new_value);
            if (needs_recheck(p, ext) ||
                (motion_record_ && prismatic && !motion_skip(p, ext_before, ext)))
                todo_[n++] = p;
        }
        return n;
    }
    for (int64_t m = 0; m < n_moved; ++m) {
        const int64_t j = moved_[m];
        const double old_value = q_ref_[j];
        const double new_value = q_ref_[j] = q[j];
        for (int64_t t = joint_pairs_start_[j]; t < joint_pairs_start_[j + 1]; ++t) {
            const int64_t p = joint_pairs_[t];
            if (!pending_[p]) {  // first seen: its sums are still those of the last state
                if (motion_record_) record_gap(p, ext_before);
                pending_[p] = 1;
                todo_[n++] = p;
            }
            if (clearance_[p] > 0.0 && !resync) add_travel(p, j, old_value, new_value);
        }
    }
    if (prismatic) scalars_[S_EXTENSION] = ext = extension();
    if (resync) {
        header_[H_RESYNC_COUNTDOWN] = TRAVEL_RESYNC_CALLS;
        for (int64_t p = 0; p < n_pairs_; ++p)
            if (clearance_[p] > 0.0) resync_travel(p);
    }
    int64_t kept = 0;
    for (int64_t t = 0; t < n; ++t) {
        const int64_t p = todo_[t];
        pending_[p] = 0;
        if (needs_recheck(p, ext) ||
            (motion_record_ && prismatic && !motion_skip(p, ext_before, ext)))
            todo_[kept++] = p;
    }
    return kept;
}

// ----------------------------------------------------------------------------- re-checking

// Every sub-group tree of pair p's body a against every one of body b's.
//
// A full check descends from the roots. An incremental one starts from the pair's front when
// it has one (front_scan): the node pairs where its last descent that found it apart stopped.
// A front covers every pair of triangles whatever the poses, so it never goes stale, only
// costlier: it is kept while a re-check from it tests at most as many node pairs and triangle
// pairs as the last descent from the roots did; else the next re-check descends from the
// roots again and records a fresh one. Only a pair that was apart starts from its front (one
// that collided likely still does, and a descent towards its last meeting triangles stops at
// the first that meet), and only a pair whose clearance is tiny (FRONT_GAP_REL) keeps one (a
// pair with a real clearance is skipped for whole steps; a front's finer node pairs would
// only make that clearance smaller).
//
// front rows: pair p's in rows p F on, F = front_capacity_; the last F rows are work, where a
// front is recorded. front_state[p] = (its length, 0: none; the tests its last descent from
// the roots made).
TreesResult Engine::trees_of_pair(int64_t p, bool track, double scale, double travel,
                                  double margin, int64_t a, int64_t b, const double* pose,
                                  int64_t wa, int64_t wb, double pad) {
    const int64_t F = front_capacity_;
    const int64_t n_old = (track && status_[p] == 0) ? front_state_[2 * p] : 0;
    const int64_t start = p * F;
    int64_t done = 0;
    if (track)
        done = counters_[COUNT_BOX_TESTS] + counters_[COUNT_SPHERE_SKIPS] +
               counters_[COUNT_TRIANGLE_TESTS];
    const FrontRows work = {front_ + 3 * n_pairs_ * F, front_until_ + n_pairs_ * F, F};
    int64_t n_seeds = 0, n_front;
    double gap;
    if (n_old > 0) {
        const FrontScan scan = front_scan(front_ + 3 * start, front_until_ + start, n_old, pose,
                                          forest_, travel, margin, stack_, work, counters_);
        n_seeds = scan.n_seeds;
        n_front = scan.n_kept;
        gap = scan.gap;
    } else {
        for (int64_t ea = body_elem_start_[a]; ea < body_elem_end_[a]; ++ea) {
            for (int64_t eb = body_elem_start_[b]; eb < body_elem_end_[b]; ++eb) {
                int64_t* row = stack_ + 3 * n_seeds++;
                row[0] = roots_[ea];
                row[1] = roots_[eb];
                row[2] = 0;
            }
        }
        n_front = track ? 0 : -1;
        gap = INF;
    }
    const TreesResult tree =
        trees_collide(n_seeds, pose, forest_, int(header_[H_BOX_METHOD]),
                      int(header_[H_EXPANSION]), stack_, counters_, track, wa, wb, work, n_front,
                      travel - margin, pad);
    if (tree.hit) return {true, tree.ia, tree.ib, 0.0, 0};
    gap = std::min(gap, tree.gap);
    n_front = tree.n_front;
    if (n_front < 0 || gap > FRONT_GAP_REL * scale) {
        // A full check, a front too large to keep, or a pair with a clearance that can skip
        // whole steps: a front's many finer node pairs would only make it smaller.
        if (track) front_state_[2 * p] = 0;
        return {false, -1, -1, gap, 0};
    }
    done = counters_[COUNT_BOX_TESTS] + counters_[COUNT_SPHERE_SKIPS] +
           counters_[COUNT_TRIANGLE_TESTS] - done;
    if (n_old == 0) front_state_[2 * p + 1] = done;
    if (done <= front_state_[2 * p + 1]) {
        std::copy(work.pairs, work.pairs + 3 * n_front, front_ + 3 * start);
        std::copy(work.until, work.until + n_front, front_until_ + start);
        front_state_[2 * p] = n_front;
    } else {
        front_state_[2 * p] = 0;
    }
    return {false, -1, -1, gap, 0};
}

// ----------------------------------------------------------------------------- containment

// True iff point x (in element e's body frame) lies in element e's solid (closed: the
// boundary counts, as touching does). A box, sphere or cylinder is tested as the true shape,
// not its tessellation, which lies inside it (cylinders and spheres are inscribed): a point in
// the sliver between the two counts as inside, erring toward contact, as FCL's true primitives
// do. A closed mesh: a ray from x crosses its triangles an odd number of times.
bool Engine::inside_solid(int64_t e, const double* x) const {
    const double* s = elem_solid_ + SOLID_WIDTH * e;
    const int kind = int(s[0]);
    const double* R = s + 4;
    const double* t = s + 13;
    // The point in the element frame: R' (x - t).
    const double d0 = x[0] - t[0], d1 = x[1] - t[1], d2 = x[2] - t[2];
    const double p0 = R[0] * d0 + R[3] * d1 + R[6] * d2;
    const double p1 = R[1] * d0 + R[4] * d1 + R[7] * d2;
    const double p2 = R[2] * d0 + R[5] * d1 + R[8] * d2;
    switch (kind) {
        case SOLID_BOX:
            return std::fabs(p0) <= s[1] && std::fabs(p1) <= s[2] && std::fabs(p2) <= s[3];
        case SOLID_SPHERE:
            return p0 * p0 + p1 * p1 + p2 * p2 <= s[1] * s[1];
        case SOLID_CYLINDER:
            return p0 * p0 + p1 * p1 <= s[1] * s[1] && std::fabs(p2) <= s[2];
        case SOLID_CLOSED_MESH: {
            // Parity of the crossings of a ray from x (body frame: the triangles are there)
            // along a direction no robot mesh is aligned with; a crossing at an edge or vertex
            // could count twice or not at all, which this direction makes practically never
            // happen. Moeller-Trumbore, without division.
            const double u0 = 0.5773502691896258, u1 = 0.5773502691896257, u2 = 0.5773502691896259;
            const double w0 = 0.3141592653589793, w1 = -0.2718281828459045, w2 = 0.0;
            const double r0 = u0 + 1e-3 * w0, r1 = u1 + 1e-3 * w1, r2 = u2 + 1e-3 * w2;
            int64_t crossings = 0;
            for (int64_t k = elem_tris_[2 * e]; k < elem_tris_[2 * e + 1]; ++k) {
                const double* T = forest_.tris + 9 * k;
                const double e10 = T[3] - T[0], e11 = T[4] - T[1], e12 = T[5] - T[2];
                const double e20 = T[6] - T[0], e21 = T[7] - T[1], e22 = T[8] - T[2];
                const double h0 = r1 * e22 - r2 * e21, h1 = r2 * e20 - r0 * e22,
                             h2 = r0 * e21 - r1 * e20;
                double det = e10 * h0 + e11 * h1 + e12 * h2;
                if (det == 0.0) continue;  // the ray is parallel to the triangle
                const double s0 = x[0] - T[0], s1 = x[1] - T[1], s2 = x[2] - T[2];
                double u = s0 * h0 + s1 * h1 + s2 * h2;
                const double q0 = s1 * e12 - s2 * e11, q1 = s2 * e10 - s0 * e12,
                             q2 = s0 * e11 - s1 * e10;
                double v = r0 * q0 + r1 * q1 + r2 * q2;
                double dist = e20 * q0 + e21 * q1 + e22 * q2;
                if (det < 0.0) {
                    det = -det;
                    u = -u;
                    v = -v;
                    dist = -dist;
                }
                if (u >= 0.0 && v >= 0.0 && u + v <= det && dist > 0.0) ++crossings;
            }
            return crossings % 2 == 1;
        }
        default:
            return false;
    }
}

// True iff an element of one body lies in a solid element of the other (pair a, b, b at pose
// in a's frame), called once their triangles are known apart: then one vertex decides for
// the whole element (it cannot be partly inside without its surface meeting the solid's).
// Element pairs whose spheres are apart cannot contain one another and are skipped.
bool Engine::contained(int64_t a, int64_t b, const double* P) const {
    if (!body_solid_[a] && !body_solid_[b]) return false;
    for (int64_t ea = body_elem_start_[a]; ea < body_elem_end_[a]; ++ea) {
        for (int64_t eb = body_elem_start_[b]; eb < body_elem_end_[b]; ++eb) {
            const bool solid_a = elem_solid_[SOLID_WIDTH * ea] != SOLID_NONE;
            const bool solid_b = elem_solid_[SOLID_WIDTH * eb] != SOLID_NONE;
            if (!solid_a && !solid_b) continue;
            if (elem_tris_[2 * ea] == elem_tris_[2 * ea + 1] ||
                elem_tris_[2 * eb] == elem_tris_[2 * eb + 1])
                continue;  // an element without triangles
            const int64_t ra = roots_[ea], rb = roots_[eb];
            if (spheres(forest_.box(ra), forest_.box(rb), P).apart) continue;
            if (solid_a) {  // a vertex of eb, taken to body a: R_ab x + t_ab
                const double* x = forest_.tris + 9 * elem_tris_[2 * eb];
                const double y[3] = {P[0] * x[0] + P[1] * x[1] + P[2] * x[2] + P[9],
                                     P[3] * x[0] + P[4] * x[1] + P[5] * x[2] + P[10],
                                     P[6] * x[0] + P[7] * x[1] + P[8] * x[2] + P[11]};
                if (inside_solid(ea, y)) return true;
            }
            if (solid_b) {  // a vertex of ea, taken to body b: R_ab' (x - t_ab)
                const double* x = forest_.tris + 9 * elem_tris_[2 * ea];
                const double d0 = x[0] - P[9], d1 = x[1] - P[10], d2 = x[2] - P[11];
                const double y[3] = {P[0] * d0 + P[3] * d1 + P[6] * d2,
                                     P[1] * d0 + P[4] * d1 + P[7] * d2,
                                     P[2] * d0 + P[5] * d1 + P[8] * d2};
                if (inside_solid(eb, y)) return true;
            }
        }
    }
    return false;
}

// Re-check pairs todo[:n] (all pairs if full); return how many, and whether a status changed.
//
// A full check first rebuilds the volumes spanning several links and culls scene pairs with
// them; it uses nothing carried over and records no clearance. An incremental call brings the
// two bodies' poses up to date (only those) and tests first the pair's witness, the triangle
// pair that met when the pair last collided (under small motion it usually still does, which
// then costs one triangle test instead of a descent; the answer is the same either way). It
// skips the culling: a pair it re-checks is one whose own clearance ran out, and its own boxes
// give the next clearance. Then the two bodies' boxes, then each sub-group tree against each
// (sec. 4.1), or, incrementally, the pair's front; an incremental call records the clearance
// of each pair found apart, and adds the pair's travel since its last incremental re-check to
// front_travel.
int64_t Engine::recheck_pairs(int64_t n, bool full, bool* changed) {
    const bool track = !full;
    if (full) {  // a full check uses nothing carried over; fronts are recorded afresh after it
        for (int64_t p = 0; p < n_pairs_; ++p) front_state_[2 * p] = 0;
        if (n_scene_ > 0) refresh_culling();
    }
    *changed = false;
    double pose[POSE_WIDTH];
    for (int64_t t = 0; t < n; ++t) {
        const int64_t p = full ? t : todo_[t];
        const int64_t a = pair_a_[p];
        const int64_t b = pair_b_[p];
        if (track) {
            refresh_pose(a);
            refresh_pose(b);
            // The pair's travel since its last incremental re-check joins its running sum.
            // Front untils are relative to that sum, so it restarts whenever the pair has
            // no front (it then can never grow without bound, e.g. to infinity).
            resync_travel(p);
            if (front_state_[2 * p] == 0) front_travel_[p] = 0.0;
            front_travel_[p] += travel_[2 * p] + scalars_[S_EXTENSION] * travel_[2 * p + 1];
            for (int64_t j = 0; j < n_joints_; ++j) q_eval_[n_joints_ * p + j] = q_ref_[j];
        }
        bool hit = false;
        double gap = 0.0;
        if (track || !(is_scene_[b] && scene_culled_[culled_width_ * (b - n_links_) + a])) {
            write_pair_pose(a, b, pose);
            const int64_t wa = track ? witness_[2 * p] : -1;
            const int64_t wb = track ? witness_[2 * p + 1] : -1;
            const bool single = body_elem_end_[a] - body_elem_start_[a] == 1 &&
                                body_elem_end_[b] - body_elem_start_[b] == 1;
            const double pad = padding_[a] + padding_[b];
            if (wa >= 0) hit = triangle_pair_collides(forest_.tris, wa, wb, pose, pad);
            if (!hit) {
                const double* A = body_boxes_ + BOX_WIDTH * a;
                const double* B = body_boxes_ + BOX_WIDTH * b;
                // A body of one sub-group has its tree's root box as body box: the traversal
                // tests that first, so the body box is only worth testing for several trees,
                // or for a tracked pair without a front to resume (new, forced by a scene
                // change, or last found apart at body level): apart, it needs no traversal
                // and no front, its clearance is the body boxes' gap.
                const bool fresh = track && front_state_[2 * p] == 0;
                double box_gap = 0.0;
                const bool apart = fresh ? boxes_apart_gap(A, B, pose, &box_gap)
                                         : !single && boxes_apart(A, B, pose);
                if (!apart) {
                    const double margin = track ? clearance_margin(a, b, pose) : 0.0;
                    const TreesResult r = trees_of_pair(p, track, A[BOX_RADIUS] + B[BOX_RADIUS],
                                                        front_travel_[p], margin, a, b, pose,
                                                        wa, wb, pad);
                    hit = r.hit;
                    gap = r.gap;
                    if (hit) {
                        witness_[2 * p] = r.ia;
                        witness_[2 * p + 1] = r.ib;
                    } else if (contained(a, b, pose)) {
                        hit = true;  // no triangle witness: the re-check descends again
                    }
                } else if (track) {
                    gap = fresh ? box_gap : box_pair_gap(A, B, pose);
                }
                if (track && !hit) gap -= clearance_margin(a, b, pose);
            }
        }
        if (!hit) witness_[2 * p] = witness_[2 * p + 1] = -1;
        clearance_[p] = (track && !hit && gap > 0.0) ? gap : 0.0;
        if (clearance_[p] > 0.0) travel_[2 * p] = travel_[2 * p + 1] = 0.0;
        *changed |= (status_[p] != 0) != hit;
        status_[p] = hit ? 1 : 0;
    }
    return n;
}

// ----------------------------------------------------------------------------- entry points

int64_t Engine::move_world_body(int64_t b, const double* T, double max_coordinate,
                                double rotation_tolerance) {
    if (b < n_links_ || b >= n_bodies_ || !is_scene_[b]) return MOVE_REFUSED;
    for (int k = 0; k < 12; ++k)
        if (!std::isfinite(T[k])) return MOVE_REFUSED;
    const double x = T[3], y = T[7], z = T[11];
    if (std::max({std::fabs(x), std::fabs(y), std::fabs(z)}) > max_coordinate ||
        T[12] != 0.0 || T[13] != 0.0 || T[14] != 0.0 || T[15] != 1.0)
        return MOVE_REFUSED;
    const double r00 = T[0], r01 = T[1], r02 = T[2], r10 = T[4], r11 = T[5], r12 = T[6],
                 r20 = T[8], r21 = T[9], r22 = T[10];
    const double error = std::max({std::fabs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0),
                                   std::fabs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0),
                                   std::fabs(r02 * r02 + r12 * r12 + r22 * r22 - 1.0),
                                   std::fabs(r00 * r01 + r10 * r11 + r20 * r21),
                                   std::fabs(r00 * r02 + r10 * r12 + r20 * r22),
                                   std::fabs(r01 * r02 + r11 * r12 + r21 * r22)});
    const double det = r00 * (r11 * r22 - r12 * r21) - r01 * (r10 * r22 - r12 * r20) +
                       r02 * (r10 * r21 - r11 * r20);
    if (!(error <= rotation_tolerance) || det < 0.0) return MOVE_REFUSED;
    std::memcpy(T_world_body_ + 16 * b, T, 16 * sizeof(double));
    for (int64_t k = body_pairs_start_[b]; k < body_pairs_start_[b + 1]; ++k) {
        const int64_t p = body_pairs_[k];
        if (!forced_[p]) forced_list_.push_back(p);
        forced_[p] = 1;
    }
    if (header_[H_FORCED] == 0) header_[H_FORCED] = FORCED_LISTED;
    return 0;
}

int64_t Engine::query(const double* q, bool full) {
    const int64_t bad = unusable_variable(kin_, q, n_joints_);
    if (bad >= 0) return -1 - bad;
    return run(q, full);
}

// A scene change (an object added, moved or replaced) leaves pairs whose carried status,
// clearance and front describe the scene as it was: the checker sets forced[p] for each and
// H_FORCED. The next query re-checks them whatever the joints did (an incremental one from
// their roots: a front's untils and a clearance measured the old scene), then clears both.
int64_t Engine::run(const double* q, bool full) {
    full = full || header_[H_CHECKED_ONCE] == 0;
    bool any_moved = full;
    const double tolerance = scalars_[S_TOLERANCE];
    for (int64_t j = 0; j < n_joints_; ++j) {
        q_last_[j] = q[j];
        if (std::fabs(q[j] - q_ref_[j]) > tolerance) any_moved = true;
    }
    const bool forced = header_[H_FORCED] != 0;
    if (!any_moved && !forced) return 0;
    header_[H_CHECKED_ONCE] = 1;
    int64_t n;
    if (full) {
        plan_full(q_last_);
        n = n_pairs_;
        if (forced) {  // every pair is re-checked from scratch anyway
            for (int64_t p = 0; p < n_pairs_; ++p) forced_[p] = 0;
            forced_list_.clear();
            header_[H_FORCED] = 0;
        }
    } else {
        n = any_moved ? plan_update(q_last_) : 0;
        if (forced) n = add_forced(n);
        if (n == 0) return 0;
    }
    bool changed = false;
    const int64_t rechecked = recheck_pairs(n, full, &changed);
    return 2 * rechecked + (changed ? 1 : 0);
}

// Append the forced pairs not yet in todo[:n] to it, dropping their fronts; clear the flags.
// Return the new length. pending is all zero on entry and on return (plan_update's contract).
// With H_FORCED at FORCED_LISTED every forced pair is in forced_list_: only those are visited.
int64_t Engine::add_forced(int64_t n) {
    for (int64_t t = 0; t < n; ++t) pending_[todo_[t]] = 1;
    const bool listed = header_[H_FORCED] == FORCED_LISTED;
    const int64_t count = listed ? int64_t(forced_list_.size()) : n_pairs_;
    for (int64_t k = 0; k < count; ++k) {
        const int64_t p = listed ? forced_list_[k] : k;
        if (!forced_[p]) continue;
        forced_[p] = 0;
        front_state_[2 * p] = 0;
        if (motion_record_) motion_.prev_gap[p] = -INF;  // no gap known in the new scene
        if (!pending_[p]) {
            pending_[p] = 1;
            todo_[n++] = p;
        }
    }
    for (int64_t t = 0; t < n; ++t) pending_[todo_[t]] = 0;
    forced_list_.clear();
    header_[H_FORCED] = 0;
    return n;
}

int64_t Engine::batch(const double* Q, int64_t n, bool full, uint8_t* statuses, int64_t* codes) {
    for (int64_t i = 0; i < n; ++i) {  // all rows first: a bad row changes nothing at all
        const int64_t bad = unusable_variable(kin_, Q + n_joints_ * i, n_joints_);
        if (bad >= 0) return -1 - (n_joints_ * i + bad);
    }
    for (int64_t i = 0; i < n; ++i) {
        codes[i] = run(Q + n_joints_ * i, full);
        for (int64_t p = 0; p < n_pairs_; ++p) statuses[n_pairs_ * i + p] = uint8_t(status_[p]);
    }
    return n;
}

}  // namespace collision_sensor
