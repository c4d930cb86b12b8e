// The geometry of a downward-looking (mapping) camera over a flat map: attitude convention,
// camera pose, the plane-induced homography between image and map, and back (the pose from a
// homography: planar PnP).
//
// Attitude convention (used by locate, render, mission and sim): aerospace, NED, yaw-pitch-roll
// (Z-Y-X). yaw = heading, degrees clockwise from north; pitch positive nose up; roll positive
// right wing down. ned_from_body = Rz(yaw) Ry(pitch) Rx(roll), body axes x nose, y right wing,
// z down. The mapping camera looks straight down in the body frame, image top towards the nose,
// image right towards the right wing: with zero roll and pitch the yaw is the heading of the
// frame's up direction.
//
// The ground frame G of a map: x along map pixel x, y along map pixel y, z down (into the
// ground), metres (map pixels times the map's ground sample distance), origin at map pixel (0, 0).
// For a north-up map, G is east-south-down; headings here are relative to the map's up direction
// (the grid north of the map CRS); the locator converts from and to true headings.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "optinav/geometry/lie.h"

namespace optinav::maploc {

struct Attitude {
  double roll_deg = 0, pitch_deg = 0, yaw_deg = 0;
};

// ned_from_body of an attitude, and the attitude of a rotation (yaw in [0, 360)).
Eigen::Matrix3d NedFromBody(const Attitude& attitude);
Attitude AttitudeOf(const Eigen::Matrix3d& ned_from_body);
// The mapping camera in the body frame (camera x right, y down, z optical axis).
Eigen::Matrix3d BodyFromCamera();
// G from NED when the map's up direction is north: (n, e, d) -> (e, -n, d).
Eigen::Matrix3d GroundFromNed();

// Where a vehicle is over a map and how it is oriented (yaw relative to map up).
struct AerialPose {
  Eigen::Vector2d nadir_px = Eigen::Vector2d::Zero();  // the ground point below it, map pixels
  double altitude_m = 0;                               // above the map plane
  Attitude attitude;
};

// The mapping camera's pose in G (p_ground = ground_from_camera * p_camera).
Rigid3d GroundFromCamera(const AerialPose& pose, double map_gsd_m);
AerialPose PoseOfCamera(const Rigid3d& ground_from_camera, double map_gsd_m);

// The plane-induced homography taking (undistorted) image pixels to map pixels.
Eigen::Matrix3d MapFromImage(const AerialPose& pose, const Eigen::Matrix3d& K, double map_gsd_m);

// The camera pose of a homography image px -> map px (undistorted pixels, intrinsics K): the
// decomposition H ~ diag(gsd) [r1 r2 t]^-1 K^-1 with the camera above the plane. nullopt when H
// is degenerate (singular, or no rotation fits).
std::optional<AerialPose> PoseFromHomography(const Eigen::Matrix3d& map_from_image,
                                             const Eigen::Matrix3d& K, double map_gsd_m);

// Soft knowledge of the pose for the refinement (e.g. from the autopilot).
struct PosePriors {
  std::optional<double> roll_deg, pitch_deg;
  double attitude_sigma_deg = 1.5;
  std::optional<double> altitude_m;
  double altitude_sigma_rel = 0.1;  // fraction of the altitude
  double pixel_sigma = 2.0;         // of the image measurements
};

struct PoseEstimate {
  AerialPose pose;
  // 1-sigma horizontal uncertainty of the nadir point, metres (from the Gauss-Newton normal
  // equations at the optimum, scaled by the residuals' spread).
  double horizontal_sigma_m = 0;
  double rms_px = 0;  // reprojection residual of the image points
};

// Refines a pose by Gauss-Newton (Huber-weighted) on the reprojection of map points
// (`map_px`, on the plane) to their `image_px` (undistorted), with the priors as extra residuals.
PoseEstimate RefinePose(const std::vector<Eigen::Vector2d>& image_px,
                        const std::vector<Eigen::Vector2d>& map_px, const Eigen::Matrix3d& K,
                        double map_gsd_m, const AerialPose& initial, const PosePriors& priors);

// Homography from the pixels of a camera with this roll and pitch to those of a virtual nadir
// camera at the same place with the same yaw and intrinsics (x_nadir ~ K R K^-1 x). The virtual
// camera's principal point sees the vehicle's nadir point.
Eigen::Matrix3d NadirFromImage(const Eigen::Matrix3d& K, double roll_deg, double pitch_deg);

}  // namespace optinav::maploc
