// Certified motion checks: is any configuration along a joint-space path in contact?
//
// The paper's verdicts are about one instant. A motion between two clear states can pass
// through an object; sampling it at a fixed resolution can miss a thin one. Here a path is
// proven free, never sampled: with d(t) a lower bound of a pair's padded distance at the
// state q(t) and D(s, t) a bound of how far any point of either body can move relative to the
// other between q(s) and q(t), the pair stays apart on [m - h, m + h] as long as
//     d(m) > D(m, m - h)  and  d(m) > D(m, m + h)
// (Schwarzer, Saha & Latombe 2005, "Adaptive dynamic collision checking for single and
// multiple articulated robots in complex environments", with the engine's traversal as the
// distance bound). d(m) > r is decided by the traversal itself: both bodies' boxes grown by
// r / 2 (a box grown by r / 2 along its axes holds every point within r / 2 of it, so grown
// boxes apart mean the boxes are more than r apart) and leaves tested "triangles within
// padding + r". Nothing is approximated; the answer is exact up to the touching tolerance.
//
// Bounds of the motion (motion_coefficients): a joint k on the tree path between the pair's
// two bodies moves the body on its side. Per unit of its value a revolute joint moves a point
// of body x below it by at most its lever: the joint offsets |t_parent_joint| from k down to
// x, plus the largest extension of the prismatic joints (and the translation of planar and
// floating joints) between them along the path, plus x's reach (|box centre| + radius); a
// prismatic joint, or a planar or floating joint's translation, by 1; a floating joint's
// rotation by its angle (slerp: constant angular speed about a fixed axis) times the lever.
// Summed over the joints each variable drives (|multiplier|: mimic joints follow), this is
// c[p, j], and D(s, t) = sum_j c[p, j] var_j(s, t) with var_j the variable's total variation
// between s and t. Joints above the two bodies' common ancestor move both alike: skipped.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "context.hpp"
#include "model.hpp"
#include "motion_bounds.hpp"
#include "motion_paths.hpp"

namespace collision_sensor {

// A pair's march (motion.cpp: march_step) sizes its next interval from the half-width over which
// it was last proven apart, times a factor that grows by MARCH_GROW after each interval
// proven (up to MARCH_FACTOR_MAX) and shrinks by MARCH_SHRINK after each that was not (down
// to MARCH_FACTOR_MIN). Only the work depends on them, never the answer: larger steps cost
// fewer intervals where a pair is far from everything, and more retries near contact; a pair
// that keeps a front (pair_within) pays little for a larger interval.
constexpr double MARCH_GROW = 1.5, MARCH_FACTOR_MAX = 3.0, MARCH_SHRINK = 0.5,
                 MARCH_FACTOR_MIN = 0.75;
// A pair's test starts from the node pairs where its last descent stopped (its front) while
// that front has at most this many node pairs and starting there costs no more node pairs
// than its last descent from the roots did (motion.cpp: pair_within). Work only, never answers.
constexpr int64_t MOTION_FRONT_MAX = 1024;
// A pair whose bodies only translate relative to each other along a straight motion, both
// made of convex elements (a primitive, or a convex closed mesh), is swept by ray casts
// (convex_sweep.hpp) instead of marched, up to this many element pairs; the cast stops within
// SWEEP_EPS (tolerances.hpp) of contact.
constexpr int64_t SWEEP_MAX_ELEMENT_PAIRS = 16;
// update_motion: a pair apart at both ends of a step whose gaps there do not exceed the step's
// bound has its distance at q1 measured before it marches (check_step_motion): the
// incremental query's clearance is where its descent stopped, often far below the pair's
// distance for a link hovering near an obstacle, so that the pair would march at every step.
// The search is capped at MOTION_MEASURE_AHEAD times what the proof needs: above what it
// needs, the pair is apart all along, and the distance, carried as its clearance, lets the
// planning skip the pair for the steps to come. A search near a cap that is a sizeable part of
// the bodies descends most of both trees (a slow stream's long steps), so a pair is measured
// only while the cap is at most MOTION_MEASURE_SCALE times its two body radii summed; and only
// a pair that keeps no front: its march starts from the front, whose node pairs the step's
// bound mostly proves already, for less than a search costs. Work only, never answers.
constexpr double MOTION_MEASURE_AHEAD = 4.0, MOTION_MEASURE_SCALE = 0.05;

// The motion queries' own work areas (a Scratch's counterparts), sized from the model on
// first use (size_for). Per link: its pose at the evaluated state (T, valid where stamp ==
// tag) and its joint's speeds along the path; per side of the pair at hand, its moving
// joints; per pair, its march and its front; per node and side, MotionMargin's cache.
struct MotionWork {
    // A pair's march along a path (march_step): proven apart on [0, t).
    struct March {
        int64_t p;
        double t, length, factor;
    };
    std::vector<double> delta, var, quat0;  // (J,) StraightPath's
    // PolylinePath's: its segments' arrays (S, J), and per segment and link the joint's
    // trans, rot and signed speed (S, L, 3) as straight_speeds gives them.
    std::vector<double> poly_delta, poly_var, poly_quat0, poly_speeds;
    // Each variable's variation summed over the segments before each waypoint (S + 1, J):
    // how far a pair's bodies can move between two parameters is their difference, weighed
    // by its reach rows (MotionQuery::measure).
    std::vector<double> poly_cum;
    std::vector<double> pair_rates;  // (J,) measure_pair's pair's reach rows, weighed by E
    int64_t rates_pair = -1;
    // Every link's pose at each waypoint, computed on first use (poly_posed): the crude bound
    // at a waypoint (MotionQuery::waypoint_leap) then costs no kinematics.
    std::vector<double> poly_T;        // (S + 1, L, 16)
    std::vector<uint8_t> poly_posed;   // (S + 1,)
    // The speeds in trans, rot, speed hold along the whole interval at hand as one straight
    // motion's (first-order bounds valid); false when it spans segments of a polyline.
    bool first_order = true;
    std::vector<double> q, q_prev, q_next;  // (J,) the state evaluated; update_motion's start
    bool evaluated = false;                 // q holds a state (T follows it where stamped)
    std::vector<double> crude;              // (P,) each pair's crude rate (-1: not yet)
    double extension_max = 0.0;             // E's bound along a straight path
    std::vector<double> T;                  // (L, 16)
    std::vector<double> turn;               // (L, 3) set_link_pose's cosines (kinematics.hpp)
    std::vector<int64_t> stamp, chain;      // (L,)
    int64_t tag = 0;
    std::vector<double> trans, rot, speed, accel;  // (L,) each link's joint's speeds
    std::vector<uint8_t> moving;                   // (L,) its joint moves on the path
    std::vector<int64_t> depth;                    // (L,) links above each
    int64_t side_n[2] = {0, 0};
    std::vector<int64_t> side_link[2];
    std::vector<double> side_trans[2], side_rot[2], side_speed[2], side_accel[2],
        side_above[2], side_origin[2], side_axis[2];
    std::vector<BoxMotion> node_motion[2];  // (N,)
    std::vector<int64_t> node_stamp[2];     // (N,)
    MotionMargin margin{};
    std::vector<March> heap;
    // The pairs swept (MotionQuery::sweep) by the query at hand, each one's first contact
    // (INF: none) and how far its bodies translate relative to each other; NaN for the others.
    std::vector<int64_t> swept;
    std::vector<double> swept_at, swept_span;
    // The pairs the query at hand sweeps, and each one's pose at the start and translation
    // (POSE_WIDTH + 3 each).
    std::vector<int64_t> sweeping;
    std::vector<double> sweep_poses;
    // Each element's hull (model.hpp: element_hull), built on first need: hull_state[e] -1
    // not asked yet, 0 none, 1 hulls[e]; body_hull_state[b] likewise, 1 when every element
    // of body b has one.
    std::vector<Hull> hulls;
    std::vector<int8_t> hull_state, body_hull_state;
    std::vector<std::vector<int64_t>> front;  // (P,) each pair's front (pair_within)
    // (P,) per node pair of the front, the parameter up to which it is proven apart in the
    // query at hand (-INF: not known; empty while the front was set from elsewhere, but for
    // update_motion's, which check_step_motion sets from the carried front's untils).
    std::vector<std::vector<double>> front_until;
    // (P,) along a polyline, the same in the pair's measure (MotionQuery::measure): each node
    // pair is apart while the measure stays below this (-INF: not known).
    std::vector<std::vector<double>> front_measure;
    std::vector<double> recorded_reach, kept_until, recorded_gap, kept_measure;
    std::vector<int64_t> front_cost;          // (P,) its last descent's node pairs
    std::vector<int64_t> recorded, stack, marched;
    std::vector<double> prev_gap, prev_sums;  // (P,), (P, 2): update_motion's MotionRecord
    // update_motion's march (check_step_motion): start_apart[p] = 1 for a pair the carried
    // state has apart at the start, whose front it set from the carried state's; read while
    // start_known.
    std::vector<uint8_t> start_apart;
    bool start_known = false;
    // update_motion: pairs check_step_motion measured at q1 (MOTION_MEASURE_AHEAD), each with
    // its distance there (a clearance, rounding taken off), for the engine to carry.
    std::vector<int64_t> measured;
    std::vector<double> measured_gap;
    bool sized = false;

