// OpenCV's PnP pose (Rodrigues rotation vector and translation, target_from_source) to and from
// a Rigid3d.
#pragma once

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "optinav/geometry/lie.h"

namespace optinav::vio {

inline Rigid3d PoseFromRvecTvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  Eigen::Matrix3d rotation;
  cv::cv2eigen(r, rotation);
  Eigen::Matrix<double, 3, 4> m;
  m.leftCols<3>() = rotation;
  m.col(3) << tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2);
  return Rigid3d::FromMatrix(m);
}

inline void RvecTvecFromPose(const Rigid3d& pose, cv::Mat* rvec, cv::Mat* tvec) {
  const Eigen::AngleAxisd aa(pose.rotation);
  const Eigen::Vector3d r = aa.angle() * aa.axis();
  *rvec = (cv::Mat_<double>(3, 1) << r.x(), r.y(), r.z());
  *tvec =
      (cv::Mat_<double>(3, 1) << pose.translation.x(), pose.translation.y(), pose.translation.z());
}

}  // namespace optinav::vio
