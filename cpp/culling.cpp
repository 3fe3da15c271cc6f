// First culling by the volumes spanning several links (culling.hpp).
#include "culling.hpp"

#include <algorithm>
#include <cmath>

#include "traversal.hpp"

namespace collision_sensor {

namespace {

// For every link k, the world axis-aligned box around the boxes of all links in k's subtree
// (identity axes), into S (L, BOX_WIDTH). A subtree without geometry gets half extents -1
// (empty).
void subtree_volumes(const Model& m, const double* T_world_body, double* S) {
    for (int64_t k = 0; k < m.n_links; ++k)
        for (int c = 0; c < 6; ++c) S[BOX_WIDTH * k + c] = c < 3 ? INF : -INF;  // lo, hi
    for (int64_t b = m.n_links - 1; b >= 0; --b) {  // children before parents
        double* row = S + BOX_WIDTH * b;
        if (m.elements(b) > 0) {
            const double* T = T_world_body + 16 * b;
            const double* box = m.body_box(b);
            for (int i = 0; i < 3; ++i) {
                double c = T[4 * i + 3];
                double e = 0.0;
                for (int k = 0; k < 3; ++k) {
                    c += T[4 * i + k] * box[BOX_CENTER + k];
                    // |row i of R_world_box| . half: the box's half width along world axis i.
                    const double ax = T[4 * i] * box[BOX_AXES + k] +
                                      T[4 * i + 1] * box[BOX_AXES + 3 + k] +
                                      T[4 * i + 2] * box[BOX_AXES + 6 + k];
                    e += std::fabs(ax) * box[BOX_HALF + k];
                }
                row[i] = std::min(row[i], c - e);
                row[3 + i] = std::max(row[3 + i], c + e);
            }
        }
        const int64_t p = m.kin.parent[b];
        if (p >= 0) {
            double* up = S + BOX_WIDTH * p;
            for (int i = 0; i < 3; ++i) {
                up[i] = std::min(up[i], row[i]);
                up[3 + i] = std::max(up[3 + i], row[3 + i]);
            }
        }
    }
    for (int64_t k = 0; k < m.n_links; ++k) {  // lo/hi -> a box row
        double* row = S + BOX_WIDTH * k;
        const double lo[3] = {row[0], row[1], row[2]};
        const double hi[3] = {row[3], row[4], row[5]};
        for (int c = 0; c < BOX_WIDTH; ++c) row[c] = 0.0;
        row[BOX_AXES] = row[BOX_AXES + 4] = row[BOX_AXES + 8] = 1.0;
        if (!(lo[0] <= hi[0])) {
            row[BOX_HALF] = -1.0;  // no geometry below k
            continue;
        }
        double hh = 0.0;
        for (int i = 0; i < 3; ++i) {
            const double h = 0.5 * (hi[i] - lo[i]);
            row[BOX_CENTER + i] = 0.5 * (lo[i] + hi[i]);
            row[BOX_HALF + i] = h;
            hh += h * h;
        }
        row[BOX_RADIUS] = std::sqrt(hh);
    }
}

// True iff world object w's box is disjoint from the volume A of a link's subtree.
bool outside(const Model& m, const double* T_world_body, int box_test, int64_t w,
             const double* A) {
    if (A[BOX_HALF] < 0.0) return true;  // nothing with geometry below the link
    const int64_t body = m.n_links + w;
    const double* T = T_world_body + 16 * body;
    const double P[12] = {T[0], T[1], T[2], T[4], T[5], T[6], T[8], T[9], T[10],
                          T[3], T[7], T[11]};
    return boxes_apart(box_test, A, m.body_box(body), P);
}

// True iff two subtree volumes are the same box.
bool same_volume(const double* K, const double* P) {
    return std::equal(K + BOX_CENTER, K + BOX_CENTER + 3, P + BOX_CENTER) &&
           std::equal(K + BOX_HALF, K + BOX_HALF + 3, P + BOX_HALF);
}

}  // namespace

// Top down: link k is culled for object w when its subtree's volume, or an ancestor's, misses
// w's box. A link whose volume is its parent's (a link without geometry of its own and one
// child: every link of a chain above the first with geometry) takes the parent's verdict
// untested: the same two boxes give the same answer.
void refresh_culling(const Model& m, const double* T_world_body, int box_test,
                     Scratch& scratch) {
    const double* S = scratch.subtree_boxes.data();
    subtree_volumes(m, T_world_body, scratch.subtree_boxes.data());
    for (int64_t w = 0; w < m.n_bodies - m.n_links; ++w) {
        int64_t* culled = scratch.scene_culled + m.n_links * w;
        for (int64_t k = 0; k < m.n_links; ++k) {
            const int64_t p = m.kin.parent[k];
            if (p >= 0 && (culled[p] || same_volume(S + BOX_WIDTH * k, S + BOX_WIDTH * p)))
                culled[k] = culled[p];
            else
                culled[k] = outside(m, T_world_body, box_test, w, S + BOX_WIDTH * k) ? 1 : 0;
        }
    }
}

}  // namespace collision_sensor
