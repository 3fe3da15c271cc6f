// Bindings of the point clouds an engine shows (voxel_cloud.hpp: VoxelCloud): one source's
// cloud, its next grid built off every lock (cloud_filter.hpp), and its current voxels.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "binding.hpp"
#include "cloud_filter.hpp"
#include "engine.hpp"
#include "kinematics.hpp"
#include "voxel_cloud.hpp"

namespace collision_sensor {
namespace binding {

namespace cs = collision_sensor;

namespace {

// One source's point cloud (voxel_cloud.hpp), shared by the engines that show it: the
// checker's, and the next one a scene change lays out.
struct PyVoxelCloud {
    std::shared_ptr<cs::VoxelCloud> cloud = std::make_shared<cs::VoxelCloud>();

    // The current grid's voxel centres (V, 3) and their seen stamps (V,), world frame.
    py::tuple voxels() const {
        std::lock_guard<std::mutex> hold(cloud->building);
        const cs::VoxelGrid& g = cloud->current();
        Array<double> centres({py::ssize_t(g.count), py::ssize_t(3)});
        Array<double> seen(py::ssize_t(g.count));
        for (int64_t v = 0; v < g.count; ++v) {
            g.centre(v, centres.mutable_data() + 3 * v);
            seen.mutable_data()[v] = g.seen[v];
        }
        return py::make_tuple(centres, seen, g.size);
    }
};

// (points, capped, invalid, out_of_range, self_filtered, kept_points, voxels, persisted).
py::tuple stats_tuple(const cs::CloudStats& s) {
    return py::make_tuple(s.points, s.capped, s.invalid, s.out_of_range, s.self_filtered,
                          s.kept_points, s.voxels, s.persisted);
}

}  // namespace

std::shared_ptr<cs::VoxelCloud> cloud_of(py::handle cloud) {
    return cloud.cast<PyVoxelCloud&>().cloud;
}

void bind_clouds(py::module_& m) {
    py::class_<PyVoxelCloud>(m, "VoxelCloud",
                             "One source's point cloud obstacle (cpp/voxel_cloud.hpp): its "
                             "current voxels, and the next cloud built off every lock.")
        .def(py::init<>())
        .def("voxels", &PyVoxelCloud::voxels,
             "(centres (V, 3), seen (V,), voxel size) of the current grid, world frame.")
        .def("prepare",
             [](PyVoxelCloud& self, py::handle engine, const py::array& points, int64_t frame,
                const Array<double>& q, double voxel_size, double filter_padding,
                double max_range, int64_t max_points, double stamp, double persistence,
                bool keep_points, int64_t threads) {
                 cs::Engine& owner = engine_of(engine);
                 const cs::Model& model = owner.model();
                 const bool f32 = py::isinstance<py::array_t<float>>(points);
                 if (!(f32 || py::isinstance<py::array_t<double>>(points)) || points.ndim() != 2 ||
                     points.shape(1) != 3)
                     throw std::invalid_argument(
                         "points: expected an (n, 3) float32 or float64 array");
                 expect_shape("q", q, {model.n_joints});
                 if (frame < -1 || frame >= model.n_links)
                     throw std::invalid_argument("frame: not a link of the engine");
                 if (!(voxel_size > 0.0 && std::isfinite(voxel_size) && filter_padding >= 0.0 &&
                       std::isfinite(filter_padding) && max_range > 0.0 && max_points > 0 &&
                       std::isfinite(stamp) && persistence >= 0.0 && std::isfinite(persistence) &&
                       threads >= 0 && threads <= cs::MAX_THREADS))
                     throw std::invalid_argument(
                         "voxel_size, filter_padding, max_range, max_points, stamp, "
                         "persistence, threads: out of range");
                 const int64_t bad = cs::unusable_variable(model.kin, q.data(), model.n_joints);
                 if (bad >= 0) raise_joint_state("joint value not usable", 0, bad);
                 cs::CloudPoints cloud = {static_cast<const char*>(points.data()),
                                          int64_t(points.shape(0)), int64_t(points.strides(0)),
                                          int64_t(points.strides(1)), f32};
                 const cs::CloudSettings settings = {voxel_size, filter_padding, max_range,
                                                     max_points,  stamp,          persistence,
                                                     frame,       keep_points,
                                                     cs::resolve_threads(threads)};
                 std::vector<double> T(16 * model.n_links);
                 {   // the link poses at q, with the engine's joint origins as they are now
                     std::lock_guard<std::mutex> hold(owner.lock());
                     cs::forward_kinematics(model.kin, q.data(), T.data());
                 }
                 std::vector<float> kept;
                 int64_t ticket;
                 {
                     py::gil_scoped_release release;
                     ticket = self.cloud->build(model, T.data(), cloud, settings,
                                                keep_points ? &kept : nullptr);
                 }
                 py::object out = py::none();
                 if (keep_points) {
                     Array<float> array({py::ssize_t(kept.size() / 3), py::ssize_t(3)});
                     std::copy(kept.begin(), kept.end(), array.mutable_data());
                     out = std::move(array);
                 }
                 return py::make_tuple(ticket, stats_tuple(self.cloud->stats), out);
             },
             py::arg("engine"), py::arg("points"), py::arg("frame"), py::arg("q"),
             py::arg("voxel_size"), py::arg("filter_padding"), py::arg("max_range"),
             py::arg("max_points"), py::arg("stamp"), py::arg("persistence"),
             py::arg("keep_points"), py::arg("threads"),
             "Build the next grid from points (n, 3) float32/float64 in link `frame` (-1: the "
             "world), self-filtered at the joint values q against engine's robot "
             "(cpp/cloud_filter.hpp), on up to `threads` threads (0: every hardware thread; the "
             "same grid on any number); return (ticket, stats (points, capped, invalid, "
             "out_of_range, self_filtered, kept_points, voxels, persisted), the points kept "
             "(m, 3) float32 world frame or None). Runs without the interpreter lock.");
}

}  // namespace binding
}  // namespace collision_sensor
