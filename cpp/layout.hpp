// The layout of the engine's packed arrays: the one source of truth of the Python/C++ boundary.
//
// The checker packs the arrays the engine reads into two flat buffers, float64 F and int64 I
// (collision_sensor/engine/array_pack.py), one slot per array in the order of the tables
// below, each with its layout row (offset, size, d0, d1, d2). Each slot is named, belongs to
// a group, and has its shape written in the model's dimensions (DIM_*) and constants. The
// binding exports the tables (engine.FLOAT_SLOTS, engine.INT_SLOTS: (name, group, shape)),
// the checker builds its arrays by them, and the engine checks every slot against them when
// it is made (resolve_layout): nothing about the boundary is written twice.
//
// Groups (what the checker does with a slot when the scene changes, and the engine with it):
//   model  what a query reads and never writes: the robot, the scene and the pairs (the
//          engine's scene methods change some rows between queries: engine.hpp);
//   state  the carried incremental state: what one query leaves for the next (carried over
//          a scene change by the checker, pair by pair);
//   work   what the engine's own context works in and the checker may read: counters, the
//          culling verdicts of the last full check, the proximity query's warm start (fresh
//          after a scene change).
// The engine's other work areas (stack, re-check lists, fronts, distance rows) are its own
// (context.hpp: Scratch, Fronts), sized from the model: they never cross the binding.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

#include "box_test.hpp"
#include "descent.hpp"

