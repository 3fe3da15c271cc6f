// The self-filter and the voxelisation of a point cloud (cloud_filter.hpp).
#include "cloud_filter.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#include "containment.hpp"
#include "inlining.hpp"
#include "tolerances.hpp"
#include "traversal.hpp"
#include "triangle_box.hpp"
#include "workers.hpp"

namespace collision_sensor {

using namespace cloud_detail;

namespace {

constexpr uint64_t EMPTY_KEY = ~uint64_t(0);
// The hash table's least capacity (slots; a power of 2).
constexpr int64_t MIN_TABLE = 4096;
// The fewest rows a thread of the first pass takes (enough work to repay starting and joining
// a thread); fewer rows run on fewer threads.
constexpr int64_t MIN_CHUNK_ROWS = 20000;
// Entries of the first pass's table of recent voxels (a power of 2).
constexpr int64_t RECENT = 1024;

uint64_t pack_key(int64_t i, int64_t j, int64_t k) {
    return uint64_t(i + VOXEL_COORD_LIMIT) | uint64_t(j + VOXEL_COORD_LIMIT) << 21 |
           uint64_t(k + VOXEL_COORD_LIMIT) << 42;
}

// The slot of key in a table of 2^(64 - shift) slots: Fibonacci hashing, the product's top
// bits (each depends on every bit of the key; bits 24 to 39 of it, as taken before
// 2026-11-26, miss k, so a column of voxels (i, j, *) shared one slot and chains of ~17
// probes formed along walls).
CS_ALWAYS_INLINE int64_t table_index(uint64_t key, int shift) {
    return int64_t((key * 0x9E3779B97F4A7C15ULL) >> shift);
}

int log2_of(int64_t power_of_two) { return 63 - __builtin_clzll(uint64_t(power_of_two)); }

// Row r's x, y, z.
CS_ALWAYS_INLINE bool read_row(const CloudPoints& c, int64_t r, double* x) {
    const char* row = c.data + r * c.row_stride;
    if (c.float32) {
        float v[3];
        for (int k = 0; k < 3; ++k) std::memcpy(&v[k], row + k * c.column_stride, sizeof(float));
        x[0] = v[0];
        x[1] = v[1];
        x[2] = v[2];
    } else {
        for (int k = 0; k < 3; ++k)
            std::memcpy(&x[k], row + k * c.column_stride, sizeof(double));
    }
    return std::isfinite(x[0]) && std::isfinite(x[1]) && std::isfinite(x[2]);
}

// floor(g) for |g| < 2^62, without a library call (std::floor is one without SSE4.1).
CS_ALWAYS_INLINE int64_t floor_to_int(double g) {
    const int64_t i = int64_t(g);
    return i - (double(i) > g ? 1 : 0);
}

int64_t next_power_of_two(int64_t n) {
    int64_t p = 1;
    while (p < n) p <<= 1;
    return p;
}

}  // namespace

void CloudBuilder::Tally::clear(int64_t capacity) {
    n = 0;
    invalid = out_of_range = 0;
    if (int64_t(keys.size()) != capacity) {
        keys.assign(capacity, EMPTY_KEY);
        slots.assign(capacity, -1);
        size_for(capacity);
    } else {
        std::fill(keys.begin(), keys.end(), EMPTY_KEY);
    }
}

void CloudBuilder::Tally::size_for(int64_t capacity) {
    mask = capacity - 1;
    shift = 64 - log2_of(capacity);
    const int64_t most = capacity / 2 + 1;  // voxels before the table grows
    ijk.resize(3 * most);
    lo.resize(3 * most);
    hi.resize(3 * most);
    count.resize(most);
    near_count.resize(most);
}

void CloudBuilder::Tally::rehash(int64_t capacity) {
    keys.assign(capacity, EMPTY_KEY);
    slots.assign(capacity, -1);
    size_for(capacity);
    for (int64_t v = 0; v < n; ++v) {
        const uint64_t key = pack_key(ijk[3 * v], ijk[3 * v + 1], ijk[3 * v + 2]);
        int64_t at = table_index(key, shift);
        while (keys[at] != EMPTY_KEY) at = (at + 1) & mask;
        keys[at] = key;
        slots[at] = int32_t(v);
    }
}

int64_t CloudBuilder::Tally::slot_of(uint64_t key) {
    int64_t at = table_index(key, shift);
    while (keys[at] != EMPTY_KEY) {
        if (keys[at] == key) return slots[at];
        at = (at + 1) & mask;
    }
    const int64_t v = n++;
    keys[at] = key;
    slots[at] = int32_t(v);
    const int64_t L = VOXEL_COORD_LIMIT;
    ijk[3 * v] = int32_t(int64_t(key & 0x1fffff) - L);
    ijk[3 * v + 1] = int32_t(int64_t((key >> 21) & 0x1fffff) - L);
    ijk[3 * v + 2] = int32_t(int64_t((key >> 42) & 0x1fffff) - L);
    for (int a = 0; a < 3; ++a) {
        lo[3 * v + a] = INF;
        hi[3 * v + a] = -INF;
    }
    count[v] = near_count[v] = 0;
    if (2 * n > mask + 1) rehash(2 * (mask + 1));
    return v;
}

void CloudBuilder::tally_rows(const RowPass& p, int64_t begin, int64_t end, Tally& tally,
                              int32_t* row_voxel) {
    // Locals, not p's fields: the writes below through double* could alias them.
    const CloudPoints points = *p.points;
    const int64_t step = p.step;
    double frame[12], region_lo[3], region_hi[3];
    std::copy(p.frame, p.frame + 12, frame);
    std::copy(p.region_lo, p.region_lo + 3, region_lo);
    std::copy(p.region_hi, p.region_hi + 3, region_hi);
    const double inv = p.inv, range2 = p.range2, limit = double(VOXEL_COORD_LIMIT);
    int64_t invalid = 0, out_of_range = 0;
    uint64_t last_key = EMPTY_KEY;
    int64_t last_voxel = -1;
    // The voxels met lately, direct-mapped: an organised cloud's next image row meets the
    // voxels of the last few again, and this small table stays in the L1 cache, where the
    // hash table (tens of thousands of slots) does not (a third of the lookups reach it).
    uint64_t recent_key[RECENT];
    int32_t recent_voxel[RECENT];
    std::fill(recent_key, recent_key + RECENT, EMPTY_KEY);
    for (int64_t t = begin; t < end; ++t) {
        row_voxel[t] = -1;
        double x[3], w[3];
        if (!read_row(points, t * step, x)) {
            ++invalid;
            continue;
        }
        if (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] > range2) {
            ++out_of_range;
            continue;
        }
        apply(frame, x, w);
        const double gi = w[0] * inv, gj = w[1] * inv, gk = w[2] * inv;
        if (!(std::fabs(gi) < limit && std::fabs(gj) < limit && std::fabs(gk) < limit)) {
            ++out_of_range;
            continue;
        }
        const uint64_t key = pack_key(floor_to_int(gi), floor_to_int(gj), floor_to_int(gk));
        int64_t v = last_voxel;
        if (key != last_key) {
            const int64_t at = int64_t(key ^ key >> 18 ^ key >> 39) & (RECENT - 1);
            if (recent_key[at] == key) {
                v = recent_voxel[at];
            } else {
                v = tally.slot_of(key);
                recent_key[at] = key;
                recent_voxel[at] = int32_t(v);
            }
            last_key = key;
            last_voxel = v;
        }
        row_voxel[t] = int32_t(v);
        ++tally.count[v];
        if (w[0] >= region_lo[0] && w[0] <= region_hi[0] && w[1] >= region_lo[1] &&
            w[1] <= region_hi[1] && w[2] >= region_lo[2] && w[2] <= region_hi[2]) {
            ++tally.near_count[v];
            double* lo = tally.lo.data() + 3 * v;
            double* hi = tally.hi.data() + 3 * v;
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], w[k]);
                hi[k] = std::max(hi[k], w[k]);
            }
        }
    }
    tally.invalid += invalid;
    tally.out_of_range += out_of_range;
}

