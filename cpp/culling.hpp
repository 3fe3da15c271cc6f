// First culling against the world objects by the volumes spanning several links (paper sec.
// 2.2), for full checks.
//
// For every link k, a world axis-aligned box around the boxes of all links in k's subtree
// (identity axes), rebuilt from the link boxes, never from geometry; row 0 (the root) is the
// robot's root volume. A full check rebuilds them and culls each world object against them top
// down before any pair is looked at: scene_culled[w, k] = 1 when world object w's box misses
// the volume of link k's subtree (or an ancestor's). Incremental calls skip the culling: a
// pair they re-check is one whose own clearance ran out, and its own boxes give the next.
#pragma once

#include <cstdint>

#include "context.hpp"
#include "model.hpp"

namespace collision_sensor {

// Rebuild the subtree volumes (scratch.subtree_boxes) from the link poses and fill
// scratch.scene_culled; every link pose must be current.
void refresh_culling(const Model& model, const double* T_world_body, int box_test,
                     Scratch& scratch);

// True iff pair p (link a, world object b) is culled by the last refresh_culling.
inline bool culled(const Model& m, const Scratch& scratch, int64_t a, int64_t b) {
    return m.is_world_object(b) && scratch.scene_culled[m.n_links * (b - m.n_links) + a];
}

}  // namespace collision_sensor
