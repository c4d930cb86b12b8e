#include "optinav/sim/sensors.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <fmt/format.h>

#include "optinav/util/error.h"

namespace optinav::sim {
namespace {

Eigen::Vector3d Gaussian3(std::mt19937_64& rng, double sigma) {
  std::normal_distribution<double> n(0.0, 1.0);
  const double x = n(rng), y = n(rng), z = n(rng);
  return sigma * Eigen::Vector3d(x, y, z);
}

std::pair<double, double> ParsePair(const std::string& text, const std::string& field,
                                    const char* layout) {
  const size_t colon = text.find(':');
  auto bad = [&] {
    return Error(fmt::format("expected {}, got '{}'", layout, text), {.field = field});
  };
  if (colon == std::string::npos) throw bad();
  try {
    size_t n1 = 0, n2 = 0;
    const std::string a = text.substr(0, colon), b = text.substr(colon + 1);
    const double x = std::stod(a, &n1), y = std::stod(b, &n2);
    if (n1 != a.size() || n2 != b.size() || !std::isfinite(x) || !std::isfinite(y)) throw bad();
    return {x, y};
  } catch (const std::logic_error&) {
    throw bad();
  }
}

}  // namespace

std::string ImuOptions::Check() const {
  if (!(rate_hz > 0 && rate_hz <= 10000))
    return fmt::format("imu rate_hz {} not in (0, 10000]", rate_hz);
  for (const auto& [name, v] : {std::pair{"gyroscope_noise_density", gyroscope_noise_density},
                                {"gyroscope_random_walk", gyroscope_random_walk},
                                {"accelerometer_noise_density", accelerometer_noise_density},
                                {"accelerometer_random_walk", accelerometer_random_walk},
                                {"initial_gyro_bias_sigma", initial_gyro_bias_sigma},
                                {"initial_accel_bias_sigma", initial_accel_bias_sigma}}) {
    if (!(v >= 0) || !std::isfinite(v)) return fmt::format("imu {} = {} must be >= 0", name, v);
  }
  return "";
}

ImuSensor::ImuSensor(const ImuOptions& options, uint64_t seed)
    : options_(options), rng_(seed ^ 0x1a2b3c4d5e6f7788ull) {
  const double dt = 1.0 / options.rate_hz;
  if (!options.noise_free) {
    bg_ = Gaussian3(rng_, options.initial_gyro_bias_sigma);
    ba_ = Gaussian3(rng_, options.initial_accel_bias_sigma);
  }
  sg_ = options.gyroscope_noise_density * std::sqrt(options.rate_hz);
  sa_ = options.accelerometer_noise_density * std::sqrt(options.rate_hz);
  wg_ = options.gyroscope_random_walk * std::sqrt(dt);
  wa_ = options.accelerometer_random_walk * std::sqrt(dt);
}

ImuMeasurement ImuSensor::Measure(const BodyState& s) {
  ImuMeasurement m;
  m.t_ns = s.t_ns;
  m.gyro_rad_s = s.angular_velocity_in_body;
  m.accel_m_s2 = s.world_from_body.rotation.conjugate() *
                 (s.acceleration_in_world + Eigen::Vector3d(0, 0, kGravity));
  if (!options_.noise_free) {
    m.gyro_rad_s += bg_ + Gaussian3(rng_, sg_);
    m.accel_m_s2 += ba_ + Gaussian3(rng_, sa_);
    m.gyro_bias = bg_;
    m.accel_bias = ba_;
    bg_ += Gaussian3(rng_, wg_);
    ba_ += Gaussian3(rng_, wa_);
  }
  return m;
}

std::vector<ImuMeasurement> SimulateImu(const BodyTrajectory& trajectory, const ImuOptions& options,
                                        uint64_t seed) {
  ImuSensor sensor(options, seed);
  const double dt = 1.0 / options.rate_hz;
  std::vector<ImuMeasurement> out;
  for (int64_t k = 0;; ++k) {
    const int64_t t = trajectory.start_ns() + static_cast<int64_t>(std::llround(k * dt * 1e9));
    if (t > trajectory.end_ns()) break;
    BodyState s = trajectory.At(t);
    s.t_ns = t;
    out.push_back(sensor.Measure(s));
  }
  return out;
}

std::string BaroOptions::Check() const {
  if (!(rate_hz >= 0.1 && rate_hz <= 1000)) {
    return fmt::format("barometer rate {} Hz not in [0.1, 1000]", rate_hz);
  }
  for (const auto& [name, v] : {std::pair{"noise_sigma_m", noise_sigma_m},
                                {"initial_bias_sigma_m", initial_bias_sigma_m},
                                {"bias_random_walk", bias_random_walk}}) {
    if (!(v >= 0) || !std::isfinite(v))
      return fmt::format("barometer {} = {} must be >= 0", name, v);
  }
  if (!(noise_sigma_m > 0)) return "barometer noise_sigma_m must be > 0";
  return "";
}

BaroSensor::BaroSensor(const BaroOptions& options, uint64_t seed)
    : options_(options), rng_(seed ^ 0x5b4a3c2d1e0f9687ull) {
  bias_ = options.initial_bias_sigma_m * normal_(rng_);
  walk_ = options.bias_random_walk * std::sqrt(1.0 / options.rate_hz);
}

BaroMeasurement BaroSensor::Measure(int64_t t_ns, double z) {
  const BaroMeasurement m{t_ns, z + bias_ + options_.noise_sigma_m * normal_(rng_), bias_};
  bias_ += walk_ * normal_(rng_);
  return m;
}

std::vector<BaroMeasurement> SimulateBaro(const BodyTrajectory& trajectory,
                                          const BaroOptions& options, uint64_t seed) {
  BaroSensor sensor(options, seed);
  const double dt = 1.0 / options.rate_hz;
  std::vector<BaroMeasurement> out;
  for (int64_t k = 0;; ++k) {
    const int64_t t = trajectory.start_ns() + static_cast<int64_t>(std::llround(k * dt * 1e9));
    if (t > trajectory.end_ns()) break;
    out.push_back(sensor.Measure(t, trajectory.At(t).world_from_body.translation.z()));
  }
  return out;
}

std::string GnssOptions::Check() const {
  if (!(rate_hz >= 0.1 && rate_hz <= 100)) {
    return fmt::format("--gnss-rate {} Hz not in [0.1, 100]", rate_hz);
  }
  if (!(sigma_m >= 0 && std::isfinite(sigma_m))) return fmt::format("--gnss-sigma {} < 0", sigma_m);
  if (!(outlier_fraction >= 0 && outlier_fraction <= 1)) {
    return fmt::format("--gnss-outliers fraction {} not in [0, 1]", outlier_fraction);
  }
  if (!(outlier_magnitude_m >= 0)) {
    return fmt::format("--gnss-outliers magnitude {} m < 0", outlier_magnitude_m);
  }
  if (!(outlier_magnitude_max_m >= 0 && std::isfinite(outlier_magnitude_max_m))) {
    return fmt::format("outlier_magnitude_max_m {} < 0", outlier_magnitude_max_m);
  }
  if (!(first_sample_s >= 0 && std::isfinite(first_sample_s))) {
    return fmt::format("first_sample_s {} < 0", first_sample_s);
  }
  for (const GnssOutage& o : outages) {
    if (!(o.start_s >= 0 && o.duration_s > 0)) {
      return fmt::format("--gnss-outage {}:{} needs start >= 0 and duration > 0", o.start_s,
                         o.duration_s);
    }
  }
  if (!(std::abs(origin.lat_deg) <= 90 && std::abs(origin.lon_deg) <= 180)) {
    return fmt::format("origin {},{} is not a latitude/longitude", origin.lat_deg, origin.lon_deg);
  }
  return "";
}

namespace {

// One epoch's random draws.
struct GnssEpochDraw {
  Eigen::Vector3d noise_m = Eigen::Vector3d::Zero();
  bool outlier = false;
  Eigen::Vector3d outlier_offset_m = Eigen::Vector3d::Zero();
};

// GnssDraws::kSingleStream.
class SingleStreamDraws {
 public:
  SingleStreamDraws(const GnssOptions& o, uint64_t seed)
      : o_(o), rng_(seed ^ 0x9e3779b97f4a7c15ull) {}

