// xgauge._xgauge: the Python bindings (pybind11) behind the package xgauge
// (python/xgauge/__init__.py, docs/python.md).
//
// Contract:
// - Images cross as numpy float32 arrays of shape (rows, columns), row 0 the
//   top (docs/conventions.md). An image the library made is handed over
//   without a copy: the array's base is a capsule that owns the Image.
// - Files (part, machine, material, job) are given as paths or as dicts that
//   hold what the JSON file would; a dict's relative paths are taken from
//   `base_dir`. Every bad input raises xgauge.Error (a ValueError) with the
//   library's message, which names the file or "<dict>" and the key.
// - Long calls (render, measure, simulate, TIFF I/O) release the GIL; the
//   progress callback is called with the GIL held, from whichever thread
//   logs.
#include "xgauge/calibrate/part.h"
#include "xgauge/calibrate/wedge.h"
#include "xgauge/core/config.h"
#include "xgauge/core/error.h"
#include "xgauge/core/log.h"
#include "xgauge/core/output.h"
#include "xgauge/core/progress.h"
#include "xgauge/geometry/part_model.h"
#include "xgauge/image/radiograph_file.h"
#include "xgauge/image/tiff.h"
#include "xgauge/lab/dataset.h"
#include "xgauge/lab/recipe.h"
#include "xgauge/material/exponential_sum.h"
#include "xgauge/material/transmission_table.h"
#include "xgauge/measure/inputs.h"
#include "xgauge/measure/measure.h"
#include "xgauge/measure/model.h"
#include "xgauge/measure/truth.h"
#include "xgauge/report/calibration.h"
#include "xgauge/report/measurement.h"
#include "xgauge/version.h"
#include "xgauge/xgauge.h"
#include "xgauge/xray/derivatives.h"
#include "xgauge/xray/machine.h"
#include "xgauge/xray/renderer.h"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>
#include <spdlog/sinks/base_sink.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace py = pybind11;
namespace fs = std::filesystem;

