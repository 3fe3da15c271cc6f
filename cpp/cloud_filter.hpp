// A point cloud made an obstacle: points in, the robot's own points filtered out,
// the rest grouped into voxels (voxel_grid.hpp).
//
// Contract, for the points p (rows of the cloud, in the frame of link `frame` or the world)
// and the link poses T at the cloud's state:
//     taken   = every ceil(rows / max_points)-th row (all when rows <= max_points)
//     valid   = taken rows with finite x, y, z, within max_range of the frame's origin, whose
//               world point T_frame p lies in the grid's reach (voxel_grid.hpp)
//     removed = valid points x with, for some body b of the robot (its links and attached
//               objects) and element e of b: the distance from x to e's triangles <= r, or x
//               within r of e's solid (box, sphere, cylinder: the true shape), or inside it
//               (a closed mesh, with the checker's mesh_containment), r = filter_padding
//     voxels  = the cubes of the voxel_size grid holding a valid point not removed, plus
//               (persistence > 0) the voxels of the previous grid seen within persistence
//               of stamp whose centre is not removed (the robot may have moved into them)
// Only the work is organised, never the answer: the points are hashed into their voxels (one
// pass over the rows, or up to settings.threads passes over contiguous chunks of them, merged
// in order into what one pass gives); a hierarchy over the occupied voxels, each with the box
// of its own points, is traversed against every body's tree with boxes grown by r (the
// elements shared out to up to settings.threads threads, gathered in element order), which
// gives each voxel the triangles and solids that can come within r of it (the same list on
// any number of threads); a voxel none of whose candidates comes
// within r of its points' box keeps its points untested, one whose points' box lies within r
// of a single triangle or solid loses them all untested (the distance to a convex set is
// convex, so the box's farthest point from it is a corner: within r of its centre plus its half
// diagonal), and only the points of the voxels in between are tested one by one, nearest
// candidate first (the classes and the second pass on up to settings.threads threads too,
// merged in order).
#pragma once

#include <cstdint>
#include <vector>

#include "inlining.hpp"
#include "model.hpp"
#include "voxel_grid.hpp"

namespace collision_sensor {

// What cloud_filter.cpp (the passes over the rows) and cloud_self_filter.cpp (the robot's
// candidates near each voxel) share.
namespace cloud_detail {

// A voxel's class: its points kept untested, removed untested, or tested one by one.
constexpr uint8_t KEEP = 0, DROP = 1, MIXED = 2;

// x in the frame of pose (12 numbers: R row-major, t): R x + t.
CS_ALWAYS_INLINE void apply(const double* P, const double* x, double* y) {
    for (int i = 0; i < 3; ++i)
        y[i] = P[3 * i] * x[0] + P[3 * i + 1] * x[1] + P[3 * i + 2] * x[2] + P[9 + i];
}

}  // namespace cloud_detail

// The rows of a cloud as read: x, y and z of row r at data + r row_stride + {0, 1, 2}
// column_stride bytes, float32 or float64.
struct CloudPoints {
    const char* data;
    int64_t rows;
    int64_t row_stride;
    int64_t column_stride;
    bool float32;
};

struct CloudSettings {
    double voxel_size;      // m
    double filter_padding;  // r, m
    double max_range;       // m from the frame's origin (INF: none)
    int64_t max_points;     // rows taken at most
    double stamp;           // s, the cloud's time (persistence)
    double persistence;     // s; 0: only this cloud
    int64_t frame;          // the engine link the points are in, -1: the world
    bool keep_points;       // write the points not removed (world frame)
    int64_t threads = 1;    // the rows' first pass, the candidates and the near voxels'
                            // classes on up to this many threads (>= 1; the answer is the
                            // same on any number)
};

// What became of a cloud's rows (their sum: points = capped + invalid + out_of_range +
// self_filtered + kept_points).
struct CloudStats {
    int64_t points = 0, capped = 0, invalid = 0, out_of_range = 0, self_filtered = 0,
            kept_points = 0, voxels = 0, persisted = 0;
};

// The self-filter and the voxelisation of one source's clouds, with work areas kept from one
// cloud to the next (the source's clouds are built one at a time).
class CloudBuilder {
   public:
    // Build into `out` the grid of the cloud `points` (settings as above), filtered against
    // the robot of `model` at the link poses T_links (L, 16), merging the voxels of `previous`
    // (its own grid so far). The points kept go, world frame, to kept (3 per point) when
    // settings.keep_points. Reads the model's trees and solids only.
    CloudStats build(const Model& model, const double* T_links, const CloudPoints& points,
                     const CloudSettings& settings, const VoxelGrid& previous, VoxelGrid& out,
                     std::vector<float>* kept);

   private:
    struct Candidate {
        int64_t voxel;
        int64_t body;
        int64_t item;  // a triangle (row of tris), or -1 - e for solid element e
    };
    struct Nearby {
        double distance;  // of the voxel's points' box centre
        int64_t body, item;
    };

