// Small helpers shared by the unit tests: tolerant matrix comparison,
// numerical Jacobians and the location of the shared datasets.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <gtest/gtest.h>

namespace lmf::testing {

// gtest predicate: |a - b| <= tolerance element-wise, with a readable message.
inline ::testing::AssertionResult matrices_near(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b,
                                                double tolerance) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) {
    return ::testing::AssertionFailure() << "sizes differ: " << a.rows() << "x" << a.cols() << " vs "
                                         << b.rows() << "x" << b.cols();
  }
  if (a.size() == 0) return ::testing::AssertionSuccess();
  const double err = (a - b).cwiseAbs().maxCoeff();
  if (err <= tolerance) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "max |a - b| = " << err << " > " << tolerance << "\na =\n"
                                       << a << "\nb =\n"
                                       << b;
}

// Central-difference Jacobian of f at x. `difference` maps (f(x + h e_i), f(x - h e_i))
// to their difference, so callers can wrap angle components.
inline Eigen::MatrixXd numerical_jacobian(
    const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& x,
    const std::function<Eigen::VectorXd(const Eigen::VectorXd&, const Eigen::VectorXd&)>& difference,
    double step = 1e-6) {
  const Eigen::VectorXd f0 = f(x);
  Eigen::MatrixXd J(f0.size(), x.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    Eigen::VectorXd xp = x;
    Eigen::VectorXd xm = x;
    xp(i) += step;
    xm(i) -= step;
    J.col(i) = difference(f(xp), f(xm)) / (2.0 * step);
  }
  return J;
}

// The shared datasets folder, or nullopt when it is absent (data tests then skip).
inline std::optional<std::filesystem::path> datasets_dir() {
  const char* env = std::getenv("LMF_DATASETS_DIR");
  if (env == nullptr) return std::nullopt;
  std::filesystem::path dir(env);
  if (!std::filesystem::is_directory(dir)) return std::nullopt;
  return dir;
}

// The shared ROS bags folder (beside the datasets: ../shared/bags), or nullopt.
inline std::optional<std::filesystem::path> bags_dir() {
  const auto datasets = datasets_dir();
  if (!datasets) return std::nullopt;
  const std::filesystem::path dir = *datasets / ".." / "bags";
  if (!std::filesystem::is_directory(dir)) return std::nullopt;
  return dir;
}

}  // namespace lmf::testing

// Skips the current test with a clear message when the datasets are absent.
#define LMF_REQUIRE_DATASETS(dir_var)                                                         \
  const auto dir_var##_opt = ::lmf::testing::datasets_dir();                                  \
  if (!dir_var##_opt) {                                                                       \
    GTEST_SKIP() << "shared datasets folder not found (LMF_DATASETS_DIR="                     \
                 << (std::getenv("LMF_DATASETS_DIR") ? std::getenv("LMF_DATASETS_DIR") : "") \
                 << "); skipping data test";                                                  \
  }                                                                                           \
  const std::filesystem::path dir_var = *dir_var##_opt

// Skips the current test with a clear message when the shared bags are absent.
#define LMF_REQUIRE_BAGS(dir_var)                                                                  \
  const auto dir_var##_opt = ::lmf::testing::bags_dir();                                           \
  if (!dir_var##_opt) {                                                                            \
    GTEST_SKIP() << "shared bags folder not found (beside LMF_DATASETS_DIR="                       \
                 << (std::getenv("LMF_DATASETS_DIR") ? std::getenv("LMF_DATASETS_DIR") : "")      \
                 << "); skipping bag test";                                                        \
  }                                                                                                \
  const std::filesystem::path dir_var = *dir_var##_opt