namespace xgauge::python {
namespace {

// Images ----------------------------------------------------------------------

// A (rows, columns) array over `image`'s pixels, which the array then owns
// (no copy).
template <typename T>
py::array_t<T> toNumpy(ImageT<T> image) {
  auto* owned = new ImageT<T>(std::move(image));
  py::capsule base(owned, [](void* p) { delete static_cast<ImageT<T>*>(p); });
  const auto columns = static_cast<py::ssize_t>(owned->width());
  const auto rows = static_cast<py::ssize_t>(owned->height());
  const auto size = static_cast<py::ssize_t>(sizeof(T));
  return py::array_t<T>({rows, columns}, {columns * size, size}, owned->pixels().data(), base);
}

// A copy of a 2-D array (any real dtype, converted to float32).
Image fromNumpy(const py::array_t<float, py::array::c_style | py::array::forcecast>& array) {
  if (array.ndim() != 2)
    throw Error(fmt::format("an image is a 2-D array (rows, columns), not {}-D", array.ndim()));
  Image image(static_cast<int>(array.shape(1)), static_cast<int>(array.shape(0)));
  std::copy_n(array.data(), image.size(), image.pixels().data());
  return image;
}

// Inputs ----------------------------------------------------------------------

bool isPath(const py::handle& spec) {
  return py::isinstance<py::str>(spec) ||
         py::isinstance(spec, py::module_::import("os").attr("PathLike"));
}

// A file's parsed contents, from its path or from a dict holding the same.
ConfigNode configFrom(const py::handle& spec, const std::string& what) {
  if (isPath(spec)) return ConfigNode::loadFile(py::cast<fs::path>(spec));
  if (!py::isinstance<py::dict>(spec))
    throw Error(fmt::format("{}: give a file path or a dict, not {}", what,
                            py::str(py::type::of(spec).attr("__name__")).cast<std::string>()));
  const std::string text = py::module_::import("json").attr("dumps")(spec).cast<std::string>();
  return ConfigNode::parse(text, "<" + what + " dict>");
}

PartModel partFrom(const py::handle& spec, const fs::path& base_dir) {
  if (isPath(spec)) {
    const fs::path path = py::cast<fs::path>(spec);
    return PartModel::fromFile(path);
  }
  const ConfigNode root = configFrom(spec, "part");
  PartModel part = PartModel::fromConfig(root, base_dir / "part.json");
  root.finish();
  return part;
}

Machine machineFrom(const py::handle& spec) {
  const ConfigNode node = configFrom(spec, "machine");
  Machine machine = Machine::fromConfig(node);
  node.finish();
  return machine;
}

ExponentialSum materialFrom(const py::handle& spec) {
  const ConfigNode node = configFrom(spec, "material");
  ExponentialSum material = ExponentialSum::fromConfig(node);
  node.finish();
  return material;
}

// A pose: a 4x4 world_from_part matrix (nested sequences or an array), a
// dict with the pose file's keys, or a pair (rotation_deg, translation_mm).
Pose poseFrom(const py::handle& spec) {
  if (py::isinstance<py::dict>(spec) || isPath(spec)) {
    const ConfigNode node = configFrom(spec, "pose");
    Pose pose = poseFromConfig(node);
    node.finish();
    return pose;
  }
  const auto array = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(spec);
  if (array && array.ndim() == 2 && array.shape(0) == 4 && array.shape(1) == 4) {
    Mat4 m;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m(r, c) = array.at(r, c);
    return Pose::fromMatrix(m);
  }
  if (array && array.ndim() == 2 && array.shape(0) == 2 && array.shape(1) == 3)
    return Pose::fromEulerDeg({array.at(0, 0), array.at(0, 1), array.at(0, 2)},
                              {array.at(1, 0), array.at(1, 1), array.at(1, 2)});
  throw Error(
      "pose: give a 4x4 matrix, a pair (rotation_deg [rx, ry, rz], translation_mm [x, y, z]) or a "
      "dict with the pose file's keys");
}

// Dimension values: a dict {name: value} over the nominal values, or one
// value per dimension in the model's order.
std::vector<double> valuesFrom(const PartModel& part, const py::handle& spec) {
  if (spec.is_none()) return part.nominalValues();
  if (py::isinstance<py::dict>(spec))
    return part.values(py::cast<std::map<std::string, double>>(spec));
  auto values = py::cast<std::vector<double>>(spec);
  if (values.size() != part.dimensions().size())
    throw Error(fmt::format("{} dimension values for the {} dimensions of {}", values.size(),
                            part.dimensions().size(), part.name()));
  part.validate(values);
  return values;
}

// Rendering -------------------------------------------------------------------

// The image of `part` at `values` and `pose` and, with `derivatives`, its
// derivative with respect to every dimension (model order) and to the pose's
// rx, ry, rz (deg; R = Rz Ry Rx) and x, y, z (mm), the image's as
// renderIntensityDerivatives gives them (xray/derivatives.h). Without a
// material: the path length (mm), without derivatives. The transmission
// table is `xgauge render`'s, so the image is that command's to the bit.
// `float64`: the image in double precision (no derivatives), for finite
// differences.
py::dict render(const py::object& part_spec, const py::object& values_spec,
                const py::object& pose_spec, const py::object& machine_spec,
                const py::object& material_spec, int samples, int edge_samples,
                std::optional<std::array<int, 4>> region, bool derivatives, bool float64,
                const fs::path& base_dir) {
  const PartModel part = partFrom(part_spec, base_dir);
  const std::vector<double> values = valuesFrom(part, values_spec);
  const Pose pose = poseFrom(pose_spec);
  const Machine machine = machineFrom(machine_spec);
  std::optional<ExponentialSum> material;
  if (!material_spec.is_none()) material = materialFrom(material_spec);
  if (derivatives && !material) throw Error("derivatives are of the intensity: give a material");
  if (derivatives && float64) throw Error("derivatives come with the float32 image");
  RenderOptions options;
  options.samples_per_axis = samples;
  options.edge_samples_per_axis = edge_samples;
  if (region) options.region = {(*region)[0], (*region)[1], (*region)[2], (*region)[3]};
  if (samples < 1 || samples > 16) throw Error("samples: 1 to 16 per axis");
  if (edge_samples != 0 && (edge_samples <= samples || edge_samples > 32))
    throw Error("edge_samples: 0 (off) or more than samples, up to 32");

  const TriangleMesh mesh = part.mesh(values);
  std::vector<Vec3> world;
  poseVertices(pose, mesh.vertices, world);
  if (auto why = outsideBeam(machine, world)) throw Error(*why + ": check the pose");
  if (auto why = shadowMissesDetector(machine, world))
    throw Error(*why + ": check the pose (the part must be in the beam)");
  const WorldMesh posed{world, mesh.triangles, mesh.csg.get()};

  std::vector<std::string> names;
  for (const Dimension& d : part.dimensions()) names.push_back(d.name);
  const size_t dims = names.size();
  Image image;
  ImageT<double> image64;
  IntensityDerivatives d;
  {
    py::gil_scoped_release release;
    if (!material) {
      if (float64)
        renderPathLength(machine, posed, options, image64);
      else
        renderPathLength(machine, posed, options, image);
    } else {
      const double longest = boundingBox(mesh).diagonal() + 1.0;  // as `xgauge render`
      const TransmissionTable table = TransmissionTable::forMaterial(*material, longest);
      if (float64) {
        renderIntensity(machine, posed, table, options, image64);
      } else if (!derivatives) {
        renderIntensity(machine, posed, table, options, image);
      } else {
        // Vertex velocities over (dimensions, rx, ry, rz, x, y, z) by central
        // differences of the vertex map (ForwardModel's steps).
        const Vec3 angles = pose.eulerDeg();
        std::vector<double> theta = values;
        for (int a = 0; a < 3; ++a) theta.push_back(angles[a]);
        for (int a = 0; a < 3; ++a) theta.push_back(pose.translation_mm[a]);
        std::vector<int> indices(theta.size());
        std::vector<double> steps(theta.size());
        for (size_t k = 0; k < theta.size(); ++k) {
          indices[k] = static_cast<int>(k);
          steps[k] = 1e-4 * std::max(1.0, std::abs(theta[k]));
        }
        std::vector<Vec3> part_vertices;
        const VertexMap map = [&](std::span<const double> t, std::vector<Vec3>& out) {
          if (part.tryEvaluate(t.first(dims), part_vertices)) return false;
          poseVertices(Pose::fromEulerDeg(Vec3(t[dims], t[dims + 1], t[dims + 2]),
                                          Vec3(t[dims + 3], t[dims + 4], t[dims + 5])),
                       part_vertices, out);
          return true;
        };
        std::vector<Vec3> velocities;
        if (!vertexVelocities(map, theta, indices, steps, velocities))
          throw Error(
              "no step of some dimension gives a part: derivatives need room around "
              "the values");
        renderIntensityDerivatives(machine, posed, table, options, velocities,
                                   static_cast<int>(theta.size()), d);
        image = std::move(d.intensity);
      }
    }
  }
  py::dict out;
  if (float64)
    out["image"] = toNumpy(std::move(image64));
  else
    out["image"] = toNumpy(std::move(image));
  if (derivatives) {
    py::dict by_dimension, by_pose;
    for (size_t k = 0; k < dims; ++k)
      by_dimension[py::str(names[k])] = toNumpy(std::move(d.per_parameter[k]));
    const char* pose_names[] = {"rx", "ry", "rz", "x", "y", "z"};
    for (size_t k = 0; k < 6; ++k)
      by_pose[py::str(pose_names[k])] = toNumpy(std::move(d.per_parameter[dims + k]));
    out["d_dimensions"] = by_dimension;
    out["d_pose"] = by_pose;
  }
  out["dimensions"] = py::cast(values);
  out["dimension_names"] = py::cast(names);
  return out;
}

// Progress --------------------------------------------------------------------

// Forwards the library's log messages (the stages as they run) to a Python
// callable(level, message) while it is installed (a scope).
class CallbackSink : public spdlog::sinks::base_sink<std::mutex> {
 public:
  explicit CallbackSink(py::object callback) : callback_(std::move(callback)) {}
  ~CallbackSink() override {
    py::gil_scoped_acquire gil;
    callback_ = py::object();
    error_.reset();
  }
  // The first exception the callback raised, re-raised once the call ends.
  void rethrow() {
    py::gil_scoped_acquire gil;
    if (error_) {
      auto error = std::move(error_);
      error->restore();
      throw py::error_already_set();
    }
  }

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    const std::string level(spdlog::level::to_string_view(msg.level).data(),
                            spdlog::level::to_string_view(msg.level).size());
    const std::string text(msg.payload.data(), msg.payload.size());
    py::gil_scoped_acquire gil;
    if (error_) return;
    try {
      callback_(level, text);
    } catch (py::error_already_set& e) {
      error_ = std::make_unique<py::error_already_set>(std::move(e));
    }
  }
  void flush_() override {}

