// IMU and GNSS measurements of a BodyTrajectory.
//
// IMU (frame = body frame): gyro = omega_body + b_g + n_g, accel = R^T (a + g e_z) + b_a + n_a,
// with white noise of the given continuous-time densities (sigma_discrete = density * sqrt(rate))
// and biases following a random walk (sigma per step = random_walk * sqrt(dt)), the Kalibr/EuRoC
// noise model. Defaults are EuRoC's ADIS16448 figures.
// GNSS: the antenna (at a lever arm in the body frame) in local ENU with Gaussian noise, optional
// outliers and outage windows, also as WGS84 latitude/longitude/ellipsoidal height about the
// origin of the ENU frame. The body pose comes from a BodyTrajectory (`optinav sim`) or from any
// pose-at-time function (`optinav bench gnss` samples a recorded ground truth).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "optinav/geo/geo.h"
#include "optinav/sim/trajectory.h"

namespace optinav::sim {

struct ImuOptions {
  double rate_hz = 200.0;
  double gyroscope_noise_density = 1.6968e-4;   // rad / s / sqrt(Hz)
  double gyroscope_random_walk = 1.9393e-5;     // rad / s^2 / sqrt(Hz)
  double accelerometer_noise_density = 2.0e-3;  // m / s^2 / sqrt(Hz)
  double accelerometer_random_walk = 3.0e-3;    // m / s^3 / sqrt(Hz)
  double initial_gyro_bias_sigma = 2e-3;        // rad/s, per axis
  double initial_accel_bias_sigma = 2e-2;       // m/s^2, per axis
  bool noise_free = false;                      // exact measurements, zero biases
  // Empty when valid, else the offending field and value.
  std::string Check() const;
};

struct ImuMeasurement {
  int64_t t_ns = 0;
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d::Zero();
  // The true biases at this sample (written to the ground truth).
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();
};

// The IMU's noise and biases sample by sample, for trajectories that are not known in advance
// (the closed-loop flights of `optinav mission --estimator nav`). SimulateImu draws the same
// numbers: a sensor fed the same states gives the same measurements.
class ImuSensor {
 public:
  ImuSensor(const ImuOptions& options, uint64_t seed);
  // The measurement of the state at its time (call at the options' rate, in time order).
  ImuMeasurement Measure(const BodyState& state);

 private:
  ImuOptions options_;
  std::mt19937_64 rng_;
  Eigen::Vector3d bg_ = Eigen::Vector3d::Zero(), ba_ = Eigen::Vector3d::Zero();
  double sg_ = 0, sa_ = 0, wg_ = 0, wa_ = 0;
};

// Samples at start + k / rate for every k with t <= end.
std::vector<ImuMeasurement> SimulateImu(const BodyTrajectory& trajectory, const ImuOptions& options,
                                        uint64_t seed);

// Barometer: altitude = z of the body in the world frame + bias + white noise, the bias drifting
// as a random walk (sigma per step = random_walk * sqrt(dt)) from an initial Gaussian draw.
// Defaults: a MEMS barometer (MS5611 class) after its usual filtering.
struct BaroOptions {
  bool enabled = false;  // `optinav sim` turns it on for drone routes
  double rate_hz = 20.0;
  double noise_sigma_m = 0.3;  // white noise per sample
  double initial_bias_sigma_m = 2.0;
  double bias_random_walk = 0.02;  // m / sqrt(s): about 0.5 m of drift in 10 minutes
  std::string Check() const;
};

struct BaroMeasurement {
  int64_t t_ns = 0;
  double altitude_m = 0;
  double bias_m = 0;  // the true bias at this sample
};

// The barometer sample by sample (as ImuSensor); SimulateBaro draws the same numbers.
class BaroSensor {
 public:
  BaroSensor(const BaroOptions& options, uint64_t seed);
  // The measurement of a body at height z (world) at time t (call at the options' rate).
  BaroMeasurement Measure(int64_t t_ns, double z);

 private:
  BaroOptions options_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  double bias_ = 0, walk_ = 0;
};

// Samples at start + k / rate for every k with t <= end.
std::vector<BaroMeasurement> SimulateBaro(const BodyTrajectory& trajectory,
                                          const BaroOptions& options, uint64_t seed);

struct GnssOutage {
  double start_s = 0, duration_s = 0;  // seconds after the start of the trajectory
};

// How the random numbers are drawn. Both schemes draw every epoch's noise, outlier decision and
// outlier offset also inside outages, so the noise of a sample depends only on its epoch and the
// seed: runs that differ only by outages (or by the outlier fraction) share their noise (common
// random numbers).
enum class GnssDraws {
  // One std::mt19937_64 stream seeded from `seed`: per epoch the noise, the outlier decision,
  // the outlier direction (and magnitude, for a magnitude range). `optinav sim`.
  kSingleStream,
  // Two std::mt19937 streams: the noise from seed 1000 + seed, the outlier decision (drawn only
  // when outlier_fraction > 0), direction and magnitude from seed 5000 + seed, normal deviates
  // through one std::normal_distribution shared by both. `optinav bench gnss`: its published
  // figures were made with these draws.
  kNoiseAndOutlierStreams,
};

struct GnssOptions {
  double rate_hz = 5.0;
  double first_sample_s = 0.0;       // the first sample this long after the start, then 1 / rate
  double sigma_m = 1.0;              // per axis
  double outlier_fraction = 0.0;     // [0, 1]
  double outlier_magnitude_m = 0.0;  // outliers are offset by this distance, random direction
  // Above outlier_magnitude_m: the offset is uniform in [outlier_magnitude_m, this].
  double outlier_magnitude_max_m = 0.0;
  std::vector<GnssOutage> outages;  // no samples inside these windows
  GnssDraws draws = GnssDraws::kSingleStream;
  Eigen::Vector3d lever_arm_in_body{0, 0, 0.1};  // antenna position in the body frame (m)
  geo::LatLon origin{47.3769, 8.5417};           // the ENU origin (Zurich by default)
  double origin_height_m = 408.0;                // ellipsoidal
  std::string Check() const;
};

struct GnssMeasurement {
  int64_t t_ns = 0;
  Eigen::Vector3d position_enu_m = Eigen::Vector3d::Zero();
  double lat_deg = 0, lon_deg = 0, height_m = 0;
  bool outlier = false;
};

// The body pose in the world (ENU) frame at a time; nullopt where it is unknown (that epoch gives
// no sample, its random numbers are still drawn).
using PoseAtTime = std::function<std::optional<Rigid3d>(int64_t t_ns)>;

// Samples at start_ns + first_sample_s + k / rate_hz for every k with t <= end_ns; outage windows
// count from start_ns.
std::vector<GnssMeasurement> SimulateGnss(const PoseAtTime& world_from_body, int64_t start_ns,
                                          int64_t end_ns, const GnssOptions& options,
                                          uint64_t seed);
// The same over the whole trajectory.
std::vector<GnssMeasurement> SimulateGnss(const BodyTrajectory& trajectory,
                                          const GnssOptions& options, uint64_t seed);

// "0.05:20" -> fraction 0.05, magnitude 20 m; "30:10" -> outage from 30 s for 10 s. Throw Error
// naming `field` when malformed.
std::pair<double, double> ParseOutlierSpec(const std::string& text, const std::string& field);
GnssOutage ParseOutageSpec(const std::string& text, const std::string& field);

}  // namespace optinav::sim
