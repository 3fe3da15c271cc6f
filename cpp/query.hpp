// One collision query over the whole robot and scene (paper sec. 2, 4.1, 4.2).
//
// A query takes joint positions and:
// 1. decides which joint variables moved (by more than the motion tolerance) since the state
//    the carried statuses describe, and takes their new values into that state (plan_update;
//    plan_full takes them all);
// 2. lists only the pairs whose relative pose can have changed: those with a moved joint on
//    the tree path between their two bodies (sec. 4.2), minus those whose recorded clearance
//    the motion cannot have closed; every other pair keeps its status;
// 3. re-checks the listed pairs (recheck_pairs): (full checks) culling with the volumes
//    spanning several links (scene pairs), (incremental calls) the pair's last meeting
//    triangle pair, then the two bodies' boxes, then each sub-group tree against each (sec.
//    4.1, trees_collide); an incremental call starts a pair in near contact from its front.
//
// Poses follow the joints lazily: a moved joint marks the links below it stale, and a link's
// world pose is recomputed only when a pair being re-checked needs it, or when Python asks
// for the poses. Full checks rebuild the volumes spanning several links (for each link a
// world box around its subtree's link boxes, the root's being the robot's root volume, from
// the link boxes, never from geometry: sec. 2.2) and cull scene pairs with them first.
//
// Bodies are the engine's links (FK order, parents first, world == root link frame): the
// robot's links, then the objects attached to them (each a link on a fixed joint below its
// robot link, whose T_parent_joint is the object's pose in that link's frame), followed by
// the world objects. A query never moves a world object; the checker does, between queries
// (collision_sensor/engine/dynamic_scene.py), and then lists the pairs that must be re-checked
// whatever the joints did in `forced` (see run). A body may be padded (padding[b], metres: its
// geometry grown by a swept sphere, MoveIt's link padding): its boxes then hold the padded
// geometry (the checker grows them), the leaf test of a pair is "triangles within the two
// paddings' sum" (traversal.hpp: triangles_within), and every clearance is one of the padded
// distance, which moves exactly as the unpadded one does, so the travel bounds hold as they are.
//
// All state, the model's arrays and the carried statuses alike, lives in two flat buffers
// that the Python checker packs (collision_sensor/array_pack.py): doubles F and int64 I, with
// a layout table in I's header naming each array's offset and shape. The engine reads them in
// place, so the Python side can inspect any of them as a numpy view, and a query allocates
// nothing.
#pragma once

#include <cstdint>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "distance.hpp"
#include "kinematics.hpp"
#include "motion.hpp"
#include "traversal.hpp"

