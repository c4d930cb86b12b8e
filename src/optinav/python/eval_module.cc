// optinav.eval: ape() and rpe() over app::RunEvaluation, the code of `optinav eval`.
#include <optional>
#include <string>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "optinav/app/evaluation.h"
#include "optinav/io/trajectory_io.h"
#include "optinav/python/convert.h"

namespace optinav::python {
namespace {

using app::EvaluationSettings;

// The keyword arguments of ape() and rpe(); the names are the CLI's flags.
struct EvalArgs {
  std::string align = "none", pose_relation = "trans", ref_format = "auto", est_format = "auto";
  double max_diff = 0.01, t_offset = 0;
  std::optional<size_t> n_to_align;
  bool align_origin = false;
  py::object ref_times, est_times, json, plot, save_aligned;
  std::string plot_plane = "xy";
  // rpe only
  double delta = 1.0;
  std::string unit = "frames";
  bool all_pairs = false;
  double rel_delta_tol = 0.1;
};

std::string OptionalPath(const py::object& path) { return path.is_none() ? "" : ToPath(path); }

// A trajectory argument: a file, an array of rows or a dict of EuRoC arrays. `*label` becomes
// the file's path (the JSON's "ref"/"est"), empty for arrays.
Trajectory ToTrajectory(const py::object& value, const std::string& name,
                        const io::TrajectoryReadOptions& read, std::string* label) {
  if (IsPath(value)) {
    *label = ToPath(value);
    py::gil_scoped_release release;
    return io::ReadTrajectory(*label, read);
  }
  label->clear();
  const std::string source = name + " array";
  if (!read.kitti_times_path.empty()) {
    throw py::value_error(name +
                          "_times: a times file only applies to a KITTI file, not to an "
                          "array (give N x 8 TUM rows with times instead)");
  }
  if (py::isinstance<py::dict>(value)) {
    const py::dict d = value.cast<py::dict>();
    for (const char* key : {"t_ns", "position", "quaternion_wxyz"}) {
      if (!d.contains(key)) {
        throw py::value_error(name +
                              ": a dict trajectory needs t_ns, position and "
                              "quaternion_wxyz (as optinav.io.read_euroc gives)");
      }
    }
    const auto t =
        py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(d["t_ns"]);
    const auto p =
        py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(d["position"]);
    const auto q = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(
        d["quaternion_wxyz"]);
    if (!t || !p || !q || t.ndim() != 1 || p.ndim() != 2 || q.ndim() != 2 || p.shape(1) != 3 ||
        q.shape(1) != 4 || p.shape(0) != t.shape(0) || q.shape(0) != t.shape(0)) {
      throw py::value_error(name +
                            ": t_ns must have shape (N,), position (N, 3) and "
                            "quaternion_wxyz (N, 4)");
    }
    const size_t n = t.shape(0);
    std::vector<double> rows(7 * n);
    for (size_t i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) rows[7 * i + k] = p.at(i, k);
      for (int k = 0; k < 4; ++k) rows[7 * i + 3 + k] = q.at(i, k);
    }
    return io::TrajectoryFromEurocRows(t.data(), rows.data(), n, source);
  }
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(value);
  if (!a) throw py::type_error(name + ": expected a path, an array or a dict of arrays");
  const size_t columns = a.ndim() == 2 ? a.shape(1) : 0;
  const bool tum = columns == 8 && read.format != io::TrajectoryFormat::kKitti &&
                   read.format != io::TrajectoryFormat::kEuroc;
  const bool kitti = columns == 12 && (read.format == io::TrajectoryFormat::kAuto ||
                                       read.format == io::TrajectoryFormat::kKitti);
  if (!tum && !kitti) {
    std::string shape = "(";
    for (py::ssize_t k = 0; k < a.ndim(); ++k)
      shape += (k ? ", " : "") + std::to_string(a.shape(k));
    throw py::value_error(name +
                          ": an array must be N x 8 TUM rows (t x y z qx qy qz qw) or N x 12 "
                          "KITTI rows (3x4 pose, row-major), with " +
                          name + "_format auto or that format; got shape " + shape + ")");
  }
  return tum ? io::TrajectoryFromTumRows(a.data(), a.shape(0), source)
             : io::TrajectoryFromKittiRows(a.data(), a.shape(0), source);
}

// The settings of the arguments, checked with the messages of `optinav eval` (ValueError).
EvaluationSettings Settings(EvaluationSettings::Metric metric, const EvalArgs& a) {
  EvaluationSettings st;
  st.metric = metric;
  const auto format = [](const std::string& name, const char* flag) {
    const auto f = io::ParseTrajectoryFormat(name);
    if (!f)
      throw py::value_error(std::string(flag) + ": unknown format '" + name +
                            "' (auto|tum|kitti|euroc)");
    return *f;
  };
  st.ref_read.format = format(a.ref_format, "ref_format");
  st.est_read.format = format(a.est_format, "est_format");
  st.ref_read.kitti_times_path = OptionalPath(a.ref_times);
  st.est_read.kitti_times_path = OptionalPath(a.est_times);
  st.association.max_diff_s = a.max_diff;
  st.association.t_offset_s = a.t_offset;
  const auto align = eval::ParseAlignMode(a.align);
  if (!align) {
    throw py::value_error("align: unknown mode '" + a.align + "' (none|se3|sim3|scale|posyaw)");
  }
  st.alignment.mode = *align;
  st.alignment.n_to_align = a.n_to_align.value_or(0);
  st.alignment.align_origin = a.align_origin;
  const auto relation = eval::ParsePoseRelation(a.pose_relation);
  if (!relation) {
    throw py::value_error("pose_relation: unknown relation '" + a.pose_relation +
                          "' (trans|rot|full|angle_deg|angle_rad)");
  }
  st.relation = *relation;
  st.json_path = OptionalPath(a.json);
  st.plot_path = OptionalPath(a.plot);
  st.plot_plane = a.plot_plane;
  st.aligned_out_path = OptionalPath(a.save_aligned);
  if (metric == EvaluationSettings::Metric::kRpe) {
    st.rpe.delta = a.delta;
    const auto unit = eval::ParseDeltaUnit(a.unit);
    if (!unit) throw py::value_error("unit: unknown unit '" + a.unit + "' (frames|m|s|rad|deg)");
    st.rpe.unit = *unit;
    st.rpe.all_pairs = a.all_pairs;
    st.rpe.rel_delta_tol = a.rel_delta_tol;
  }
  RaiseIfInvalid(st.Check());
  return st;
}

py::dict Evaluate(EvaluationSettings::Metric metric, const py::object& ref, const py::object& est,
                  const EvalArgs& args) {
  EvaluationSettings st = Settings(metric, args);
  Trajectory ref_traj = ToTrajectory(ref, "ref", st.ref_read, &st.ref_path);
  Trajectory est_traj = ToTrajectory(est, "est", st.est_read, &st.est_path);
  app::EvaluationOutcome outcome;
  {
    py::gil_scoped_release release;
    outcome = app::RunEvaluation(st, std::move(ref_traj), std::move(est_traj));
  }
  return JsonToPython(outcome.json).cast<py::dict>();
}

constexpr const char* kTrajectoryDoc = R"(
ref, est: a trajectory file (str or path; format detected as by the CLI, or given by
  ref_format/est_format: tum, kitti, euroc), or a float array of rows: N x 8 TUM rows
  (t [s], x, y, z, qx, qy, qz, qw; times in seconds as in a TUM file) or N x 12 KITTI rows (the
  3x4 world_from_camera pose, row-major; no times: association by index), or a dict with
  t_ns (int64, N), position (N x 3) and quaternion_wxyz (N x 4) as optinav.io.read_euroc's
  ground truth. Arrays are checked as files are; errors name 'ref array' and the 1-based row.
Keywords are the flags of `optinav eval` (docs/EVALUATION.md) with the same defaults:
  align none|se3|sim3|scale|posyaw, n_to_align (None: all pairs), align_origin,
  pose_relation trans|rot|full|angle_deg|angle_rad, max_diff (s), t_offset (s),
  ref_times/est_times (KITTI times files), and optional outputs json, plot (+ plot_plane),
  save_aligned (paths, written atomically).
Returns the statistics dict of `--json` (rmse, mean, median, std, min, max, sse, n, alignment,
association, ...); "ref"/"est" are the paths, None for arrays.
Raises optinav.Error on bad input (message names file/array and line/row), ValueError on invalid
options (the CLI's message).)";

const std::string& ApeDoc() {
  static const std::string doc =
      std::string("Absolute pose error (`optinav eval ape`).\n") + kTrajectoryDoc;
  return doc;
}

const std::string& RpeDoc() {
  static const std::string doc =
      std::string(
          "Relative pose error (`optinav eval rpe`): delta with unit frames|m|s|rad|deg, "
          "all_pairs and rel_delta_tol as the CLI's flags.\n") +
      kTrajectoryDoc;
  return doc;
}

// The arguments ape and rpe share, as EvalArgs (rpe adds its own four).
EvalArgs CommonArgs(const std::string& align, const std::string& pose_relation, double max_diff,
                    double t_offset, std::optional<size_t> n_to_align, bool align_origin,
                    const std::string& ref_format, const std::string& est_format,
                    const py::object& ref_times, const py::object& est_times,
                    const py::object& json, const py::object& plot, const std::string& plot_plane,
                    const py::object& save_aligned) {
  EvalArgs a;
  a.align = align;
  a.pose_relation = pose_relation;
  a.max_diff = max_diff;
  a.t_offset = t_offset;
  a.n_to_align = n_to_align;
  a.align_origin = align_origin;
  a.ref_format = ref_format;
  a.est_format = est_format;
  a.ref_times = ref_times;
  a.est_times = est_times;
  a.json = json;
  a.plot = plot;
  a.plot_plane = plot_plane;
  a.save_aligned = save_aligned;
  return a;
}

}  // namespace

void DefineEval(py::module_& m) {
  const auto ape = [](const py::object& ref, const py::object& est, const std::string& align,
                      const std::string& pose_relation, double max_diff, double t_offset,
                      std::optional<size_t> n_to_align, bool align_origin,
                      const std::string& ref_format, const std::string& est_format,
                      const py::object& ref_times, const py::object& est_times,
                      const py::object& json, const py::object& plot, const std::string& plot_plane,
                      const py::object& save_aligned) {
    return Evaluate(
        EvaluationSettings::Metric::kApe, ref, est,
        CommonArgs(align, pose_relation, max_diff, t_offset, n_to_align, align_origin, ref_format,
                   est_format, ref_times, est_times, json, plot, plot_plane, save_aligned));
  };
  m.def("ape", ape, py::arg("ref"), py::arg("est"), py::kw_only(), py::arg("align") = "none",
        py::arg("pose_relation") = "trans", py::arg("max_diff") = 0.01, py::arg("t_offset") = 0.0,
        py::arg("n_to_align") = py::none(), py::arg("align_origin") = false,
        py::arg("ref_format") = "auto", py::arg("est_format") = "auto",
        py::arg("ref_times") = py::none(), py::arg("est_times") = py::none(),
        py::arg("json") = py::none(), py::arg("plot") = py::none(), py::arg("plot_plane") = "xy",
        py::arg("save_aligned") = py::none(), ApeDoc().c_str());

  const auto rpe = [](const py::object& ref, const py::object& est, double delta,
                      const std::string& unit, bool all_pairs, double rel_delta_tol,
                      const std::string& align, const std::string& pose_relation, double max_diff,
                      double t_offset, std::optional<size_t> n_to_align, bool align_origin,
                      const std::string& ref_format, const std::string& est_format,
                      const py::object& ref_times, const py::object& est_times,
                      const py::object& json, const py::object& plot, const std::string& plot_plane,
                      const py::object& save_aligned) {
    EvalArgs a =
        CommonArgs(align, pose_relation, max_diff, t_offset, n_to_align, align_origin, ref_format,
                   est_format, ref_times, est_times, json, plot, plot_plane, save_aligned);
    a.delta = delta;
    a.unit = unit;
    a.all_pairs = all_pairs;
    a.rel_delta_tol = rel_delta_tol;
    return Evaluate(EvaluationSettings::Metric::kRpe, ref, est, a);
  };
  m.def("rpe", rpe, py::arg("ref"), py::arg("est"), py::kw_only(), py::arg("delta") = 1.0,
        py::arg("unit") = "frames", py::arg("all_pairs") = false, py::arg("rel_delta_tol") = 0.1,
        py::arg("align") = "none", py::arg("pose_relation") = "trans", py::arg("max_diff") = 0.01,
        py::arg("t_offset") = 0.0, py::arg("n_to_align") = py::none(),
        py::arg("align_origin") = false, py::arg("ref_format") = "auto",
        py::arg("est_format") = "auto", py::arg("ref_times") = py::none(),
        py::arg("est_times") = py::none(), py::arg("json") = py::none(),
        py::arg("plot") = py::none(), py::arg("plot_plane") = "xy",
        py::arg("save_aligned") = py::none(), RpeDoc().c_str());
}

}  // namespace optinav::python
