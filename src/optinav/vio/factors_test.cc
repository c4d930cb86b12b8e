#include "optinav/vio/factors.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace optinav::vio {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct Evaluation {
  Eigen::Vector2d residual;
  RowMatrix d_pose{2, kPoseSize}, d_point{2, kPointSize};
};

Evaluation Evaluate(const ceres::CostFunction& cost, const double* pose, const double* point) {
  Evaluation e;
  const double* parameters[2] = {pose, point};
  double* jacobians[2] = {e.d_pose.data(), e.d_point.data()};
  EXPECT_TRUE(cost.Evaluate(parameters, e.residual.data(), jacobians));
  return e;
}

// Largest |a - b| relative to the largest entry of b (entries near zero are not divided by).
double RelativeDifference(const RowMatrix& a, const RowMatrix& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(b.cwiseAbs().maxCoeff(), 1e-300);
}

TEST(Reprojection, AnalyticJacobianMatchesAutoDiff) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  auto random_vector = [&](double scale) -> Eigen::Vector3d {
    return Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng)) * scale;
  };
  auto random_rotation = [&]() {
    return Eigen::Quaterniond(uniform(rng), uniform(rng), uniform(rng), uniform(rng)).normalized();
  };
  double worst_residual = 0, worst_pose = 0, worst_point = 0, worst_tangent = 0;
  int in_front = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Rigid3d cam_from_body(random_rotation(), random_vector(0.2));
    const Rigid3d world_from_body(random_rotation(), random_vector(50.0));
    // A point 0.5-40 m in front of the camera (some trials: behind it).
    const Eigen::Vector3d p_in_cam(uniform(rng) * 10, uniform(rng) * 10,
                                   trial % 10 == 0 ? -5.0 : 20.5 + 19.5 * uniform(rng));
    const Eigen::Vector3d p_in_world = world_from_body * (cam_from_body.Inverse() * p_in_cam);
    const Eigen::Vector2d observed =
        p_in_cam.head<2>() / p_in_cam.z() + Eigen::Vector2d(uniform(rng), uniform(rng)) * 0.01;
    double pose[kPoseSize] = {world_from_body.translation.x(), world_from_body.translation.y(),
                              world_from_body.translation.z(), world_from_body.rotation.x(),
                              world_from_body.rotation.y(),    world_from_body.rotation.z(),
                              world_from_body.rotation.w()};
    // Some trials off the unit sphere: the ambient Jacobian must still be the exact derivative.
    if (trial % 3 == 1)
      for (int i = 3; i < 7; ++i) pose[i] *= 1.0 + 0.05 * uniform(rng);
    const double point[kPointSize] = {p_in_world.x(), p_in_world.y(), p_in_world.z()};

    const std::unique_ptr<ceres::CostFunction> analytic(
        CreateReprojectionFactor(cam_from_body, observed, 450.0, 1.5));
    const std::unique_ptr<ceres::CostFunction> autodiff(
        CreateAutoDiffReprojectionFactor(cam_from_body, observed, 450.0, 1.5));
    const Evaluation a = Evaluate(*analytic, pose, point);
    const Evaluation b = Evaluate(*autodiff, pose, point);
    worst_residual = std::max(worst_residual, (a.residual - b.residual).cwiseAbs().maxCoeff() /
                                                  std::max(b.residual.cwiseAbs().maxCoeff(), 1.0));
    if (p_in_cam.z() < 0) {
      EXPECT_EQ(a.d_pose.cwiseAbs().maxCoeff(), 0.0);
      EXPECT_EQ(a.d_point.cwiseAbs().maxCoeff(), 0.0);
      continue;
    }
    ++in_front;
    worst_pose = std::max(worst_pose, RelativeDifference(a.d_pose, b.d_pose));
    worst_point = std::max(worst_point, RelativeDifference(a.d_point, b.d_point));
    // What the solver uses: the Jacobian on the manifold's tangent space.
    RowMatrix plus(kPoseSize, kPoseTangentSize);
    PoseManifold()->PlusJacobian(pose, plus.data());
    worst_tangent =
        std::max(worst_tangent, RelativeDifference(a.d_pose * plus, RowMatrix(b.d_pose * plus)));
  }
  std::printf(
      "analytic vs autodiff reprojection (%d points in front): residual %.1e, pose %.1e, "
      "point %.1e, tangent %.1e (relative, < 1e-8)\n",
      in_front, worst_residual, worst_pose, worst_point, worst_tangent);
  EXPECT_GT(in_front, 1500);
  EXPECT_LT(worst_residual, 1e-8);
  EXPECT_LT(worst_pose, 1e-8);
  EXPECT_LT(worst_point, 1e-8);
  EXPECT_LT(worst_tangent, 1e-8);
}

