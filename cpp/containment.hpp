// Containment: one body wholly inside a solid element of the other, with no triangles meeting
// (FCL's rule for primitives: something inside a solid collides with it).
//
// A solid element (layout.hpp: elem_solid) is a box, sphere or cylinder, tested as the true
// shape, not its tessellation, which lies inside it (cylinders and spheres are inscribed): a
// point in the sliver between the two counts as inside, erring toward contact, as FCL's true
// primitives do; or a closed mesh (the checker's mesh_containment), where a point is inside
// when a ray from it crosses the mesh's triangles an odd number of times.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "model.hpp"

namespace collision_sensor {

// Point x (in the body frame) in the frame of a solid (elem_solid row s: kind, size, R at s + 4,
// t at s + 13): p = R' (x - t).
inline void in_solid_frame(const double* s, const double* x, double* p) {
    const double* R = s + 4;
    const double* t = s + 13;
    const double d0 = x[0] - t[0], d1 = x[1] - t[1], d2 = x[2] - t[2];
    p[0] = R[0] * d0 + R[3] * d1 + R[6] * d2;
    p[1] = R[1] * d0 + R[4] * d1 + R[7] * d2;
    p[2] = R[2] * d0 + R[5] * d1 + R[8] * d2;
}

// True iff point x (in element e's body frame) lies in element e's solid: the true box, sphere
// or cylinder, or a closed mesh by ray parity (the boundary counts). False for no solid.
bool inside_solid(const Model& model, int64_t e, const double* x);

// True iff an element of one body lies in a solid element of the other (pair a, b; body b at
// pose in a's frame), called once their triangles are known apart: then one vertex, the
// element's test vertex (layout.hpp: SOLID_PROBE), decides for the whole element (it cannot
// be partly inside without its surface meeting the solid's). Element pairs whose spheres are
// apart cannot contain one another and are skipped.
bool contained(const Model& model, int64_t a, int64_t b, const double* pose);

// Like contained(), for a pair known to collide without meeting triangles: a vertex x (in body
// a's frame) of an element of one body that lies in a solid element of the other, a point of
// both bodies. False if there is none.
bool contained_vertex(const Model& model, int64_t a, int64_t b, const double* pose, double* x);

// The distance from point x (in element e's body frame) to the solid of element e, 0 inside:
// the true box, sphere or cylinder (elem_solid row s: kind, size, R, t). INF for a closed mesh
// or none: a body cannot enter a closed mesh without its surface meeting the mesh's, which the
// triangles see; a primitive's tessellation is inscribed, so a vertex can enter the true solid
// (which check() counts) without any triangle meeting.
inline double solid_distance(const double* s, const double* x) {
    double p[3];
    in_solid_frame(s, x, p);
    const double p0 = p[0], p1 = p[1], p2 = p[2];
    switch (int(s[0])) {
        case SOLID_BOX: {  // half extents
            const double e0 = std::max(std::fabs(p0) - s[1], 0.0);
            const double e1 = std::max(std::fabs(p1) - s[2], 0.0);
            const double e2 = std::max(std::fabs(p2) - s[3], 0.0);
            return std::sqrt(e0 * e0 + e1 * e1 + e2 * e2);
        }
        case SOLID_SPHERE:  // radius
            return std::max(std::sqrt(p0 * p0 + p1 * p1 + p2 * p2) - s[1], 0.0);
        case SOLID_CYLINDER: {  // along z: radius, half length
            const double er = std::max(std::sqrt(p0 * p0 + p1 * p1) - s[1], 0.0);
            const double ez = std::max(std::fabs(p2) - s[2], 0.0);
            return std::sqrt(er * er + ez * ez);
        }
        default:
            return std::numeric_limits<double>::infinity();
    }
}

}  // namespace collision_sensor
