// lmf-scan-match: the front end's registration (escalating_registration.hpp)
// on every scan of a CARMEN log, against the recent scans as the local map
// keeps them (scan_history.hpp), scored against a reference trajectory:
// increment errors of the odometry and of the match, and the consistency of
// both (NEES of the increment perturbation, mean 3 when the covariance is
// right), also of the laser alone in the directions it constrains, and of
// chains of consecutive matches (lmf/eval/increment_chain.hpp), in which an
// error of one scan's own cancels.
#include <algorithm>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <boost/math/distributions/chi_squared.hpp>
#include <boost/program_options.hpp>

#include "lmf/eval/increment_chain.hpp"
#include "lmf/eval/match_closure.hpp"
#include "lmf/io/carmen.hpp"
#include "lmf/local_map/local_map_config_json.hpp"
#include "lmf/local_map/local_map_measurements.hpp"
#include "lmf/front_end/escalating_registration.hpp"
#include "lmf/front_end/scan_history.hpp"
#include "lmf/scan/scan_matcher.hpp"
#include "tools/tool_support.hpp"

namespace po = boost::program_options;

namespace {

// Error statistics of one estimator of the increments.
struct Errors {
  std::vector<double> translation_m;
  std::vector<double> rotation_rad;
  std::vector<double> nees;