CloudStats CloudBuilder::build(const Model& m, const double* T_links, const CloudPoints& pts,
                               const CloudSettings& s, const VoxelGrid& previous,
                               VoxelGrid& out, std::vector<float>* kept) {
    CloudStats stats;
    stats.points = pts.rows;
    const int64_t step = pts.rows > s.max_points ? (pts.rows + s.max_points - 1) / s.max_points
                                                 : 1;
    const int64_t taken = pts.rows > 0 ? (pts.rows + step - 1) / step : 0;
    stats.capped = pts.rows - taken;
    const double size = s.voxel_size, inv = 1.0 / size, r = s.filter_padding;
    const double range2 = s.max_range * s.max_range;

    // World -> body poses at the cloud's state, and the frame's pose.
    body_pose_.resize(12 * m.n_links);
    for (int64_t b = 0; b < m.n_links; ++b) {
        const double* T = T_links + 16 * b;
        double* P = body_pose_.data() + 12 * b;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) P[3 * i + j] = T[4 * j + i];
            P[9 + i] = -(T[i] * T[3] + T[4 + i] * T[7] + T[8 + i] * T[11]);
        }
    }
    RowPass pass{&pts, step, {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0}, inv, range2, {}, {}};
    double* frame = pass.frame;
    if (s.frame >= 0) {
        const double* T = T_links + 16 * s.frame;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) frame[3 * i + j] = T[4 * i + j];
            frame[9 + i] = T[4 * i + 3];
        }
    }

    // The region the robot's geometry grown by r can reach: the world box around its bodies'
    // boxes. Points outside it are kept untested, and only voxels with points in it (near
    // voxels) are looked at further.
    double* region_lo = pass.region_lo;
    double* region_hi = pass.region_hi;
    for (int i = 0; i < 3; ++i) {
        region_lo[i] = INF;
        region_hi[i] = -INF;
    }
    for (int64_t b = 0; b < m.n_links; ++b) {
        if (m.elements(b) == 0) continue;
        const double* T = T_links + 16 * b;
        const double* box = m.body_box(b);
        for (int i = 0; i < 3; ++i) {
            double c = T[4 * i + 3], e = r;
            for (int k = 0; k < 3; ++k) {
                c += T[4 * i + k] * box[BOX_CENTER + k];
                const double axis = T[4 * i] * box[BOX_AXES + k] +
                                    T[4 * i + 1] * box[BOX_AXES + 3 + k] +
                                    T[4 * i + 2] * box[BOX_AXES + 6 + k];
                e += std::fabs(axis) * box[BOX_HALF + k];
            }
            e += BOUND_ROUNDING_REL * (std::fabs(c) + e);  // rounding: err toward near
            region_lo[i] = std::min(region_lo[i], c - e);
            region_hi[i] = std::max(region_hi[i], c + e);
        }
    }
    auto in_region = [&](const double* w) {
        return w[0] >= region_lo[0] && w[0] <= region_hi[0] && w[1] >= region_lo[1] &&
               w[1] <= region_hi[1] && w[2] >= region_lo[2] && w[2] <= region_hi[2];
    };

    // Points into voxels (the hash tables sized for the last cloud's voxels): the rows in k
    // contiguous chunks, chunk 0 into tally_, chunk c >= 1 into chunks_[c - 1] on a thread of
    // its own, merged into tally_ in chunk order. Voxels are numbered as one pass would number
    // them (in the order their first point comes: chunk 0's, then each later chunk's new
    // ones in its own order), and counts, boxes (min, max) and rows merge exactly, so the
    // grid is the same on any number of threads.
    const int64_t expected = std::max<int64_t>(MIN_TABLE, next_power_of_two(4 * out.count + 1));
    const int64_t k = std::max<int64_t>(
        1, std::min<int64_t>(s.threads, taken / MIN_CHUNK_ROWS));
    tally_.clear(expected);
    if (int64_t(chunks_.size()) < k - 1) {
        chunks_.resize(k - 1);
        chunk_voxel_.resize(k - 1);
    }
    row_voxel_.resize(taken);
    run_chunks(k, [&](int64_t c) {
        const Chunk rows = chunk_of(c, k, taken);
        Tally& tally = c == 0 ? tally_ : chunks_[c - 1];
        if (c > 0) tally.clear(expected);
        tally_rows(pass, rows.begin, rows.end, tally, row_voxel_.data());
    });
    for (int64_t c = 1; c < k; ++c) {
        const Tally& from = chunks_[c - 1];
        std::vector<int32_t>& to = chunk_voxel_[c - 1];
        to.resize(from.n);
        for (int64_t u = 0; u < from.n; ++u) {
            const int32_t* ijk = from.ijk.data() + 3 * u;
            const int64_t v = tally_.slot_of(pack_key(ijk[0], ijk[1], ijk[2]));
            to[u] = int32_t(v);
            tally_.count[v] += from.count[u];
            tally_.near_count[v] += from.near_count[u];
            for (int a = 0; a < 3; ++a) {
                tally_.lo[3 * v + a] = std::min(tally_.lo[3 * v + a], from.lo[3 * u + a]);
                tally_.hi[3 * v + a] = std::max(tally_.hi[3 * v + a], from.hi[3 * u + a]);
            }
        }
        tally_.invalid += from.invalid;
        tally_.out_of_range += from.out_of_range;
    }
    // Row t of chunk c >= 1 holds its voxel's number in chunks_[c - 1]; the second pass (the
    // same chunks) reads it through chunk_voxel_[c - 1].
    const int64_t row_chunks = k;
    stats.invalid = tally_.invalid;
    stats.out_of_range = tally_.out_of_range;
    old_seen_.assign(tally_.n, -INF);
    // Earlier voxels still within the persistence, not seen in this cloud: their centres.
    if (s.persistence > 0.0 && previous.size == size) {
        for (int64_t v = 0; v < previous.count; ++v) {
            if (!(previous.seen[v] >= s.stamp - s.persistence)) continue;
            const int32_t* c = previous.ijk.data() + 3 * v;
            const int64_t u = tally_.slot_of(pack_key(c[0], c[1], c[2]));
            old_seen_.resize(tally_.n, -INF);
            if (tally_.count[u] > 0) continue;
            old_seen_[u] = std::max(old_seen_[u], previous.seen[v]);
            double centre[3];
            for (int k = 0; k < 3; ++k) centre[k] = size * (c[k] + 0.5);
            if (in_region(centre)) {
                tally_.near_count[u] = 1;
                for (int k = 0; k < 3; ++k) tally_.lo[3 * u + k] = tally_.hi[3 * u + k] = centre[k];
            }
        }
    }

    // The filter's hierarchy over the near voxels, each with the box of its near points.
    const int64_t V = tally_.n;
    sort_.keyed.clear();
    for (int64_t v = 0; v < V; ++v)
        if (tally_.near_count[v] > 0)
            sort_.keyed.push_back(
                {morton_code(tally_.ijk[3 * v], tally_.ijk[3 * v + 1], tally_.ijk[3 * v + 2]), v});
    sort_by_code(sort_);
    const int64_t n_near = int64_t(sort_.keyed.size());
    codes_.resize(n_near);
    order_.resize(n_near);
    item_lo_.resize(3 * n_near);
    item_hi_.resize(3 * n_near);
    for (int64_t i = 0; i < n_near; ++i) {
        const int64_t v = sort_.keyed[i].second;
        codes_[i] = sort_.keyed[i].first;
        order_[i] = v;
        for (int k = 0; k < 3; ++k) {
            item_lo_[3 * i + k] = tally_.lo[3 * v + k];
            item_hi_[3 * i + k] = tally_.hi[3 * v + k];
        }
    }
    filter_depth_ = build_box_hierarchy(codes_.data(), item_lo_.data(), item_hi_.data(), n_near,
                                        1, filter_nodes_, filter_boxes_);
    if (n_near > 0) collect_candidates(m, T_links, r, s.threads);
    else start_.assign(V + 1, 0);

    // Each near voxel's class (its near points kept, removed, or tested one by one); the
    // others keep theirs. Points are read again only where needed.
    class_.assign(V, KEEP);
    kept_.assign(V, 0);
    classify_voxels(m, r, s.threads);
    bool again = kept && s.keep_points;
    for (int64_t v = 0; v < V; ++v)
        again |= class_[v] == MIXED || (class_[v] == DROP && tally_.near_count[v] < tally_.count[v]);
    if (kept) kept->clear();
    const bool keep_rows = kept && s.keep_points;
    // Voxels kept or removed whole need no row read: their counts first.
    for (int64_t v = 0; v < V; ++v) {
        if (class_[v] == KEEP) {
            kept_[v] = tally_.count[v];
            stats.kept_points += tally_.count[v];
        } else if (class_[v] == DROP && tally_.near_count[v] == tally_.count[v]) {
            stats.self_filtered += tally_.count[v];
        }
    }
    if (again) {
        // The other rows (and every row when they are written) in the first pass's chunks:
        // chunk 0 into kept_ and kept, chunk c >= 1 into rows_[c - 1], added and appended in
        // chunk order (the one thread's counts and rows).
        const int64_t k = row_chunks;
        if (int64_t(rows_.size()) < k - 1) rows_.resize(k - 1);
        run_chunks(k, [&](int64_t c) {
            const Chunk rows = chunk_of(c, k, taken);
            const int32_t* merged = c == 0 ? nullptr : chunk_voxel_[c - 1].data();
            KeptRows* own = c == 0 ? nullptr : &rows_[c - 1];
            if (own) {
                own->counts.assign(V, 0);
                own->points.clear();
                own->self_filtered = 0;
            }
            int32_t* counts = own ? own->counts.data() : kept_.data();
            std::vector<float>* points = own ? &own->points : kept;
            int64_t self_filtered = 0;
            for (int64_t t = rows.begin; t < rows.end; ++t) {
                const int64_t u = row_voxel_[t];
                if (u < 0) continue;
                const int64_t v = merged ? merged[u] : u;
                const uint8_t cls = class_[v];
                if (cls == KEEP ? !keep_rows
                                : cls == DROP && tally_.near_count[v] == tally_.count[v])
                    continue;  // counted above
                double x[3], w[3];
                read_row(pts, t * step, x);
                apply(frame, x, w);
                if (cls != KEEP && in_region(w)) {
                    const double* lo = tally_.lo.data() + 3 * v;
                    const double* hi = tally_.hi.data() + 3 * v;
                    const double centre[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]),
                                              0.5 * (lo[2] + hi[2])};
                    if (cls == DROP || removed(m, w, r, near_.data() + near_start_[v],
                                               near_start_[v + 1] - near_start_[v], centre)) {
                        ++self_filtered;
                        continue;
                    }
                }
                if (cls != KEEP) ++counts[v];
                if (keep_rows)
                    points->insert(points->end(), {float(w[0]), float(w[1]), float(w[2])});
            }
            if (own) own->self_filtered = self_filtered;
            else stats.self_filtered += self_filtered;
        });
        for (int64_t c = 1; c < k; ++c) {
            const KeptRows& from = rows_[c - 1];
            for (int64_t v = 0; v < V; ++v) kept_[v] += from.counts[v];
            stats.self_filtered += from.self_filtered;
            if (keep_rows) kept->insert(kept->end(), from.points.begin(), from.points.end());
        }
        for (int64_t v = 0; v < V; ++v)
            if (class_[v] != KEEP) stats.kept_points += kept_[v];
    }

    // The voxels kept: those with a point kept, and earlier ones whose centre is kept.
    out_ijk_.clear();
    out_seen_.clear();
    for (int64_t v = 0; v < V; ++v) {
        const bool earlier = tally_.count[v] == 0;
        if (earlier ? class_[v] != KEEP : kept_[v] == 0) continue;
        out_ijk_.insert(out_ijk_.end(), {tally_.ijk[3 * v], tally_.ijk[3 * v + 1], tally_.ijk[3 * v + 2]});
        out_seen_.push_back(earlier ? old_seen_[v] : s.stamp);
        stats.persisted += earlier ? 1 : 0;
    }
    build_voxel_grid(out_ijk_.data(), out_seen_.data(), int64_t(out_seen_.size()), size, sort_,
                     out);
    stats.voxels = out.count;
    return stats;
}

}  // namespace collision_sensor