namespace collision_sensor {

// The packed arrays, in the order of their slots in the layout tables (the Python side packs
// them in this order: it reads these lists from the binding).
#define CS_FLOAT_SLOTS(X)                                                                     \
    X(scalars) X(q_last) X(q_ref) X(T_parent_joint) X(axis) X(multiplier) X(offset)           \
    X(T_world_body) X(body_boxes) X(boxes) X(volume) X(gain) X(tris) X(elem_solid)            \
    X(subtree_boxes) X(padding)                                                               \
    X(clearance) X(q_eval) X(reach) X(reach_ext) X(travel) X(front_until) X(front_travel)
#define CS_INT_SLOTS(X)                                                                       \
    X(header) X(parent) X(joint_type) X(q_index) X(is_scene) X(body_elem_start)              \
    X(body_elem_end) X(roots) X(nodes) X(pair_a) X(pair_b) X(joint_pairs_start)              \
    X(joint_pairs) X(joint_links_start) X(joint_links) X(joint_prismatic) X(status) X(witness) \
    X(moved) X(stale) X(chain) X(pending) X(todo) X(scene_culled) X(stack) X(counters)        \
    X(front) X(front_state) X(nearest) X(forced)

#define CS_SLOT_ENUM(name) name,
enum FloatSlot : int { CS_FLOAT_SLOTS(CS_SLOT_ENUM) N_FLOAT_SLOTS };
enum IntSlot : int { CS_INT_SLOTS(CS_SLOT_ENUM) N_INT_SLOTS };
#undef CS_SLOT_ENUM

// scalars[S_*]; header[H_*], then the float layout (N_FLOAT_SLOTS, LAYOUT_WIDTH), then the
// int layout. layout[k] = (offset, size, d0, d1, d2).
constexpr int S_TOLERANCE = 0, S_EXTENSION = 1, N_SCALARS = 2;
// H_FORCED: nonzero when some forced[p] is set (the checker sets both after a scene change);
// FORCED_LISTED when only Engine::move_world_body set them (it lists the pairs it forces).
constexpr int H_N_LINKS = 0, H_BOX_METHOD = 1, H_EXPANSION = 2, H_CHECKED_ONCE = 3,
              H_RESYNC_COUNTDOWN = 4, H_FORCED = 5, H_LAYOUTS = 6;
constexpr int64_t FORCED_LISTED = 2;
//: Engine::move_world_body's answer when it changed nothing.
constexpr int64_t MOVE_REFUSED = -1;
constexpr int LAYOUT_WIDTH = 5;
constexpr int H_I_LAYOUT = H_LAYOUTS + N_FLOAT_SLOTS * LAYOUT_WIDTH;
constexpr int HEADER_SIZE = H_I_LAYOUT + N_INT_SLOTS * LAYOUT_WIDTH;

// elem_solid[e] (one row per sub-group tree, in roots order): what element e fills besides its
// surface, in its body's frame: kind, size (3), R (3, 3, row-major), t (3). Primitives are solid
// (box: half extents; sphere: radius; cylinder along z: radius, half length); a closed mesh is
// with the checker's mesh_containment. Something wholly inside a solid collides with it though
// no triangles meet (FCL's rule for primitives); a surface mesh contains nothing.
constexpr int SOLID_NONE = 0, SOLID_BOX = 1, SOLID_SPHERE = 2, SOLID_CYLINDER = 3,
              SOLID_CLOSED_MESH = 4, SOLID_WIDTH = 16;

// A pair's clearance is rounded down by this fraction of the pair's coordinate scale (its
// body boxes' reach plus their distance): it covers the triangle test's contact tolerance,
// boxes that hold their triangles only up to rounding, and the rounding of the gaps and FK.
constexpr double CLEARANCE_EPS_REL = 1e-9;
// A skipped pair's running travel sum is replaced by the exact sum once it reaches this
// fraction of the pair's clearance (see plan_update) ...
constexpr double TRAVEL_GUARD = 1.0 - 1e-6;
// ... and every tracked pair's, at least once in this many incremental calls.
constexpr int64_t TRAVEL_RESYNC_CALLS = int64_t(1) << 24;
// A pair keeps a front only while its clearance is at most this fraction of its size.
constexpr double FRONT_GAP_REL = 1e-3;

// Number of rows of every front (FRONT_POOL_ROWS over the pairs, clipped) is chosen by the
// checker; these bounds are the checker's (exported for it).
constexpr int64_t FRONT_POOL_ROWS = int64_t(1) << 16;
constexpr int64_t FRONT_ROWS_MIN = 64, FRONT_ROWS_MAX = 1024;

// Slot names, for the binding.
extern const char* const FLOAT_SLOT_NAMES[N_FLOAT_SLOTS];
extern const char* const INT_SLOT_NAMES[N_INT_SLOTS];

// The checker's buffers, cut into named arrays once (the layout never changes after packing).
class Engine {
   public:
    // Validate the layout against the buffers' sizes and the shapes the engine reads; throws
    // std::invalid_argument naming the array at fault.
    Engine(double* F, int64_t f_size, int64_t* I, int64_t i_size);

    // Validate q (J values), copy it to q_last, bring the statuses up to date with it: a full
    // check re-checks every pair, an incremental one only what the motion can have changed.
    // The first call always checks in full. Returns 2 * rechecked + changed, or -1 - j when
    // q[j] is not usable (kinematics.hpp: unusable_variable; nothing changed then).
    int64_t query(const double* q, bool full);
    // query() on each row of Q (n, J) in turn; statuses (n, P) uint8 and codes (n,) out.
    // Returns n, or -1 - (J i + j) when row i's value j is not usable: every row is validated
    // before any is run, so nothing changed then.
    int64_t batch(const double* Q, int64_t n, bool full, uint8_t* statuses, int64_t* codes);
    // Bring every link pose up to date (incremental calls compute them only on demand).
    void refresh_all_poses();
    // distance.cpp: query(q, false), then each pair's padded distance and nearest points
    // (world frame) into distance (P,) (INF when not below max_distance; <= 0 when in
    // contact) and points (P, 6) (on body pair_a, on body pair_b). Returns query()'s code.
    int64_t proximity(const double* q, double max_distance, double* distance, double* points);
    // Give body b, an object fixed in the world, the pose T (4, 4, row-major) and force its
    // pairs (see run), if T is a rigid transform: finite, its position within max_coordinate
    // of the origin on each axis, last row (0, 0, 0, 1), |R^T R - I| <= rotation_tolerance
    // entrywise and det R >= 0 (dynamic_scene.py: checked_pose, the same arithmetic). Returns
    // 0, or MOVE_REFUSED when b is no such body or T no such transform (nothing changed then).
    int64_t move_world_body(int64_t b, const double* T, double max_coordinate,
                            double rotation_tolerance);

