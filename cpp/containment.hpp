// Containment: one body wholly inside a solid element of the other, with no triangles meeting
// (FCL's rule for primitives: something inside a solid collides with it).
//
// A solid element (layout.hpp: elem_solid) is a box, sphere or cylinder, tested as the true
// shape, not its tessellation, which lies inside it (cylinders and spheres are inscribed): a
// point in the sliver between the two counts as inside, erring toward contact, as FCL's true
// primitives do; or a closed mesh (the checker's mesh_containment), where a point is inside
// when a ray from it crosses the mesh's triangles an odd number of times.
#pragma once

#include <cstdint>

#include "model.hpp"

namespace collision_sensor {

// True iff an element of one body lies in a solid element of the other (pair a, b; body b at
// pose in a's frame), called once their triangles are known apart: then one vertex, the
// element's test vertex (layout.hpp: SOLID_PROBE), decides for the whole element (it cannot be partly inside without its surface meeting the solid's).
// Element pairs whose spheres are apart cannot contain one another and are skipped.
// True iff point x (in element e's body frame) lies in element e's solid: the true box, sphere
// or cylinder, or a closed mesh by ray parity (the boundary counts). False for no solid.
bool inside_solid(const Model& model, int64_t e, const double* x);

bool contained(const Model& model, int64_t a, int64_t b, const double* pose);

// Like contained(), for a pair known to collide without meeting triangles: a vertex x (in body
// a's frame) of an element of one body that lies in a solid element of the other, a point of
// both bodies. False if there is none.
bool contained_vertex(const Model& model, int64_t a, int64_t b, const double* pose, double* x);

}  // namespace collision_sensor