  GnssEpochDraw Next() {
    GnssEpochDraw d;
    d.noise_m = Gaussian3(rng_, o_.sigma_m);
    const bool outlier = u01_(rng_) < o_.outlier_fraction;
    const Eigen::Vector3d dir = Gaussian3(rng_, 1.0);
    double magnitude = o_.outlier_magnitude_m;
    if (o_.outlier_magnitude_max_m > magnitude)
      magnitude += (o_.outlier_magnitude_max_m - magnitude) * u01_(rng_);
    if (outlier && dir.norm() > 1e-9) {
      d.outlier = true;
      d.outlier_offset_m = magnitude * dir.normalized();
    }
    return d;
  }

 private:
  const GnssOptions& o_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> u01_{0, 1};
};

// GnssDraws::kNoiseAndOutlierStreams.
class TwoStreamDraws {
 public:
  TwoStreamDraws(const GnssOptions& o, uint64_t seed)
      : o_(o), noise_rng_(1000 + seed), outlier_rng_(5000 + seed) {}

  GnssEpochDraw Next() {
    GnssEpochDraw d;
    // Components drawn z, y, x: the order in which GCC evaluated the Eigen::Vector3d constructor
    // arguments of the benchmark's original generator (the same normal_distribution caches its
    // second deviate, so the order also decides which stream a cached deviate came from).
    const Eigen::Vector3d noise = Normal3(noise_rng_);
    d.outlier = o_.outlier_fraction > 0 && u01_(outlier_rng_) < o_.outlier_fraction;
    const Eigen::Vector3d dir = Normal3(outlier_rng_);
    const double low = o_.outlier_magnitude_m;
    const double magnitude =
        low + (std::max(o_.outlier_magnitude_max_m, low) - low) * u01_(outlier_rng_);
    d.noise_m = o_.sigma_m * noise;
    if (d.outlier) d.outlier_offset_m = dir.normalized() * magnitude;
    return d;
  }