namespace collision_sensor {

// The model's dimensions, by which the slots' shapes are written.
enum Dim : int {
    DIM_LINKS,          // the engine's links: the robot's, then the attached objects
    DIM_BODIES,         // the links, then the world objects
    DIM_WORLD_OBJECTS,  // bodies - links
    DIM_JOINTS,         // joint variables (q)
    DIM_PAIRS,          // checked pairs
    DIM_NODES,          // OBB tree nodes, every tree's
    DIM_TRIANGLES,      // triangles, every tree's
    DIM_ELEMENTS,       // trees (the paper's sub-groups): the robot's elements, then objects
    DIM_JOINT_PAIRS,    // entries of the variable -> pairs lists
    DIM_JOINT_LINKS,    // entries of the variable -> links lists
    N_DIMS,
    DIM_NONE = -1
};
// Their names in the exported shapes ("links", "joints+1", ...).
extern const char* const DIM_NAMES[N_DIMS];

enum Group : int { GROUP_MODEL, GROUP_STATE, GROUP_WORK, N_GROUPS };
extern const char* const GROUP_NAMES[N_GROUPS];

// One extent of a shape: a dimension plus a constant, or (DIM_NONE) the constant alone.
struct Extent {
    int dim;
    int64_t plus;
    constexpr Extent(Dim d) : dim(d), plus(0) {}
    constexpr Extent(int n) : dim(DIM_NONE), plus(n) {}
    constexpr Extent(Dim d, int64_t n) : dim(d), plus(n) {}
};
constexpr Extent plus_one(Dim d) { return Extent(d, 1); }

struct Shape {
    int ndim;
    Extent extent[3];
};
constexpr Shape shape(Extent a) { return {1, {a, Extent(1), Extent(1)}}; }
constexpr Shape shape(Extent a, Extent b) { return {2, {a, b, Extent(1)}}; }
constexpr Shape shape(Extent a, Extent b, Extent c) { return {3, {a, b, c}}; }

// query_flags[QUERY_*]: the state's counts that are not arrays.
constexpr int QUERY_CHECKED_ONCE = 0;   // 1 once a full check has run (the first always is)
constexpr int QUERY_CALLS = 1;          // incremental calls since the travel sums' last resync
constexpr int N_QUERY_FLAGS = 2;

// elem_solid[e] (one row per tree, in roots order): what element e fills besides its surface,
// in its body's frame: kind, size (3), R (3, 3, row-major), t (3). Primitives are solid (box:
// half extents; sphere: radius; cylinder along z: radius, half length); a closed mesh is with
// the checker's mesh_containment. Something wholly inside a solid collides with it though no
// triangles meet (FCL's rule for primitives); a surface mesh contains nothing
// (containment.hpp). Columns SOLID_PROBE .. + 2 of every row (solid or not): the element's
// test vertex, its mesh's first vertex (faces[0][0]) in its body's frame, the one that decides
// whether it lies in a solid of another body; never the first of the tree's order, which
// moves with how the tree is split.
constexpr int SOLID_NONE = 0, SOLID_BOX = 1, SOLID_SPHERE = 2, SOLID_CYLINDER = 3,
              SOLID_CLOSED_MESH = 4, SOLID_PROBE = 16, SOLID_WIDTH = 19;

// The float64 slots (buffer F): name, group, shape.
#define CS_FLOAT_SLOTS(X)                                                                     \
    X(T_parent_joint, MODEL, shape(DIM_LINKS, 4, 4))  /* joint origins (kinematics.hpp) */  \
    X(axis, MODEL, shape(DIM_LINKS, 3))               /* joint axes */                      \
    X(multiplier, MODEL, shape(DIM_LINKS))            /* value = multiplier q + offset */   \
    X(offset, MODEL, shape(DIM_LINKS))                                                      \
    X(body_boxes, MODEL, shape(DIM_BODIES, BOX_WIDTH))  /* each body's box (padded) */      \
    X(padding, MODEL, shape(DIM_BODIES))                /* each body's padding, m */        \
    X(boxes, MODEL, shape(DIM_NODES, BOX_WIDTH))        /* every tree node's box */         \
    X(volume, MODEL, shape(DIM_NODES))                  /* box volumes (EXPAND_LARGER) */   \
    X(gain, MODEL, shape(DIM_NODES))                    /* EXPAND_PROMISING's score */      \
    X(tris, MODEL, shape(DIM_TRIANGLES, 3, 3))          /* triangles, body frames */        \
    X(elem_solid, MODEL, shape(DIM_ELEMENTS, SOLID_WIDTH))                                  \
    X(reach, MODEL, shape(DIM_PAIRS, DIM_JOINTS))       /* planning.hpp: travel bounds */   \
    X(reach_ext, MODEL, shape(DIM_PAIRS, DIM_JOINTS))                                       \
    X(q_last, STATE, shape(DIM_JOINTS))                 /* the last call's q */             \
    X(q_ref, STATE, shape(DIM_JOINTS))                  /* the q the statuses describe */   \
    X(extension, STATE, shape(1))                       /* E at q_ref (planning.hpp) */     \
    X(T_world_body, STATE, shape(DIM_BODIES, 4, 4))     /* poses (world objects': model) */ \
    X(clearance, STATE, shape(DIM_PAIRS))               /* lower bound of the distance */   \
    X(q_eval, STATE, shape(DIM_PAIRS, DIM_JOINTS))      /* q at the pair's last re-check */ \
    X(travel, STATE, shape(DIM_PAIRS, 2))               /* running travel sums */

// The int64 slots (buffer I): name, group, shape.
#define CS_INT_SLOTS(X)                                                                       \
    X(parent, MODEL, shape(DIM_LINKS))                  /* parent link, -1 for the root */  \
    X(joint_type, MODEL, shape(DIM_LINKS))              /* JOINT_* */                       \
    X(q_index, MODEL, shape(DIM_LINKS))                 /* driving variable, -1: fixed */   \
    X(body_elem_start, MODEL, shape(DIM_BODIES))        /* body b's trees: roots[start:  */ \
    X(body_elem_end, MODEL, shape(DIM_BODIES))          /*                       end]   */  \
    X(roots, MODEL, shape(DIM_ELEMENTS))                /* each tree's root node */         \
    X(nodes, MODEL, shape(DIM_NODES, NODE_WIDTH))       /* left, right, first, count */     \
    X(pair_a, MODEL, shape(DIM_PAIRS))                  /* a link */                        \
    X(pair_b, MODEL, shape(DIM_PAIRS))                  /* a link or a world object */      \
    X(joint_pairs_start, MODEL, shape(plus_one(DIM_JOINTS)))  /* variable j's pairs: */     \
    X(joint_pairs, MODEL, shape(DIM_JOINT_PAIRS))       /* joint_pairs[start[j]:start[j+1]] */ \
    X(joint_links_start, MODEL, shape(plus_one(DIM_JOINTS)))  /* the links it moves */      \
    X(joint_links, MODEL, shape(DIM_JOINT_LINKS))                                           \
    X(joint_prismatic, MODEL, shape(DIM_JOINTS))        /* 1: it drives a slider */         \
    X(motion_kind, MODEL, shape(DIM_JOINTS))            /* MOTION_*: how it moves (motion) */ \
    X(query_flags, STATE, shape(N_QUERY_FLAGS))         /* QUERY_* */                       \
    X(stale, STATE, shape(DIM_BODIES))                  /* 1: pose behind q_ref */          \
    X(status, STATE, shape(DIM_PAIRS))                  /* 1: in contact */                 \
    X(witness, STATE, shape(DIM_PAIRS, 2))              /* meeting triangles, or -1 */      \
    X(forced, STATE, shape(DIM_PAIRS))                  /* 1: re-check whatever q does */   \
    X(counters, WORK, shape(N_COUNTERS))                /* COUNT_*: work done */            \
    X(scene_culled, WORK, shape(DIM_WORLD_OBJECTS, DIM_LINKS))  /* culling.hpp */           \
    X(nearest, WORK, shape(DIM_PAIRS, 2))               /* proximity's warm start, or -1 */

// Each slot's index in its table: slot::T_parent_joint, slot::parent, ...
namespace slot {
#define CS_SLOT_ENUM(name, group, shape) name,
enum Float : int { CS_FLOAT_SLOTS(CS_SLOT_ENUM) };
enum Int : int { CS_INT_SLOTS(CS_SLOT_ENUM) };
#undef CS_SLOT_ENUM
}  // namespace slot
#define CS_SLOT_COUNT(name, group, shape) +1
constexpr int N_FLOAT_SLOTS = 0 CS_FLOAT_SLOTS(CS_SLOT_COUNT);
constexpr int N_INT_SLOTS = 0 CS_INT_SLOTS(CS_SLOT_COUNT);
#undef CS_SLOT_COUNT

struct SlotSpec {
    const char* name;
    Group group;
    Shape shape;
};
extern const SlotSpec FLOAT_SLOT_SPECS[N_FLOAT_SLOTS];
extern const SlotSpec INT_SLOT_SPECS[N_INT_SLOTS];

// A layout row: where a slot lies in its buffer and its extents (padded to 3 with 1).
constexpr int LAYOUT_WIDTH = 5;

// The checker's layout is not the engine's (a slot outside its buffer, or of another shape
// than the tables say): the two were built from different sources.
struct LayoutError : std::invalid_argument {
    using std::invalid_argument::invalid_argument;
};

// The packed buffers, cut into the slots: pointers into F and I, and the resolved dimensions.
struct ResolvedLayout {
    double* f[N_FLOAT_SLOTS];
    int64_t* i[N_INT_SLOTS];
    int64_t dims[N_DIMS];
};

// Cut F (f_size doubles) and I (i_size int64) by their layout rows (N_*_SLOTS, LAYOUT_WIDTH),
// resolving each dimension from the first slot that has it and checking every other slot
// against it. Throws LayoutError naming the slot, its shape and the expected one.
ResolvedLayout resolve_layout(double* F, int64_t f_size, const int64_t* f_layout, int64_t* I,
                              int64_t i_size, const int64_t* i_layout);

// A shape in words: "(links, 4, 4)", "(joints+1,)".
std::string shape_name(const Shape& s);

}  // namespace collision_sensor
