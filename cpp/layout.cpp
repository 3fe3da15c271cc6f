// The packed arrays' layout: the slot tables and their check (layout.hpp).
#include "layout.hpp"

namespace collision_sensor {

const char* const DIM_NAMES[N_DIMS] = {
    "links", "bodies", "world_objects", "joints", "pairs", "nodes", "triangles", "elements",
    "joint_pairs", "joint_links"};

const char* const GROUP_NAMES[N_GROUPS] = {"model", "state", "work"};

#define CS_SLOT_SPEC(name, group, shape) {#name, GROUP_##group, shape},
const SlotSpec FLOAT_SLOT_SPECS[N_FLOAT_SLOTS] = {CS_FLOAT_SLOTS(CS_SLOT_SPEC)};
const SlotSpec INT_SLOT_SPECS[N_INT_SLOTS] = {CS_INT_SLOTS(CS_SLOT_SPEC)};
#undef CS_SLOT_SPEC

namespace {

std::string extent_name(const Extent& e) {
    if (e.dim == DIM_NONE) return std::to_string(e.plus);
    std::string name = DIM_NAMES[e.dim];
    return e.plus == 0 ? name : name + "+" + std::to_string(e.plus);
}

// The dimensions resolved so far, and the slot each was first seen in.
struct Dims {
    int64_t* size;
    const char* source[N_DIMS];
};

// "(pairs, joints) = (52, 7), joints from 'reach'": a shape with the sizes resolved so far.
std::string expected_name(const Shape& s, const Dims& dims) {
    std::string sizes = "(", sources;
    for (int k = 0; k < s.ndim; ++k) {
        const Extent& e = s.extent[k];
        sizes += (k ? ", " : "") + std::to_string(e.dim == DIM_NONE ? e.plus
                                                                     : dims.size[e.dim] + e.plus);
        if (e.dim != DIM_NONE)
            sources += std::string(", ") + DIM_NAMES[e.dim] + " from '" + dims.source[e.dim] +
                       "'";
    }
    return shape_name(s) + " = " + sizes + (s.ndim == 1 ? ",)" : ")") + sources;
}

std::string extents_name(const int64_t* d, int ndim) {
    std::string s = "(";
    for (int k = 0; k < ndim; ++k) s += (k ? ", " : "") + std::to_string(d[k]);
    return s + (ndim == 1 ? ",)" : ")");
}

// Cut one buffer: each slot's row checked against the buffer's size and its spec's shape,
// each dimension resolved from the first slot that has it.
template <class T>
void cut(const char* dtype, T* buffer, int64_t size, const int64_t* layout,
         const SlotSpec* specs, int n_slots, T** out, Dims& dims) {
    for (int k = 0; k < n_slots; ++k) {
        const SlotSpec& spec = specs[k];
        const int64_t* row = layout + LAYOUT_WIDTH * k;
        const int64_t offset = row[0], count = row[1];
        const int64_t* d = row + 2;
        if (offset < 0 || count < 0 || d[0] < 0 || d[1] < 0 || d[2] < 0 ||
            offset > size - count || d[0] * d[1] * d[2] != count)
            throw LayoutError(std::string("packed ") + dtype + " array '" + spec.name +
                              "' lies outside its buffer; the checker and the engine disagree "
                              "on the layout: rebuild the engine");
        bool ok = true;
        for (int a = 0; a < 3; ++a) {
            const Extent& e = a < spec.shape.ndim ? spec.shape.extent[a] : Extent(1);
            int64_t want = e.plus;
            if (e.dim != DIM_NONE) {
                if (dims.size[e.dim] < 0) {  // first seen here
                    dims.size[e.dim] = d[a] - e.plus;
                    dims.source[e.dim] = spec.name;
                }
                want = dims.size[e.dim] + e.plus;
            }
            ok = ok && d[a] == want;
        }
        if (!ok)
            throw LayoutError(std::string("packed ") + dtype + " array '" + spec.name +
                              "' has shape " + extents_name(d, spec.shape.ndim) +
                              ", expected " + expected_name(spec.shape, dims) +
                              "; the checker and the engine disagree on the layout: rebuild "
                              "the engine");
        out[k] = buffer + offset;
    }
}

}  // namespace

std::string shape_name(const Shape& s) {
    std::string out = "(";
    for (int k = 0; k < s.ndim; ++k) out += (k ? ", " : "") + extent_name(s.extent[k]);
    return out + (s.ndim == 1 ? ",)" : ")");
}

ResolvedLayout resolve_layout(double* F, int64_t f_size, const int64_t* f_layout, int64_t* I,
                              int64_t i_size, const int64_t* i_layout) {
    ResolvedLayout r;
    for (int64_t& d : r.dims) d = -1;
    Dims dims = {r.dims, {}};
    cut("float64", F, f_size, f_layout, FLOAT_SLOT_SPECS, N_FLOAT_SLOTS, r.f, dims);
    cut("int64", I, i_size, i_layout, INT_SLOT_SPECS, N_INT_SLOTS, r.i, dims);
    for (int k = 0; k < N_DIMS; ++k)
        if (r.dims[k] < 0)
            throw LayoutError(std::string("no packed array has dimension '") + DIM_NAMES[k] +
                              "': rebuild the engine");
    if (r.dims[DIM_WORLD_OBJECTS] != r.dims[DIM_BODIES] - r.dims[DIM_LINKS])
        throw LayoutError("packed arrays: world_objects is not bodies - links (" +
                          std::to_string(r.dims[DIM_WORLD_OBJECTS]) + " != " +
                          std::to_string(r.dims[DIM_BODIES]) + " - " +
                          std::to_string(r.dims[DIM_LINKS]) + ")");
    return r;
}

}  // namespace collision_sensor