 private:
  Eigen::Vector3d Normal3(std::mt19937& rng) {
    const double z = normal_(rng), y = normal_(rng), x = normal_(rng);
    return {x, y, z};
  }

  const GnssOptions& o_;
  std::mt19937 noise_rng_, outlier_rng_;
  std::normal_distribution<double> normal_;
  std::uniform_real_distribution<double> u01_{0.0, 1.0};
};

template <typename Draws>
std::vector<GnssMeasurement> SimulateGnssWith(Draws draws, const PoseAtTime& world_from_body,
                                              int64_t start_ns, int64_t end_ns,
                                              const GnssOptions& options) {
  const geo::LocalEnu enu(options.origin, options.origin_height_m);
  std::vector<GnssMeasurement> out;
  const double dt = 1.0 / options.rate_hz;
  const int64_t first_ns =
      start_ns + static_cast<int64_t>(std::llround(options.first_sample_s * 1e9));
  for (int64_t k = 0;; ++k) {
    const double t_s = options.first_sample_s + k * dt;
    const int64_t t = first_ns + static_cast<int64_t>(std::llround(k * dt * 1e9));
    if (t > end_ns) break;
    // Drawn for every epoch, so outages do not shift the noise of later samples.
    const GnssEpochDraw d = draws.Next();
    bool in_outage = false;
    for (const GnssOutage& o : options.outages) {
      in_outage |= t_s >= o.start_s && t_s < o.start_s + o.duration_s;
    }
    if (in_outage) continue;
    const std::optional<Rigid3d> pose = world_from_body(t);
    if (!pose) continue;
    GnssMeasurement m;
    m.t_ns = t;
    m.position_enu_m = *pose * options.lever_arm_in_body + d.noise_m;
    if (d.outlier) {
      m.position_enu_m += d.outlier_offset_m;
      m.outlier = true;
    }
    const geo::LatLon ll = enu.FromEnu(m.position_enu_m, &m.height_m);
    m.lat_deg = ll.lat_deg;
    m.lon_deg = ll.lon_deg;
    out.push_back(m);
  }
  return out;
}

}  // namespace

std::vector<GnssMeasurement> SimulateGnss(const PoseAtTime& world_from_body, int64_t start_ns,
                                          int64_t end_ns, const GnssOptions& options,
                                          uint64_t seed) {
  switch (options.draws) {
    case GnssDraws::kSingleStream:
      return SimulateGnssWith(SingleStreamDraws(options, seed), world_from_body, start_ns, end_ns,
                              options);
    case GnssDraws::kNoiseAndOutlierStreams:
      return SimulateGnssWith(TwoStreamDraws(options, seed), world_from_body, start_ns, end_ns,
                              options);
  }
  return {};
}

std::vector<GnssMeasurement> SimulateGnss(const BodyTrajectory& trajectory,
                                          const GnssOptions& options, uint64_t seed) {
  return SimulateGnss(
      [&](int64_t t_ns) -> std::optional<Rigid3d> { return trajectory.At(t_ns).world_from_body; },
      trajectory.start_ns(), trajectory.end_ns(), options, seed);
}

std::pair<double, double> ParseOutlierSpec(const std::string& text, const std::string& field) {
  return ParsePair(text, field, "FRACTION:MAGNITUDE_M, e.g. 0.05:20");
}

GnssOutage ParseOutageSpec(const std::string& text, const std::string& field) {
  const auto [a, b] = ParsePair(text, field, "START_S:DURATION_S, e.g. 30:10");
  return {a, b};
}

}  // namespace optinav::sim