 private:
  py::object callback_;
  std::unique_ptr<py::error_already_set> error_;
};

class ProgressScope {
 public:
  explicit ProgressScope(const py::object& callback) {
    if (callback.is_none()) return;
    sink_ = std::make_shared<CallbackSink>(callback);
    spdlog::default_logger()->sinks().push_back(sink_);
  }
  ~ProgressScope() { detach(); }
  void finish() {
    detach();
    if (sink_) sink_->rethrow();
  }

 private:
  void detach() {
    if (!sink_ || detached_) return;
    auto& sinks = spdlog::default_logger()->sinks();
    sinks.erase(std::remove(sinks.begin(), sinks.end(), sink_), sinks.end());
    detached_ = true;
  }
  std::shared_ptr<CallbackSink> sink_;
  bool detached_ = false;
};

// Measuring -------------------------------------------------------------------

// A measurement as `xgauge measure` makes it (apps/xgauge/measure_commands.cpp):
// the inputs, the model that measured, the result and the full-size
// simulated radiographs whose losses the result carries.
struct Measurement {
  std::unique_ptr<MeasurementInputs> inputs;
  std::unique_ptr<ForwardModel> model;
  MeasurementResult result;
  std::vector<Image> simulated;
};

std::unique_ptr<Measurement> measureJob(const py::object& job_spec, const fs::path& base_dir,
                                        const py::object& progress) {
  auto m = std::make_unique<Measurement>();
  std::optional<ConfigNode> root;
  fs::path job_file;
  if (isPath(job_spec)) {
    job_file = py::cast<fs::path>(job_spec);
  } else {
    root = configFrom(job_spec, "job");
    job_file = base_dir / "job.json";  // relative paths are the base folder's
  }
  ProgressScope scope(progress);
  {
    py::gil_scoped_release release;
    if (root) {
      m->inputs = std::make_unique<MeasurementInputs>(loadMeasurementInputs(*root, job_file, true));
      root->finish();
    } else {
      m->inputs = std::make_unique<MeasurementInputs>(loadMeasurementInputs(job_file));
    }
    m->model = std::make_unique<ForwardModel>(*m->inputs);
    // As the CLI: the full-size losses from the full-size simulation.
    MeasurementWithPictures measured = measureWithPictures(*m->model);
    m->result = std::move(measured.result);
    m->simulated = std::move(measured.simulated);
  }
  scope.finish();
  return m;
}

// Calibrating -----------------------------------------------------------------

// A calibration as `xgauge calibrate wedge|part JOB -o FOLDER [--truth T]`
// makes it (apps/xgauge/measure_commands.cpp): its outputs written into
// `folder`; after a failure the diagnostic written there and Error raised,
// naming the step.
void calibrate(const std::string& kind, const fs::path& job_file, const fs::path& folder,
               bool report, const std::optional<fs::path>& truth_file, const py::object& progress) {
  if (kind != "wedge" && kind != "part") throw Error("calibrate: kind 'wedge' or 'part'");
  checkOutputFolder(folder);
  TrueCurve truth;
  if (truth_file) {
    const DatasetTruth dataset = DatasetTruth::load(*truth_file);
    truth = {dataset.path_mm, dataset.transmission};
  }
  const auto failed = [&](const std::string& step, const Error& e) {
    return Error(fmt::format("the calibration failed at its step \"{}\": {} (what it found: {})",
                             step, e.message(), folder.string()),
                 e.where());
  };
  ProgressScope scope(progress);
  {
    py::gil_scoped_release release;
    if (kind == "wedge") {
      const WedgeCalibrationJob job = WedgeCalibrationJob::load(job_file);
      WedgeCalibration result;
      try {
        calibrateFromWedge(job, result);
      } catch (const Error& e) {
        writeFailedWedgeCalibration(job, result, e.what(), folder, report);
        throw failed(result.step, e);
      }
      writeWedgeCalibration(job, result, truth, folder, report);
    } else {
      const PartCalibrationJob job = PartCalibrationJob::load(job_file);
      PartCalibration result;
      try {
        calibrateFromPart(job, result);
      } catch (const Error& e) {
        writeFailedPartCalibration(job, result, e.what(), folder, report);
        throw failed(result.step, e);
      }
      writePartCalibration(job, result, truth, folder, report);
    }
  }
  scope.finish();
}

// Simulating ------------------------------------------------------------------

py::dict simulate(const fs::path& recipe_file, const fs::path& folder, const py::object& progress) {
  const Recipe recipe = Recipe::load(recipe_file);
  ProgressScope scope(progress);
  DatasetReport report;
  {
    py::gil_scoped_release release;
    report = simulateDataset(recipe, folder);
  }
  scope.finish();
  py::dict out;
  out["shots"] = report.shots;
  out["seconds"] = report.seconds;
  out["white_region"] = py::make_tuple(report.white_region.x, report.white_region.y,
                                       report.white_region.width, report.white_region.height);
  return out;
}

}  // namespace
}  // namespace xgauge::python