// The fixed-pose reprojection (anchored observations) is the reprojection with its pose held:
// the same residual and point Jacobian, one block.
TEST(Reprojection, FixedPoseIsTheReprojectionWithThePoseHeld) {
  const Rigid3d cam_from_body(
      Eigen::Quaterniond(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitX())),
      Eigen::Vector3d(0.05, -0.1, 0.02));
  const Rigid3d world_from_body(
      Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, -0.3, 1.0).normalized())),
      Eigen::Vector3d(12.0, -3.0, 1.5));
  const Eigen::Vector2d observed(0.11, -0.07);
  const double pose[kPoseSize] = {world_from_body.translation.x(), world_from_body.translation.y(),
                                  world_from_body.translation.z(), world_from_body.rotation.x(),
                                  world_from_body.rotation.y(),    world_from_body.rotation.z(),
                                  world_from_body.rotation.w()};
  const std::unique_ptr<ceres::CostFunction> full(
      CreateReprojectionFactor(cam_from_body, observed, 450.0, 1.5));
  const std::unique_ptr<ceres::CostFunction> fixed(
      CreateFixedPoseReprojectionFactor(world_from_body, cam_from_body, observed, 450.0, 1.5));
  ASSERT_EQ(fixed->parameter_block_sizes(), std::vector<int32_t>{kPointSize});
  int in_front = 0;
  for (const Eigen::Vector3d& p_in_cam :
       {Eigen::Vector3d(1.0, -2.0, 8.0), Eigen::Vector3d(-4.0, 0.5, 30.0),
        Eigen::Vector3d(0.3, 0.2, 0.7), Eigen::Vector3d(1.0, 1.0, -3.0)}) {
    const Eigen::Vector3d p = world_from_body * (cam_from_body.Inverse() * p_in_cam);
    const double point[kPointSize] = {p.x(), p.y(), p.z()};
    const Evaluation a = Evaluate(*full, pose, point);
    Eigen::Vector2d residual;
    RowMatrix d_point(2, kPointSize);
    const double* parameters[1] = {point};
    double* jacobians[1] = {d_point.data()};
    ASSERT_TRUE(fixed->Evaluate(parameters, residual.data(), jacobians));
    EXPECT_EQ(residual, a.residual);
    EXPECT_EQ(d_point, a.d_point);
    ASSERT_TRUE(fixed->Evaluate(parameters, residual.data(), nullptr));
    EXPECT_EQ(residual, a.residual);
    in_front += p_in_cam.z() > 0 ? 1 : 0;
    if (p_in_cam.z() > 0) {
      EXPECT_GT(a.d_point.cwiseAbs().maxCoeff(), 0.0);
    }
  }
  EXPECT_EQ(in_front, 3);
}

TEST(GroundVehicle, PenalisesOnlyTheBodyFramesSidewaysAndVerticalVelocity) {
  // A car heading north-east (yaw 45 deg), pitched up 5 deg on a slope.
  const Eigen::Quaterniond world_from_body =
      Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitZ()) *
      Eigen::AngleAxisd(-5 * M_PI / 180, Eigen::Vector3d::UnitY());
  const double pose[kPoseSize] = {
      3, -2, 1, world_from_body.x(), world_from_body.y(), world_from_body.z(), world_from_body.w()};
  auto evaluate = [&](const Eigen::Vector3d& v_body, double sigma_lateral, double sigma_vertical) {
    const Eigen::Vector3d v_world = world_from_body * v_body;
    const double speed_bias[kSpeedBiasSize] = {v_world.x(), v_world.y(), v_world.z(), 0.01, 0,
                                               0,           0.1,         0,           0};
    std::unique_ptr<ceres::CostFunction> cost(
        CreateGroundVehicleFactor(sigma_lateral, sigma_vertical));
    const double* parameters[2] = {pose, speed_bias};
    Eigen::Vector2d r;
    EXPECT_TRUE(cost->Evaluate(parameters, r.data(), nullptr));
    return r;
  };
  // Driving along the body x axis, uphill: no residual.
  EXPECT_LT(evaluate({8, 0, 0}, 0.1, 0.05).norm(), 1e-12);
  // Sliding sideways 0.2 m/s and sinking 0.1 m/s through the body: whitened by each sigma.
  const Eigen::Vector2d r = evaluate({8, 0.2, -0.1}, 0.1, 0.05);
  EXPECT_NEAR(r.x(), 2.0, 1e-9);
  EXPECT_NEAR(r.y(), -2.0, 1e-9);
  // A zero sigma leaves that component free.
  EXPECT_NEAR(evaluate({8, 0.2, -0.1}, 0, 0.05).x(), 0.0, 1e-12);
}

