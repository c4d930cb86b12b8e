#include "optinav/sim/internal/spline.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Sparse>
#include <Eigen/SparseLU>

#include "optinav/util/error.h"

namespace optinav::sim {
namespace {

constexpr int kOrder = 6;  // degree 5

// Basis matrix of the uniform B-spline (Qin 2000): segment value = [1 u .. u^5] M [c_0..c_5].
const std::array<std::array<double, kOrder>, kOrder>& BasisMatrix() {
  static const auto m = [] {
    auto binom = [](int n, int k) {
      double r = 1;
      for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
      return r;
    };
    std::array<std::array<double, kOrder>, kOrder> out{};
    const int k = kOrder;
    double fact = 1;
    for (int i = 2; i < k; ++i) fact *= i;
    for (int i = 0; i < k; ++i) {
      for (int j = 0; j < k; ++j) {
        double sum = 0;
        for (int s = j; s < k; ++s) {
          sum += ((s - j) % 2 ? -1.0 : 1.0) * binom(k, s - j) * std::pow(k - 1 - s, k - 1 - i);
        }
        out[i][j] = binom(k - 1, i) * sum / fact;
      }
    }
    return out;
  }();
  return m;
}

// Weights of the six control points for the `order`-th derivative w.r.t. u at u.
std::array<double, kOrder> Weights(double u, int order) {
  const auto& m = BasisMatrix();
  std::array<double, kOrder> w{};
  for (int i = order; i < kOrder; ++i) {
    double coef = 1;
    for (int r = 0; r < order; ++r) coef *= (i - r);
    const double pw = coef * std::pow(u, i - order);
    for (int j = 0; j < kOrder; ++j) w[j] += pw * m[i][j];
  }
  return w;
}

}  // namespace

QuinticSpline::QuinticSpline(const Eigen::MatrixXd& samples, double dt_s)
    : dt_s_(dt_s), num_samples_(static_cast<int>(samples.rows())) {
  OPTINAV_CHECK(num_samples_ >= 2 && dt_s > 0);
  const int n = num_samples_, unknowns = n + 4;
  std::vector<Eigen::Triplet<double>> triplets;
  const auto w0 = Weights(0, 0), w1 = Weights(0, 1), w2 = Weights(0, 2);
  // Rows 0..n-1: the curve passes through each sample (segment m at u = 0 uses c_m..c_m+5).
  for (int m = 0; m < n; ++m) {
    for (int j = 0; j < kOrder; ++j) {
      if (w0[j] != 0) triplets.emplace_back(m, m + j, w0[j]);
    }
  }
  // Rows n..n+3: zero velocity and acceleration at the first and the last sample.
  int row = n;
  for (int seg : {0, n - 1}) {
    for (const auto* w : {&w1, &w2}) {
      for (int j = 0; j < kOrder; ++j) {
        if ((*w)[j] != 0) triplets.emplace_back(row, seg + j, (*w)[j]);
      }
      ++row;
    }
  }
  Eigen::SparseMatrix<double> a(unknowns, unknowns);
  a.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(unknowns, samples.cols());
  rhs.topRows(n) = samples;
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
  lu.compute(a);
  OPTINAV_CHECK_MSG(lu.info() == Eigen::Success, "spline system is singular");
  control_ = lu.solve(rhs);
}

Eigen::VectorXd QuinticSpline::Evaluate(double t_s, int order) const {
  OPTINAV_CHECK(order >= 0 && order <= 4 && num_samples_ >= 2);
  const double x = t_s / dt_s_;
  const int last_segment = num_samples_ - 2;
  if (x < 0 || x > last_segment + 1) {
    if (order > 0) return Eigen::VectorXd::Zero(control_.cols());
  }
  const double xc = std::clamp(x, 0.0, static_cast<double>(last_segment + 1));
  const int seg = std::min(static_cast<int>(std::floor(xc)), last_segment);
  const double u = xc - seg;
  const auto w = Weights(u, order);
  Eigen::VectorXd out = Eigen::VectorXd::Zero(control_.cols());
  for (int j = 0; j < kOrder; ++j) out += w[j] * control_.row(seg + j).transpose();
  return out / std::pow(dt_s_, order);
}

}  // namespace optinav::sim
