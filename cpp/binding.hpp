// What the binding files share (bindings.cpp, bind_engine.cpp, bind_clouds.cpp,
// bind_kernels.cpp): the array type they take, the one shape check, the package's exceptions,
// and each concern's binding function, which the module definition (bindings.cpp) calls in
// turn.
//
// Everything else under cpp/ is plain C++17 over contiguous arrays. Arrays cross here as
// numpy arrays of the exact dtype and layout the engine reads: inputs are converted by
// pybind11 when they are not (a copy is harmless for them), arrays written in place are
// taken only as they are (.noconvert(): a buffer that needed a copy would silently lose its
// writes). Every shape is checked by one function (expect_shape). Errors cross as the
// package's own exceptions (collision_sensor/errors.py): EngineInputError for an argument the
// engine cannot take, EngineBuildError for packed buffers whose layout is not the engine's,
// JointStateError for joint values it cannot honour, EngineWorkerError for a batch whose worker
// thread failed.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <exception>
#include <memory>
#include <initializer_list>
#include <stdexcept>
#include <string>

namespace collision_sensor {

class Engine;
class VoxelCloud;

namespace binding {

namespace py = pybind11;

template <class T>
using Array = py::array_t<T, py::array::c_style>;

// The package's exception types, looked up once (and kept for the interpreter's life).
struct PackageErrors {
    py::handle input, build, joint_state, worker;
};
const PackageErrors& errors();

// Set the Python error for a C++ exception as the module's translator does: LayoutError ->
// EngineBuildError, WorkerError -> EngineWorkerError, std::invalid_argument ->
// EngineInputError, py::error_already_set restored, anything else RuntimeError (for entry
// points called without pybind11's dispatch).
void set_python_error(std::exception_ptr thrown);

// Raise JointStateError(message) with attributes row and variable (the index into q).
[[noreturn]] void raise_joint_state(const std::string& message, py::ssize_t row,
                                    int64_t variable);

// True iff array a has the extents dims (-1: any): the one shape check of the binding.
bool has_shape(const py::array& a, std::initializer_list<py::ssize_t> dims);

// has_shape, or EngineInputError naming the array, the shape expected and the one given.
void expect_shape(const char* name, const py::array& a, std::initializer_list<py::ssize_t> dims);

template <class T>
T* writable(const char* name, Array<T>& a) {
    if (!a.writeable())
        throw std::invalid_argument(std::string(name) + ": the array is read-only");
    return a.mutable_data();
}

// The data of h if it is already an array the engine takes as it is (C-contiguous, aligned,
// native float64 of the extents dims), else nullptr: the check of every joint-state message,
// which costs less than converting.
const double* exact_doubles(py::handle h, std::initializer_list<py::ssize_t> dims);

// The engine of a binding's Engine object, and the cloud of its VoxelCloud object (either
// object of another type: a cast error).
Engine& engine_of(py::handle engine);                  // bind_engine.cpp
std::shared_ptr<VoxelCloud> cloud_of(py::handle cloud);  // bind_clouds.cpp

// A result area a binding keeps between calls (its arrays allocated once), lent to one call
// at a time: a call reads its answer there after the engine's lock is let go and the
// interpreter taken back, when another thread may have run a check of its own. The lending
// happens with the interpreter lock held, so a flag says whether the area is out; a call that
// finds it out (another thread is between its check and its answer) gets an area of its own.
template <class Result>
struct KeptArea {
    Result result;
    bool lent = false;
};

template <class Result>
class AreaLoan {
   public:
    explicit AreaLoan(KeptArea<Result>& area) : area_(area.lent ? nullptr : &area) {
        if (area_)
            area_->lent = true;
        else
            own_ = std::make_unique<Result>();
    }
    ~AreaLoan() {
        if (area_) area_->lent = false;
    }
    AreaLoan(const AreaLoan&) = delete;
    AreaLoan& operator=(const AreaLoan&) = delete;
    Result& operator*() { return area_ ? area_->result : *own_; }

   private:
    KeptArea<Result>* area_;
    std::unique_ptr<Result> own_;
};

// Each concern's bindings, registered by the module definition (bindings.cpp) in turn. A new
// concern adds its function here and its call there, in a file of its own.
void export_constants(py::module_& m);     // bindings.cpp: constants and the packed layout
void bind_engine(py::module_& m);          // bind_engine.cpp: Engine, its result types
void bind_clouds(py::module_& m);          // bind_clouds.cpp: VoxelCloud
void bind_sensor(py::module_& m);          // bind_sensor.cpp: SensorCore
void bind_kinematics(py::module_& m);      // bind_kernels.cpp: Kinematics
void bind_query_kernels(py::module_& m);   // bind_kernels.cpp: box, triangle, tree kernels
void bind_build_kernels(py::module_& m);   // bind_kernels.cpp: fits, trees, number tables

}  // namespace binding
}  // namespace collision_sensor