    // motion.cpp. How each variable moves along a straight motion (MOTION_*), (J,).
    void set_motion_kinds(const int64_t* kinds);
    // The straight motion q0 -> q1 (motion.hpp), proven free or its first contact found,
    // without touching the carried state. Returns 0 (free), 1 (contact: *t its fraction of
    // the motion, pairs[p] = 1 for the pairs in contact, or within MOTION_TOUCH_TOLERANCE,
    // there, else 0), or -1 - j when q0[j] (j < J) or q1[j - J] is not usable.
    int64_t motion(const double* q0, const double* q1, double* t, uint8_t* pairs);
    // The motion from the carried state (the last query's q; none before the first: q itself)
    // to q, then query(q, false), whose code goes to *query_code. Returns motion()'s code
    // (q unusable: nothing changed).
    int64_t update_motion(const double* q, double* t, uint8_t* pairs, int64_t* query_code);
    // The straight motions Q[0] -> Q[1] -> ... -> Q[n - 1] in turn until one is not free:
    // *segment its index (-1: all free), *t and pairs as motion(). Returns 0, 1, or -1 -
    // (J i + j) when Q[i][j] is not usable (every row is validated first).
    int64_t path(const double* Q, int64_t n, int64_t* segment, double* t, uint8_t* pairs);
    // The spline segments coef (n, J, 6) (motion.hpp: SplinePath, each over t in [0, 1]) in
    // turn until one is not free: as path(). Returns -1 - i when segment i has a coefficient
    // that is not finite, moves a planar or floating joint, or starts or ends at an unusable
    // value (every segment is validated first).
    int64_t spline(const double* coef, int64_t n, int64_t* segment, double* t, uint8_t* pairs);

    int64_t n_joints() const { return n_joints_; }
    int64_t n_pairs() const { return n_pairs_; }
    std::mutex& lock() { return lock_; }

   private:
    int64_t run(const double* q, bool full);
    struct Shape {
        int64_t size, d0, d1, d2;
    };
    void check_shape(const char* name, const Shape& s, int64_t d0, int64_t d1, int64_t d2) const;
    int64_t plan_update(const double* q);
    int64_t add_forced(int64_t n);
    void plan_full(const double* q);
    int64_t recheck_pairs(int64_t n, bool full, bool* changed);
    void refresh_pose(int64_t i);
    void refresh_culling();
    void subtree_volumes();
    bool scene_body_outside(int64_t s, int64_t k);
    bool same_volume(int64_t k, int64_t p) const;
    double extension() const;
    void resync_travel(int64_t p);
    void add_travel(int64_t p, int64_t j, double old_value, double new_value);
    bool needs_recheck(int64_t p, double extension);
    double clearance_margin(int64_t a, int64_t b, const double* pose) const;
    void write_pair_pose(int64_t a, int64_t b, double* pose) const;
    bool boxes_apart(const double* A, const double* B, const double* P) const;
    bool boxes_apart_gap(const double* A, const double* B, const double* P, double* gap) const;
    bool contained(int64_t a, int64_t b, const double* pose) const;
    bool inside_solid(int64_t e, const double* x) const;
    bool contained_vertex(int64_t a, int64_t b, const double* pose, double* x) const;
    void seed_nearest(int64_t ia, int64_t ib, const double* pose, double pad,
                      NearestPoints& best) const;
    void write_nearest_points(int64_t a, double pad_a, double pad_b, const NearestPoints& best,
                              double* row) const;
    TreesResult trees_of_pair(int64_t p, bool track, double scale, double travel, double margin,
                              int64_t a, int64_t b, const double* pose, int64_t wa, int64_t wb,
                              double pad);

