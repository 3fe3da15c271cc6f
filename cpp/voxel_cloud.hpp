// One source's point cloud obstacle: the side structure the engine keeps for a
// world object named cloud/<source>, a body without trees whose geometry is a VoxelGrid
// (voxel_grid.hpp).
//
// Two grids: the current one, which queries read (Model::clouds points at it), and the next,
// which the source's next cloud is built into (CloudBuilder: the self-filter and the voxels,
// with work areas kept from cloud to cloud), off the engine's lock and off the interpreter's,
// while queries go on. Committing it (Engine::commit_cloud, under the engine's lock) swaps the
// two and forces the cloud's pairs: the obstacle is updated in place, the engine and every
// other pair's state untouched, and the next query re-checks only the cloud's pairs (and what
// the joints moved). The grid swapped out is the next cloud's to build into: no allocation
// once the clouds' sizes settle.
#pragma once

#include <cstdint>
#include <mutex>
#include <vector>

#include "cloud_filter.hpp"
#include "voxel_grid.hpp"

namespace collision_sensor {

struct VoxelCloud {
    std::mutex building;  // one build at a time; a commit waits for the build in progress
    VoxelGrid grids[2];
    int front = 0;
    CloudBuilder builder;
    CloudStats stats;     // the last build's
    int64_t ticket = 0;   // the last build's number
    bool built = false;   // grids[1 - front] holds build `ticket`, not committed yet

    const VoxelGrid& current() const { return grids[front]; }

    // Build the next grid from the current one (CloudBuilder::build); return its ticket.
    int64_t build(const Model& model, const double* T_links, const CloudPoints& points,
                  const CloudSettings& settings, std::vector<float>* kept) {
        std::lock_guard<std::mutex> hold(building);
        stats = builder.build(model, T_links, points, settings, grids[front], grids[1 - front],
                              kept);
        built = true;
        return ++ticket;
    }

    // Make build `number` current; false when it is not the last build, or was committed.
    bool swap(int64_t number) {
        std::lock_guard<std::mutex> hold(building);
        if (!built || number != ticket) return false;
        front = 1 - front;
        built = false;
        return true;
    }
};

}  // namespace collision_sensor
