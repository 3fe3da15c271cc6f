// Containment of one body in a solid element of the other (containment.hpp).
#include "containment.hpp"

#include <cmath>
#include <cstring>

#include "traversal.hpp"

namespace collision_sensor {

// True iff point x (in element e's body frame) lies in element e's solid (closed: the
// boundary counts, as touching does). A box, sphere or cylinder is tested as the true shape,
// not its tessellation, which lies inside it (cylinders and spheres are inscribed): a point in
// the sliver between the two counts as inside, erring toward contact, as FCL's true primitives
// do. A closed mesh: a ray from x crosses its triangles an odd number of times.
bool inside_solid(const Model& m, int64_t e, const double* x) {
    const double* s = m.elem_solid + SOLID_WIDTH * e;
    double p[3];
    in_solid_frame(s, x, p);
    const double p0 = p[0], p1 = p[1], p2 = p[2];
    switch (int(s[0])) {
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
            for (int64_t k = m.elem_tris[2 * e]; k < m.elem_tris[2 * e + 1]; ++k) {
                const double* T = m.forest.tris + 9 * k;
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

bool contained(const Model& m, int64_t a, int64_t b, const double* P) {
    if (!m.body_solid[a] && !m.body_solid[b]) return false;
    for (int64_t ea = m.elem_start[a]; ea < m.elem_end[a]; ++ea) {
        for (int64_t eb = m.elem_start[b]; eb < m.elem_end[b]; ++eb) {
            const bool solid_a = m.elem_solid[SOLID_WIDTH * ea] != SOLID_NONE;
            const bool solid_b = m.elem_solid[SOLID_WIDTH * eb] != SOLID_NONE;
            if (!solid_a && !solid_b) continue;
            if (m.elem_tris[2 * ea] == m.elem_tris[2 * ea + 1] ||
                m.elem_tris[2 * eb] == m.elem_tris[2 * eb + 1])
                continue;  // an element without triangles
            const int64_t ra = m.roots[ea], rb = m.roots[eb];
            if (spheres(m.forest.box(ra), m.forest.box(rb), P).apart) continue;
            if (solid_a) {  // a vertex of eb, taken to body a: R_ab x + t_ab
                const double* x = m.elem_solid + SOLID_WIDTH * eb + SOLID_PROBE;
                const double y[3] = {P[0] * x[0] + P[1] * x[1] + P[2] * x[2] + P[9],
                                     P[3] * x[0] + P[4] * x[1] + P[5] * x[2] + P[10],
                                     P[6] * x[0] + P[7] * x[1] + P[8] * x[2] + P[11]};
                if (inside_solid(m, ea, y)) return true;
            }
            if (solid_b) {  // a vertex of ea, taken to body b: R_ab' (x - t_ab)
                const double* x = m.elem_solid + SOLID_WIDTH * ea + SOLID_PROBE;
                const double d0 = x[0] - P[9], d1 = x[1] - P[10], d2 = x[2] - P[11];
                const double y[3] = {P[0] * d0 + P[3] * d1 + P[6] * d2,
                                     P[1] * d0 + P[4] * d1 + P[7] * d2,
                                     P[2] * d0 + P[5] * d1 + P[8] * d2};
                if (inside_solid(m, eb, y)) return true;
            }
        }
    }
    return false;
}

bool contained_vertex(const Model& m, int64_t a, int64_t b, const double* P, double* x) {
    for (int64_t ea = m.elem_start[a]; ea < m.elem_end[a]; ++ea) {
        for (int64_t eb = m.elem_start[b]; eb < m.elem_end[b]; ++eb) {
            if (m.elem_tris[2 * ea] == m.elem_tris[2 * ea + 1] ||
                m.elem_tris[2 * eb] == m.elem_tris[2 * eb + 1])
                continue;
            if (m.elem_solid[SOLID_WIDTH * ea] != SOLID_NONE) {  // eb's vertex, in body a
                const double* v = m.elem_solid + SOLID_WIDTH * eb + SOLID_PROBE;
                for (int i = 0; i < 3; ++i)
                    x[i] = P[3 * i] * v[0] + P[3 * i + 1] * v[1] + P[3 * i + 2] * v[2] + P[9 + i];
                if (inside_solid(m, ea, x)) return true;
            }
            if (m.elem_solid[SOLID_WIDTH * eb] != SOLID_NONE) {  // ea's vertex, in body b
                const double* v = m.elem_solid + SOLID_WIDTH * ea + SOLID_PROBE;
                const double d0 = v[0] - P[9], d1 = v[1] - P[10], d2 = v[2] - P[11];
                const double y[3] = {P[0] * d0 + P[3] * d1 + P[6] * d2,
                                     P[1] * d0 + P[4] * d1 + P[7] * d2,
                                     P[2] * d0 + P[5] * d1 + P[8] * d2};
                if (inside_solid(m, eb, y)) {
                    std::memcpy(x, v, 3 * sizeof(double));
                    return true;
                }
            }
        }
    }
    return false;
}

}  // namespace collision_sensor