    // motion.cpp: a pair's march along a path (march_step).
    struct PairMarch {
        int64_t p;
        double t, length, factor;
    };
    // motion.cpp: the work of the motion queries, sized on their first call.
    struct MotionWork {
        std::vector<int64_t> kind;              // (J,) MOTION_*
        std::vector<double> delta, var, quat0;  // (J,) StraightPath's
        std::vector<double> q;                  // (J,) the state being evaluated
        std::vector<double> T;                  // (L, 16) link poses at q
        std::vector<int64_t> stamp, chain;      // (L,) T[i] is current when stamp[i] == tag
        int64_t tag = 0;
        std::vector<double> trans, rot, speed, accel;  // (L,) each link's joint's speeds
        std::vector<uint8_t> moving;            // (L,) its joint moves somewhere on the path
        std::vector<int64_t> depth;             // (L,) links above each
        // The two sides of the pair at hand (motion_sides, motion_margin).
        int64_t side_n[2] = {0, 0};
        std::vector<int64_t> side_link[2];
        std::vector<double> side_trans[2], side_rot[2], side_origin[2], side_axis[2];
        std::vector<double> side_speed[2], side_above[2], side_accel[2];
        std::vector<BoxMotion> node_motion[2];  // (N,) MotionMargin's caches
        std::vector<int64_t> node_stamp[2];
        MotionMargin margin{};
        std::vector<double> q_prev;             // (J,) update_motion's start
        std::vector<PairMarch> heap;            // the pairs' marches (straight_motion)
        std::vector<double> prev_gap, prev_sums;  // (P,), (P, 2) update_motion: record_gap's
        std::vector<int64_t> marched;           // the pairs update_motion marches
    };
    MotionWork motion_;
    // While true, plan_update and add_forced record each pair's gap at the last state
    // (record_gap) before moving its travel sums: update_motion's.
    bool motion_record_ = false;
    void record_gap(int64_t p, double extension);
    bool motion_skip(int64_t p, double extension_before, double extension) const;
    template <class Path>
    int64_t march_pairs(const int64_t* list, int64_t n, const Path& path, const double* q0,
                        double* best);
    void straight_speeds(const double* q0, const double* q1);
    void motion_prepare();
    void motion_evaluate(const double* q);
    void motion_link_pose(int64_t i);
    void motion_pair_pose(int64_t a, int64_t b, double* pose);
    bool motion_sides(int64_t p);
    void motion_margin(int64_t p, double h2);
    WithinResult pair_within(int64_t p, const double* pose, double h, double extra = 0.0);
    double solid_gap(int64_t a, int64_t b, const double* pose) const;
    static constexpr int MARCH_ON = 0, MARCH_FREE = 1, MARCH_CONTACT = 2;
    template <class Path>
    int march_step(PairMarch& s, const Path& path, double t_end);
    void path_speeds(const StraightPath&, double, double) {}  // constant: straight_speeds
    void path_speeds(const SplinePath& path, double t, double h2);
    void spline_moving(const SplinePath& path);
    int64_t straight_motion(const double* q0, const double* q1, double* t, uint8_t* pairs);
    template <class Path>
    int64_t motion_marched(const int64_t* list, int64_t n, const Path& path, const double* q0,
                           double* t, uint8_t* pairs);
    template <class Path>
    void motion_contacts(const int64_t* list, int64_t n, const Path& path, double t,
                         uint8_t* pairs);

    std::mutex lock_;
    int64_t* header_;
    double* scalars_;
    int64_t n_links_, n_bodies_, n_joints_, n_pairs_, n_scene_, culled_width_;
    int64_t stack_rows_, front_capacity_, n_tris_, n_nodes_;
    KinematicTree kin_;
    Forest forest_;
    const double* elem_solid_;
    std::vector<uint8_t> body_solid_;  // 1 where a body has a solid element
    std::vector<int64_t> elem_tris_;   // (E, 2): each tree's triangle range (its leaves')
    std::vector<double> body_reach_;   // |body box centre| + its radius, per body
    // body_pairs_[body_pairs_start_[b]:body_pairs_start_[b + 1]]: the pairs whose body b is b.
    std::vector<int64_t> body_pairs_start_, body_pairs_;
    std::vector<int64_t> forced_list_;  // the pairs move_world_body forced (see H_FORCED)
    // distance.cpp's work rows (distance.hpp: DistanceWork), sized on the first proximity call.
    std::vector<double> placed_rows_, support_rows_;
    std::vector<int64_t> placed_stamp_, support_stamp_;
    int64_t placed_tag_ = 0, support_tag_ = 0;
    double *q_last_, *q_ref_, *T_world_body_, *body_boxes_, *subtree_boxes_, *padding_,
        *clearance_, *q_eval_, *reach_, *reach_ext_, *travel_, *front_until_, *front_travel_;
    int64_t *is_scene_, *body_elem_start_, *body_elem_end_, *roots_, *pair_a_, *pair_b_,
        *joint_pairs_start_, *joint_pairs_, *joint_links_start_, *joint_links_,
        *joint_prismatic_, *status_, *witness_, *moved_, *stale_, *chain_, *pending_, *todo_,
        *scene_culled_, *stack_, *counters_, *front_, *front_state_, *nearest_, *forced_;
};

}  // namespace collision_sensor