TEST(GroundVehicle, PairFactorTakesTheChordAtTheArcsMiddleHeading) {
  // A car on a flat circle of radius 20 m (rear axle on the circle, x along the tangent),
  // turning left through 30 deg in 1 s; the start heads north-east.
  const double radius = 20, turn = 30 * M_PI / 180, dt = 1.0;
  using Pose = std::array<double, kPoseSize>;
  auto make_pose = [](const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
    return Pose{p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w()};
  };
  auto on_circle = [&](double heading) {
    const Eigen::Vector3d centre(5, 7, 2);
    const double a = M_PI / 4 + heading - M_PI / 2;  // from the centre (to the left) to the car
    return make_pose(
        centre + radius * Eigen::Vector3d(std::cos(a), std::sin(a), 0),
        Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 4 + heading, Eigen::Vector3d::UnitZ())));
  };
  auto evaluate = [&](const Pose& pa, const Pose& pb) {
    std::unique_ptr<ceres::CostFunction> cost(CreateGroundVehiclePairFactor(dt, 0.1, 0.05));
    const double* parameters[2] = {pa.data(), pb.data()};
    Eigen::Vector2d r;
    EXPECT_TRUE(cost->Evaluate(parameters, r.data(), nullptr));
    return r;
  };
  auto moved = [](Pose pose, const Eigen::Vector3d& d) {
    for (int i = 0; i < 3; ++i) pose[i] += d[i];
    return pose;
  };
  const Pose a = on_circle(0), b = on_circle(turn);
  // Along the arc: no residual, although the chord is 15 deg off both ends' headings.
  EXPECT_LT(evaluate(a, b).norm(), 1e-9);
  // The end 0.3 m to the right of the arc's middle heading: 0.3 m / (0.1 m/s * 1 s) = -3; 0.1 m
  // above it: 0.1 / 0.05 = 2.
  const Eigen::Quaterniond mid(Eigen::AngleAxisd(M_PI / 4 + turn / 2, Eigen::Vector3d::UnitZ()));
  Eigen::Vector2d r = evaluate(a, moved(b, mid * Eigen::Vector3d(0, -0.3, 0)));
  EXPECT_NEAR(r.x(), -3.0, 1e-9);
  EXPECT_NEAR(r.y(), 0.0, 1e-9);
  r = evaluate(a, moved(b, mid * Eigen::Vector3d(0, 0, 0.1)));
  EXPECT_NEAR(r.x(), 0.0, 1e-9);
  EXPECT_NEAR(r.y(), 2.0, 1e-9);
  // A heading that turned 3 deg too far at b: the chord is 1.5 deg right of the middle's x.
  Pose turned = b;
  const Eigen::Quaterniond qb = Eigen::AngleAxisd(3 * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                                Eigen::Quaterniond(b[6], b[3], b[4], b[5]);
  turned[3] = qb.x(), turned[4] = qb.y(), turned[5] = qb.z(), turned[6] = qb.w();
  const double chord = 2 * radius * std::sin(turn / 2);
  EXPECT_NEAR(evaluate(a, turned).x(), -chord * std::sin(1.5 * M_PI / 180) / 0.1, 1e-9);
  // Straight up a 6 deg slope, pitched with it: no residual; the quaternions' sign is free.
  const Eigen::Quaterniond uphill = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(-6 * M_PI / 180, Eigen::Vector3d::UnitY());
  const Eigen::Vector3d start(1, 2, 3);
  const Pose s0 = make_pose(start, uphill);
  Pose s1 = make_pose(start + uphill * Eigen::Vector3d(7, 0, 0), uphill);
  for (int i = 3; i < 7; ++i) s1[i] = -s1[i];
  EXPECT_LT(evaluate(s0, s1).norm(), 1e-9);
  // With the boresight block: a body whose forward axis is Rz(yaw) Ry(pitch) x drives along that
  // axis without residual; the body x version sees the offset.
  const double boresight[2] = {0.02, -0.01};
  const Eigen::Vector3d axis = Eigen::AngleAxisd(boresight[0], Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(boresight[1], Eigen::Vector3d::UnitY()) *
                               Eigen::Vector3d::UnitX();
  const Pose t1 = make_pose(start + uphill * (7 * axis), uphill);
  std::unique_ptr<ceres::CostFunction> with(
      CreateGroundVehiclePairFactorWithBoresight(dt, 0.1, 0.05));
  const double* parameters[3] = {s0.data(), t1.data(), boresight};
  Eigen::Vector2d r3;
  ASSERT_TRUE(with->Evaluate(parameters, r3.data(), nullptr));
  EXPECT_LT(r3.norm(), 1e-9);
  EXPECT_NEAR(evaluate(s0, t1).x(), 7 * axis.y() / 0.1, 1e-9);
}

}  // namespace
}  // namespace optinav::vio