    // The voxels of a run of rows: key -> voxel in a hash table (open addressing), voxels
    // numbered in the order their first point comes, and per voxel its coordinates, its
    // points, those near the robot and their box.
    struct Tally {
        std::vector<uint64_t> keys;
        std::vector<int32_t> slots;
        int64_t mask = 0;
        int shift = 64;  // 64 - log2(slots)
        int64_t n = 0;   // voxels
        // Per voxel, sized for the most the table holds before it grows (only [0, n) used).
        std::vector<int32_t> ijk;
        std::vector<double> lo, hi;  // (n, 3) the box of its near points (INF, -INF: none)
        std::vector<int32_t> count, near_count;
        int64_t invalid = 0, out_of_range = 0;  // rows

        // Empty, with a table of `capacity` slots (a power of 2).
        void clear(int64_t capacity);
        // The voxel of key, a new one (no point yet) if it has none.
        int64_t slot_of(uint64_t key);
        void rehash(int64_t capacity);
        void size_for(int64_t capacity);
    };
    // What the first pass over the rows needs (build's locals).
    struct RowPass {
        const CloudPoints* points;
        int64_t step;       // row t of the pass is row t step of the cloud
        double frame[12];   // frame -> world (R row-major, t)
        double inv, range2;
        double region_lo[3], region_hi[3];
    };
    // Rows [begin, end) of the pass into tally; row_voxel[t]: row t's voxel, -1 if not valid.
    static void tally_rows(const RowPass& pass, int64_t begin, int64_t end, Tally& tally,
                           int32_t* row_voxel);

    // One thread's work areas for the candidates and the classes (a cache line apart from
    // another thread's: their ends are written at every push).
    struct alignas(64) FilterWork {
        std::vector<int64_t> stack;
        std::vector<Candidate> found;  // the candidates of its elements, element after element
        std::vector<Nearby> near;      // its voxels' nearby lists, in voxel order
    };
    // Where an element's candidates went: found[begin, end) of thread `thread`'s work.
    struct Found {
        int64_t thread, begin, end;
    };
    void collect_candidates(const Model& m, const double* T_links, double r, int64_t threads);
    void element_candidates(const Model& m, const double* T_links, double r, int64_t b,
                            int64_t e, FilterWork& work);
    // element_candidates' node for the descent (cloud_self_filter.cpp); Solid: the element
    // taken whole, its solid against the voxels.
    template <bool Solid>
    struct CandidateNode;
    void classify_voxels(const Model& m, double r, int64_t threads);
    int classify(const Model& m, int64_t v, double r, std::vector<Nearby>& near);
    bool removed(const Model& m, const double* x, double r, const Nearby* near,
                 int64_t n_near, const double* centre);

    // The voxels of this cloud (V0) and, per voxel, its class, its points kept, and for the
    // earlier voxels merged in the stamp they were last seen (-INF: seen in this cloud).
    Tally tally_;
    std::vector<int32_t> kept_;
    std::vector<uint8_t> class_;
    std::vector<double> old_seen_;
    // The first pass on k threads: chunk c >= 1 of the rows tallied in chunks_[c - 1], then
    // merged into tally_ (chunk_voxel_[c - 1]: its voxels' numbers there).
    std::vector<Tally> chunks_;
    std::vector<std::vector<int32_t>> chunk_voxel_;
    // The second pass on k threads: chunk c >= 1's counts of points kept per voxel, its
    // points kept and its count of removed ones.
    struct alignas(64) KeptRows {
        std::vector<int32_t> counts;
        std::vector<float> points;
        int64_t self_filtered = 0;
    };
    std::vector<KeptRows> rows_;
    // Per taken row: its voxel (for chunk c >= 1 of the first pass, its number in
    // chunks_[c - 1]), -1 when not valid.
    std::vector<int32_t> row_voxel_;
    // The filter's hierarchy (leaves of one voxel) and each voxel's candidates.
    VoxelSortWork sort_;
    std::vector<uint64_t> codes_;
    std::vector<int64_t> order_;  // hierarchy item -> voxel
    std::vector<double> item_lo_, item_hi_;
    std::vector<int64_t> filter_nodes_;
    std::vector<double> filter_boxes_;
    int64_t filter_depth_ = 0;
    // The robot's elements (body, element) in the order one thread visits them, and where
    // each one's candidates went: each element is traversed by one thread, and sorted_
    // gathers them in element order, so the list is the one thread's on any number.
    std::vector<std::pair<int64_t, int64_t>> elements_;
    std::vector<Found> found_;
    std::vector<Candidate> sorted_;
    std::vector<int64_t> start_;  // (V0 + 1,) each voxel's candidates in sorted_
    std::vector<FilterWork> work_;  // per thread
    std::vector<Nearby> near_;    // (V0 candidates) by voxel, nearest first
    std::vector<int64_t> near_start_;
    std::vector<double> body_pose_;  // per body: R' (row-major), -R' t: world -> body
    // (N, 18) robot nodes' world boxes (cloud_filter.cpp: NODE_WORLD), valid where
    // node_stamp_ == stamp_. A node belongs to one element's tree (model.cpp checks it), and
    // an element to one thread: no entry is written by two threads.
    std::vector<double> node_world_;
    std::vector<int64_t> node_stamp_;
    int64_t stamp_ = 0;
    // The kept voxels.
    std::vector<int32_t> out_ijk_;
    std::vector<double> out_seen_;
};

}  // namespace collision_sensor