PYBIND11_MODULE(_xgauge, m) {
  using namespace xgauge;
  using namespace xgauge::python;
  m.doc() = "xgauge's library: TIFF I/O, the renderer and its derivatives, measurements";
  m.attr("__version__") = XGAUGE_VERSION_STRING;
  py::register_exception<Error>(m, "Error", PyExc_ValueError);
  // The CLI's logging: messages on stderr, info and above.
  setupLogging(Verbosity::kNormal);
  m.def(
      "set_log_level",
      [](const std::string& level) {
        const auto found = spdlog::level::from_str(level);
        if (level != "off" && found == spdlog::level::off)
          throw Error(fmt::format("log level '{}': debug, info, warning, error or off", level));
        spdlog::default_logger()->set_level(found);
        // Progress bars (stderr, on a terminal only) go with the messages.
        setProgressEnabled(found <= spdlog::level::info);
      },
      py::arg("level"),
      "The least level of a message that is shown on stderr and passed to a progress callback");

  m.def(
      "read_radiograph",
      [](const fs::path& path) {
        RadiographFile file;
        {
          py::gil_scoped_release release;
          file = readRadiograph(path);
        }
        return py::make_tuple(toNumpy(std::move(file.image)), file.frames, toString(file.format));
      },
      py::arg("path"),
      "A radiograph file of any format xgauge reads (TIFF, raw + sidecar, NXtomo with a "
      "'#selector', DICONDE) as (image float32 (rows, columns), frames averaged, format name)");
  m.def(
      "read_tiff",
      [](const fs::path& path) {
        RadiographFile file;
        {
          py::gil_scoped_release release;
          file = readRadiograph(path);
        }
        return toNumpy(std::move(file.image));
      },
      py::arg("path"),
      "A radiograph as float32 (rows, columns), without a copy: a TIFF (one page, or the mean of "
      "its pages), or any other format read_radiograph reads");
  m.def(
      "write_tiff",
      [](const fs::path& path,
         const py::array_t<float, py::array::c_style | py::array::forcecast>& a,
         const std::string& format) {
        if (format != "f32" && format != "u16") throw Error("format: 'f32' or 'u16'");
        const Image image = fromNumpy(a);
        py::gil_scoped_release release;
        writeTiff(path, image, format == "f32" ? TiffFormat::kFloat32 : TiffFormat::kUInt16);
      },
      py::arg("path"), py::arg("image"), py::arg("format") = "f32");
  m.def("render", &render, py::arg("part"), py::arg("dimensions"), py::arg("pose"),
        py::arg("machine"), py::arg("material"), py::arg("samples"), py::arg("edge_samples"),
        py::arg("region"), py::arg("derivatives"), py::arg("float64"), py::arg("base_dir"));
  m.def("calibrate", &xgauge::python::calibrate, py::arg("kind"), py::arg("job"), py::arg("output"),
        py::arg("report"), py::arg("truth"), py::arg("progress"));
  m.def("simulate", &simulate, py::arg("recipe"), py::arg("output"), py::arg("progress"));
  m.def(
      "plan",
      [](const fs::path& job, const fs::path& output) {
        PlanSummary summary;
        {
          py::gil_scoped_release release;
          summary = xgauge::plan({job, output});
        }
        if (summary.termination != RunTermination::kDone) throw Error(summary.message);
        return summary.report;
      },
      py::arg("job"), py::arg("output"),
      "The front door's view plan (xgauge/xgauge.h): plan.json, job.json and report.html into "
      "`output`; returns the table `xgauge plan` prints");

  py::class_<Measurement>(m, "Measurement")
      .def("to_json",
           [](const Measurement& self) {
             return measurementJson(*self.model, self.result).dump(2) + "\n";
           })
      .def_property_readonly("theta",
                             [](const Measurement& self) {
                               return py::array_t<double>(
                                   static_cast<py::ssize_t>(self.result.theta.size()),
                                   self.result.theta.data());
                             })
      .def_property_readonly("simulated",
                             [](py::object self) {
                               const auto& me = self.cast<const Measurement&>();
                               py::list out;
                               for (const Image& image : me.simulated) {
                                 py::array_t<float> view({static_cast<py::ssize_t>(image.height()),
                                                          static_cast<py::ssize_t>(image.width())},
                                                         image.pixels().data(), self);
                                 view.attr("flags").attr("writeable") = false;  // the object's own
                                 out.append(view);
                               }
                               return out;
                             })
      .def(
          "write_outputs",
          [](Measurement& self, const fs::path& folder, bool report) {
            py::gil_scoped_release release;
            writeMeasurementOutputs(*self.model, self.result, folder, report, nullptr,
                                    self.simulated);
          },
          py::arg("folder"), py::arg("report") = true);
  m.def("measure", &measureJob, py::arg("job"), py::arg("base_dir"), py::arg("progress"));
}