    void size_for(const Model& m);
    MotionRecord record() { return {prev_gap.data(), prev_sums.data()}; }
};

// What a motion query runs in: the engine's model and carried state (read only: the world
// objects' poses), its options, a Scratch (its counters) and the motion's own areas.
struct MotionContext {
    EngineView view;
    Scratch& scratch;
    MotionWork& work;
};

// Is any state of the straight motion q0 -> q1 (both usable) in contact? 0: none (proven); 1:
// yes, *t its first contact's fraction of the motion (the state there in contact or within
// MOTION_TOUCH_TOLERANCE of it, no earlier state in contact), pairs[p] = 1 for the pairs in
// contact (or within the tolerance) there, 0 for the others. Only the pairs list[:n] are
// looked at (list null: every pair).
int64_t check_straight_motion(MotionContext& c, const double* q0, const double* q1,
                              const int64_t* list, int64_t n, double* t, uint8_t* pairs);

// The same for the straight motions through the waypoints Q (n rows, n >= 2) in turn, as one
// path (PolylinePath): *t in [0, n - 1], segment floor(t) (a contact at waypoint k > 0 is the
// end of segment k - 1: t = k), every pair.
int64_t check_polyline_motion(MotionContext& c, const double* Q, int64_t n, double* t,
                              uint8_t* pairs);

// The same for one spline segment (coef: (J, 6), SplinePath; its ends usable, its planar and
// floating variables constant), every pair.
int64_t check_spline_motion(MotionContext& c, const double* coef, double* t, uint8_t* pairs);

// update_motion's certificate for the step q0 -> q1 once the incremental query took the state
// to q1 (engine.cpp: Engine::update_motion, which states the proof): of the pairs it
// re-checked (rechecked[:n]), those apart at q1 whose gaps at the two ends (the record's, and
// their new clearance) exceed the step's bound are apart all along; the others march
// (check_straight_motion). extension_before: E at q0.
int64_t check_step_motion(MotionContext& c, const double* q0, const double* q1,
                          const int64_t* rechecked, int64_t n, double extension_before,
                          double* t, uint8_t* pairs);

}  // namespace collision_sensor
