// The model: what a query reads and never writes (paper sec. 2), cut from the checker's packed
// buffers (layout.hpp: the model group), checked once, with the tables derived from it.
//
// Bodies are the engine's links (FK order, parents first, world == root link frame): the
// robot's links, then the objects attached to them (each a link on a fixed joint below its
// robot link, whose T_parent_joint is the object's pose in that link's frame), followed by
// the world objects. A body may be padded (padding[b], metres: its geometry grown by a swept
// sphere, MoveIt's link padding): its boxes then hold the padded geometry (the checker grows
// them), and a pair's leaves meet within the two paddings' sum (traversal.hpp).
//
// Between queries the engine's scene methods change some rows (engine.hpp: a world object's
// pose, an attached object's joint origin and its pairs' reach); a query never does.
#pragma once

#include <cstdint>
#include <vector>

#include "kinematics.hpp"
#include "layout.hpp"
#include "obb_tree.hpp"

namespace collision_sensor {

struct VoxelGrid;  // voxel_grid.hpp: a point cloud's voxels

struct Model {
    int64_t n_links, n_bodies, n_joints, n_pairs, n_elements, n_nodes, n_triangles;
    KinematicTree kin;          // the links' tree (kinematics.hpp)
    Forest forest;              // every tree (obb_tree.hpp)
    const double* body_boxes;   // (B, BOX_WIDTH) each body's box, body frame
    const double* padding;      // (B,) metres
    const int64_t* elem_start;  // (B,) body b's trees: roots[elem_start[b]:elem_end[b]]
    const int64_t* elem_end;    // (B,)
    const int64_t* roots;       // (E,) each tree's root node
    const double* elem_solid;   // (E, SOLID_WIDTH) what each tree fills (layout.hpp)
    const int64_t* pair_a;      // (P,) a link
    const int64_t* pair_b;      // (P,) a link or a world object
    const double* reach;        // (P, J) planning.hpp: how far variable j moves the pair
    const double* reach_ext;    // (P, J)
    // Variable j's pairs (those with j on their path) and links (whose pose depends on it):
    // joint_pairs[joint_pairs_start[j]:joint_pairs_start[j + 1]], joint_links likewise.
    const int64_t* joint_pairs_start;
    const int64_t* joint_pairs;
    const int64_t* joint_links_start;
    const int64_t* joint_links;
    const int64_t* joint_prismatic;  // (J,) 1 where j drives a slider
    const int64_t* motion_kind;      // (J,) MOTION_*: how j moves along a motion (motion.hpp)

    // Derived once, when the model is made.
    std::vector<int64_t> elem_tris;    // (E, 2) each tree's triangle range (its leaves')
    std::vector<uint8_t> body_solid;   // (B,) 1 where a body has a solid element
    std::vector<double> body_reach;    // (B,) |body box centre| + its radius (poses.hpp)
    // Each body's pairs as pair_b: body_pairs[body_pairs_start[b]:body_pairs_start[b + 1]].
    std::vector<int64_t> body_pairs_start, body_pairs;
    // The pairs with a joint variable on the tree path between their bodies, and the static
    // others, whose relative pose, and so whose answer, is the same at every configuration
    // (a fixed base and the world's objects); both ascending.
    std::vector<int64_t> moving_pairs, static_pairs;
    // (B,) the voxels of each body that is a point cloud (a world object without trees, its
    // grid kept by the engine: voxel_cloud.hpp), else null; set by Engine::attach_cloud.
    std::vector<const VoxelGrid*> clouds;
    int64_t depth;       // the deepest tree's depth (a lone leaf: 1)
    int64_t most_seeds;  // the most root pairs one pair has: elements(a) elements(b)

    bool is_world_object(int64_t b) const { return b >= n_links; }
    bool is_cloud(int64_t b) const { return clouds[b] != nullptr; }
    const double* body_box(int64_t b) const { return body_boxes + BOX_WIDTH * b; }
    int64_t elements(int64_t b) const { return elem_end[b] - elem_start[b]; }
};

// An element's convex hull, for motion's sweeps of bodies in relative translation
// (convex_sweep.hpp): the distinct vertices (n, 3) of a primitive's tessellation, or of a
// closed mesh every face plane of which has them all on one side, in its body's frame; each
// vertex's neighbours along the triangles' edges (adj[adj_start[i] : adj_start[i + 1]]); its
// furthest vertex along each of convex_sweep.hpp's seed directions; the vertices' mean
// (centre) and a radius about it that holds them all, rounding included.
struct Hull {
    std::vector<double> vertices;
    std::vector<int32_t> adj_start, adj, seeds;  // int32: half the cache lines a climb reads
    double centre[3] = {0.0, 0.0, 0.0};
    double radius = 0.0;
    // A box's: its axes (columns of a 3 x 3, row-major) and, per octant (bit k: + along axis
    // k), the vertex at that corner; empty for any other hull.
    std::vector<double> axes;
    std::vector<int32_t> corner;
};

// Element e's hull into out; false (out untouched) when e is not a closed convex element.
// Built on first need (motion.cpp), not with the model: a scene change lays out a new model,
// and most are never swept.
bool element_hull(const Model& m, int64_t e, Hull& out);

// The model of a resolved layout, every index a query follows without checking checked here.
// Throws std::invalid_argument naming the array at fault.
Model make_model(const ResolvedLayout& layout);

}  // namespace collision_sensor