  void add(const lmf::Pose2& estimate, const Eigen::Matrix3d& covariance, const lmf::Pose2& truth) {
    // The perturbation p with truth = estimate ⊕ p.
    const lmf::Pose2 p = lmf::between(estimate, truth);
    const Eigen::Vector3d e(p.x, p.y, lmf::wrap_angle(p.phi));
    translation_m.push_back(e.head<2>().norm());
    rotation_rad.push_back(std::abs(e(2)));
    nees.push_back(e.dot(covariance.ldlt().solve(e)));
  }
};

double rms(const std::vector<double>& v) {
  double s = 0.0;
  for (const double x : v) s += x * x;
  return v.empty() ? 0.0 : std::sqrt(s / static_cast<double>(v.size()));
}

double mean(const std::vector<double>& v) {
  double s = 0.0;
  for (const double x : v) s += x;
  return v.empty() ? 0.0 : s / static_cast<double>(v.size());
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

void print(const char* name, const Errors& e, double chi2_95) {
  const auto inside = std::count_if(e.nees.begin(), e.nees.end(), [&](double d) { return d <= chi2_95; });
  std::printf("%-9s %6zu  %8.4f  %8.3f  %9.2f  %9.1f  %7.0f%%\n", name, e.nees.size(), rms(e.translation_m),
              rms(e.rotation_rad) * 180.0 / std::numbers::pi, mean(e.nees), quantile(e.nees, 0.5) * 1.0,
              e.nees.empty() ? 0.0 : 100.0 * static_cast<double>(inside) / static_cast<double>(e.nees.size()));
}

// CPU time of this thread (us): on a shared machine the wall clock also counts other processes.
double thread_cpu_micros() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e6 * static_cast<double>(t.tv_sec) + 1e-3 * static_cast<double>(t.tv_nsec);
}

struct Options {
  std::string log_file;
  std::string reference_file;
  std::string config_file;
  double q_scale = 1.0;
  bool per_scan = false;
  bool closure = false;
};


// --closure: for every three consecutive scans A, B, C, the pairwise matches
// (each against the one scan alone), scored against the reference, and the
// closure of the three (match_closure.hpp), which needs none.
int run_closure(const Options& o, const lmf::io::CarmenLog& log, const std::vector<lmf::StampedPose>& reference,
                const lmf::LocalMapConfig& config) {
  const lmf::ScanMatcherConfig& matching = config.scan_matching;
  const auto match = [&](std::size_t a, std::size_t b) {
    const lmf::Pose2 u = lmf::between(log.scans[a].odometry, log.scans[b].odometry);
    return lmf::match_scans(lmf::ReferenceScan::from(log.scans[a], matching),
                            lmf::scan_points_by_kind(log.scans[b], matching), u,
                            o.q_scale * lmf::local_map::odometry_noise(u, config), matching);
  };
  Errors pairwise;
  std::vector<Eigen::Vector3d> pairwise_errors;
  std::vector<Eigen::Vector3d> closures;
  std::vector<double> closure_nees;
  // Each pairwise match (k − 1, k) against the reference, once.
  const auto score = [&](const std::optional<lmf::ScanMatch>& m, std::size_t k) {
    if (!m || reference.empty()) return;
    const lmf::Pose2 truth = lmf::between(reference[k - 1].pose, reference[k].pose);
    pairwise.add(m->x_AB, m->covariance, truth);
    const lmf::Pose2 e = lmf::between(m->x_AB, truth);
    pairwise_errors.emplace_back(e.x, e.y, lmf::wrap_angle(e.phi));
  };
  std::optional<lmf::ScanMatch> previous = log.scans.size() > 1 ? match(0, 1) : std::nullopt;
  score(previous, 1);
  for (std::size_t k = 2; k < log.scans.size(); ++k) {
    const std::optional<lmf::ScanMatch> ab = previous;
    const std::optional<lmf::ScanMatch> bc = match(k - 1, k);
    const std::optional<lmf::ScanMatch> ac = match(k - 2, k);
    previous = bc;
    score(bc, k);
    if (!ab || !bc || !ac) continue;
    const lmf::eval::Closure c =
        lmf::eval::closure_of({ab->x_AB, ab->covariance}, {bc->x_AB, bc->covariance}, {ac->x_AB, ac->covariance});
    closures.push_back(c.residual);
    closure_nees.push_back(c.nees);
    if (o.per_scan) {
      std::printf("%4zu  closure %+.4f %+.4f %+.5f  NEES %.1f  sigma %.4f %.4f %.5f\n", k, c.residual(0),
                  c.residual(1), c.residual(2), c.nees, std::sqrt(c.covariance(0, 0)), std::sqrt(c.covariance(1, 1)),
                  std::sqrt(c.covariance(2, 2)));
    }
  }
  const auto axis_rms = [](const std::vector<Eigen::Vector3d>& v, int axis) {
    std::vector<double> a;
    for (const Eigen::Vector3d& e : v) a.push_back(e(axis));
    return rms(a);
  };
  const auto row = [&](const char* name, const std::vector<Eigen::Vector3d>& e, const std::vector<double>& nees) {
    std::printf("%-26s %6zu  %8.4f  %8.4f  %8.3f  %9.2f  %9.2f\n", name, e.size(), axis_rms(e, 0), axis_rms(e, 1),
                axis_rms(e, 2) * 180.0 / std::numbers::pi, mean(nees), quantile(nees, 0.5));
  };
  std::printf("%s: pairwise matches (each scan against the one before, alone)\n", o.log_file.c_str());
  std::printf("%-26s %6s  %8s  %8s  %8s  %9s  %9s\n", "", "n", "RMS x m", "RMS y m", "RMS deg", "NEES mean",
              "NEES p50");
  if (!reference.empty()) row("against the reference", pairwise_errors, pairwise.nees);
  row("closure of three (no ref.)", closures, closure_nees);
  std::printf("NEES is 3 when the covariances are right; the closure's, when the three matches' errors are also "
              "independent.\n");
  return 0;
}

// The chain lengths the report scores (lmf/eval/increment_chain.hpp): one
// step, and about 5 m and 15 m of travel at the datasets' half-metre spacing.
constexpr int kChainLengths[] = {1, 10, 30};

int run(const Options& o) {
  if (o.reference_file.empty() && !o.closure) {
    throw std::invalid_argument("--gt is required (only --closure runs without a reference)");
  }
  lmf::LocalMapConfig config =
      o.config_file.empty() ? lmf::LocalMapConfig{} : lmf::load_local_map_config(o.config_file);
  config.scan_matching.enabled = true;
  const lmf::ScanMatcherConfig& matching = config.scan_matching;
  const lmf::io::CarmenLog log = lmf::io::read_carmen_log(o.log_file);
  const std::vector<lmf::StampedPose> reference =
      o.reference_file.empty() ? std::vector<lmf::StampedPose>{}
                               : lmf::tools::read_reference_per_scan(o.reference_file, log.scans.size());
  if (o.closure) return run_closure(o, log, reference, config);
  Errors odometry;
  Errors matched;
  Errors odometry_where_matched;
  Errors odometry_where_failed;
  std::vector<double> micros;
  std::vector<double> laser_nees;  // e ᵀ Λ' e / rank(Λ'): 1 on average when Λ' is right
  int failed = 0;
  // Every increment's match (std::nullopt where it fell back) and its reference, for the chains.
  std::vector<std::optional<lmf::eval::RelativePose>> matches(log.scans.size());
  lmf::ScanHistory history(matching);
  history.add(log.scans.front(), lmf::Pose2(), false);
  for (std::size_t k = 1; k < log.scans.size(); ++k) {
    const lmf::LaserScan& a = log.scans[k - 1];
    const lmf::LaserScan& b = log.scans[k];
    const lmf::Pose2 u = lmf::between(a.odometry, b.odometry);
    const Eigen::Matrix3d Q = o.q_scale * lmf::local_map::odometry_noise(u, config);
    const lmf::Pose2 truth = lmf::between(reference[k - 1].pose, reference[k].pose);
    odometry.add(u, Q, truth);
    const double t0 = thread_cpu_micros();
    const std::optional<lmf::ScanMatch> m =
        lmf::register_escalating(history.reference(), lmf::scan_points_by_kind(b, matching), u, Q, matching).match;
    micros.push_back(thread_cpu_micros() - t0);
    if (m) matches[k] = lmf::eval::RelativePose{m->x_AB, m->covariance};
    // As LocalMap::process_scan: the history goes on from the match, restarts after the odometry.
    history.add(b, m ? m->x_AB : u, m.has_value());
    if (!m) {
      ++failed;
      odometry_where_failed.add(u, Q, truth);
      continue;
    }
    matched.add(m->x_AB, m->covariance, truth);
    odometry_where_matched.add(u, Q, truth);
    {
      const lmf::Pose2 p = lmf::between(m->x_AB, truth);
      const Eigen::Vector3d e(p.x, p.y, lmf::wrap_angle(p.phi));
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(m->laser_information);
      const double largest = es.eigenvalues().maxCoeff();
      int rank = 0;
      for (int i = 0; i < 3; ++i) rank += es.eigenvalues()(i) > 1e-6 * largest ? 1 : 0;
      if (rank > 0) laser_nees.push_back(e.dot(m->laser_information * e) / rank);
    }
    if (o.per_scan) {
      const lmf::Pose2 error = lmf::between(m->x_AB, truth);
      std::printf("%4zu  odometry %.3f m %.2f deg  match %.3f m %.2f deg  NEES %.1f  points %d  rms %.3f m  "
                  "iterations %d  score %.2f  prior d2 %.1f  %.0f us  error %+.4f %+.4f %+.5f\n",
                  k, odometry.translation_m.back(), odometry.rotation_rad.back() * 180.0 / std::numbers::pi,
                  matched.translation_m.back(), matched.rotation_rad.back() * 180.0 / std::numbers::pi,
                  matched.nees.back(), m->correspondences, m->rms_m, m->iterations, m->search_score,
                  m->prior_distance2, micros.back(), error.x, error.y, lmf::wrap_angle(error.phi));
    }
  }
  const double chi2_95 = boost::math::quantile(boost::math::chi_squared_distribution<double>(3.0), 0.95);
  std::printf("%s: %zu increments, %zu matched, %d fell back to odometry\n", o.log_file.c_str(),
              log.scans.size() - 1, matched.nees.size(), failed);
  std::printf("%-9s %6s  %8s  %8s  %9s  %9s  %8s\n", "", "n", "RMS m", "RMS deg", "NEES mean", "NEES p50",
              "<= 95%");
  print("odometry", odometry, chi2_95);
  print("  (same)", odometry_where_matched, chi2_95);
  print("  (rest)", odometry_where_failed, chi2_95);
  print("match", matched, chi2_95);
  std::printf("laser alone (e' L' e / rank L', 1 when L' is right): mean %.2f, median %.2f\n", mean(laser_nees),
              quantile(laser_nees, 0.5));
  std::vector<std::optional<lmf::Pose2>> reference_poses;
  for (const lmf::StampedPose& p : reference) reference_poses.push_back(p.pose);
  for (const int n : kChainLengths) {
    Errors chained;
    Eigen::Vector3d axis_nees_sum = Eigen::Vector3d::Zero();
    for (const lmf::eval::ChainError& e : lmf::eval::chain_errors(matches, reference_poses, n)) {
      chained.translation_m.push_back(e.translation_m);
      chained.rotation_rad.push_back(e.rotation_rad);
      chained.nees.push_back(e.nees);
      axis_nees_sum += e.axis_nees;
    }
    char name[32];
    std::snprintf(name, sizeof name, "chain %d", n);
    print(name, chained, chi2_95);
    if (!chained.nees.empty()) {
      const Eigen::Vector3d axis = axis_nees_sum / static_cast<double>(chained.nees.size());
      std::printf("  per axis (1 when right): along %.2f, across %.2f, heading %.2f\n", axis(0), axis(1), axis(2));
    }
  }
  std::printf("(chain n: n consecutive matches composed, their covariances propagated as independent, against the\n"
              " reference over the same n scans; an error of one scan's own cancels in a chain, a drift does not;\n"
              " per axis: the mean of p_i^2 / var_i along and across the chain's last heading, and of its heading)\n");
  std::printf("CPU time per match (search + refinement; the history's reference is built after each scan): p50 %.0f us, p99 %.0f us, max %.0f us\n",
              quantile(micros, 0.5), quantile(micros, 0.99), quantile(micros, 1.0));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  po::options_description options(
      "lmf-scan-match: match every scan of a CARMEN log against the recent ones (the local map's\n"
      "step 1 with local_map.scan_matching: search window around the odometry increment, which is also\n"
      "the prior) and score the increments of\n"
      "the odometry and of the matches against the reference: RMS errors, NEES (3 when the\n"
      "covariance is right) and the share inside its 95 % bound, also over chains of 10 and 30\n"
      "consecutive matches (where an error of one scan's own cancels), and the time per match.\nOptions");
  options.add_options()("help,h", "print this help")(
      "log", po::value(&o.log_file)->required(), "CARMEN log (plain or .gz)")(
      "gt", po::value(&o.reference_file),
      "reference trajectory, one `index t x y theta` line per scan (required unless --closure)")(
      "q-scale", po::value(&o.q_scale)->default_value(1.0),
      "multiply the odometry noise model's covariance Q by this (an experiment: a wider prior)")(
      "config", po::value(&o.config_file),
      "JSON LocalMapConfig (odometry noise and the scan_matching section; matching is on regardless)")(
      "per-scan", po::bool_switch(&o.per_scan),
      "one line per increment: k, odometry and match errors (m, deg), match NEES, matched points, RMS (m),\n"
      "Gauss-Newton iterations, search score, prior d2, CPU time, and the signed match error\n"
      "(x, y in m, phi in rad: the reference increment seen from the match)")(
      "closure", po::bool_switch(&o.closure),
      "instead: match each scan against the one before and the one before that (alone, no history), and\n"
      "report the pairwise matches' errors against the reference beside the closure of each three\n"
      "(A→B then B→C against A→C), which needs no reference: RMS per axis and NEES; with --per-scan,\n"
      "one line per closure: k, the closure (x, y in m, phi in rad), its NEES and standard deviations");
  if (const auto exit_code = lmf::tools::parse_command_line(argc, argv, options, "lmf-scan-match")) return *exit_code;
  return lmf::tools::run_reporting_errors("lmf-scan-match", [&] { return run(o); });
}
