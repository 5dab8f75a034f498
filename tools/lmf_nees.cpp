// lmf-nees: the local map's consistency experiment (paper §III.A, Fig. 4). Runs
// one robot's local map (shipping disabled) over seeded simulator missions, with
// the perfect angular constraints on and off, and prints per time bucket the
// average NEES of the robot pose over the runs against the 95 % band for the mean
// of N chi2(3) values.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "lmf/local_map/consistency.hpp"
#include "lmf/local_map/local_map.hpp"
#include "lmf/local_map/local_map_config_json.hpp"
#include "lmf/sim/mission.hpp"
#include "tools/tool_support.hpp"

namespace po = boost::program_options;

namespace {

struct Options {
  int runs = 20;
  double duration_s = 150.0;
  uint64_t first_seed = 1;
  double bucket_s = 10.0;
  std::string config_file;
  std::string csv_file;
  std::size_t check_interval = 25;
};

// One local map over one robot's scans: the NEES at the last scan of every time
// bucket (nullopt where P_RR is singular), and the final errors.
struct RunResult {
  std::vector<std::optional<double>> nees;  // per bucket
  double final_error_m = 0.0;
  double final_error_rad = 0.0;
  std::size_t segments = 0;
  int unhealthy_checks = 0;
};

RunResult run_local_map(const lmf::sim::RobotRun& robot, const lmf::LocalMapConfig& config, double bucket_s) {
  RunResult out;
  lmf::LocalMap lm(config);
  const int64_t t0 = robot.scans.front().utime;
  for (std::size_t k = 0; k < robot.scans.size(); ++k) {
    const lmf::ScanReport r = lm.process_scan(robot.scans[k]);
    if (r.covariance_checked && !r.covariance_health.ok()) ++out.unhealthy_checks;
    // L is the robot's true pose at the first scan.
    const lmf::Pose2 x_LR_true = lmf::between(robot.true_poses.front(), robot.true_poses[k]);
    const double t = static_cast<double>(robot.scans[k].utime - t0) * 1e-6;
    // Bucket b holds the times in (b·bucket_s, (b+1)·bucket_s]; t = 0 joins bucket 0.
    const auto bucket = t <= 0.0 ? std::size_t{0} : static_cast<std::size_t>(std::ceil(t / bucket_s) - 1.0);
    if (out.nees.size() <= bucket) out.nees.resize(bucket + 1);
    const lmf::Pose2 x_LR = lm.x_LR_at_last_scan();
    out.nees[bucket] = lmf::pose_nees(x_LR, lm.robot_covariance_at_last_scan(), x_LR_true);
    out.final_error_m = std::hypot(x_LR.x - x_LR_true.x, x_LR.y - x_LR_true.y);
    out.final_error_rad = std::abs(lmf::wrap_angle(x_LR.phi - x_LR_true.phi));
  }
  out.segments = lm.num_segments();
  return out;
}

struct Series {
  std::string name;
  lmf::LocalMapConfig config;
  std::vector<RunResult> runs;
};

int run(const Options& o) {
  lmf::LocalMapConfig base =
      o.config_file.empty() ? lmf::LocalMapConfig{} : lmf::load_local_map_config(o.config_file);
  base.ship_distance_m = 1e12;  // one local map over the whole mission
  base.max_segments = static_cast<std::size_t>(1) << 40;
  base.covariance_check_interval = o.check_interval;
  std::vector<Series> series(2);
  series[0].name = "constraints_on";
  series[0].config = base;
  series[0].config.constraints_enabled = true;
  series[1].name = "constraints_off";
  series[1].config = base;
  series[1].config.constraints_enabled = false;

  double distance_m = 0.0;
  for (int r = 0; r < o.runs; ++r) {
    lmf::sim::MissionConfig mission_config;
    mission_config.seed = o.first_seed + static_cast<uint64_t>(r);
    mission_config.num_robots = 1;
    mission_config.duration_s = o.duration_s;
    const lmf::sim::Mission mission = lmf::sim::simulate_mission(mission_config);
    const lmf::sim::RobotRun& robot = mission.robots.front();
    distance_m += robot.distance_m;
    for (Series& s : series) s.runs.push_back(run_local_map(robot, s.config, o.bucket_s));
    std::cerr << "run " << r + 1 << "/" << o.runs << " (seed " << mission_config.seed << ", " << robot.scans.size()
              << " scans, " << robot.distance_m << " m): final error on " << series[0].runs.back().final_error_m
              << " m, off " << series[1].runs.back().final_error_m << " m\n";
  }

  std::size_t buckets = 0;
  for (const Series& s : series) {
    for (const RunResult& r : s.runs) buckets = std::max(buckets, r.nees.size());
  }
  std::ofstream csv;
  if (!o.csv_file.empty()) {
    csv.open(o.csv_file);
    if (!csv) throw std::runtime_error("cannot write " + o.csv_file);
    csv << "bucket_end_s,runs,band_lower,band_upper,nees_constraints_on,nees_constraints_off\n";
  }
  std::cout << "Average robot-pose NEES over " << o.runs << " seeded missions of " << o.duration_s
            << " s (mean distance " << distance_m / o.runs << " m), sampled at the end of each " << o.bucket_s
            << " s bucket; 95 % band for the mean of N chi2(3) values.\n";
  std::cout << std::setw(9) << "t_end_s" << std::setw(4) << "N" << std::setw(18) << "band" << std::setw(16)
            << "constraints_on" << std::setw(17) << "constraints_off" << "\n";
  std::vector<int> inside(series.size(), 0);
  std::vector<int> above(series.size(), 0);
  int rows = 0;
  for (std::size_t b = 0; b < buckets; ++b) {
    // Runs where both series have a NEES in this bucket.
    std::vector<double> sum(series.size(), 0.0);
    int n = 0;
    for (int r = 0; r < o.runs; ++r) {
      bool all = true;
      for (const Series& s : series) {
        const auto& v = s.runs[static_cast<std::size_t>(r)].nees;
        all = all && b < v.size() && v[b].has_value();
      }
      if (!all) continue;
      ++n;
      for (std::size_t i = 0; i < series.size(); ++i) sum[i] += *series[i].runs[static_cast<std::size_t>(r)].nees[b];
    }
    if (n == 0) continue;
    ++rows;
    const lmf::NeesBand band = lmf::average_nees_band(3, n);
    std::ostringstream band_text;
    band_text << std::fixed << std::setprecision(2) << "[" << band.lower << ", " << band.upper << "]";
    std::cout << std::setw(9) << std::fixed << std::setprecision(0) << (static_cast<double>(b) + 1.0) * o.bucket_s
              << std::setw(4) << n << std::setw(18) << band_text.str();
    if (csv) csv << (static_cast<double>(b) + 1.0) * o.bucket_s << "," << n << "," << band.lower << "," << band.upper;
    for (std::size_t i = 0; i < series.size(); ++i) {
      const double mean = sum[i] / n;
      const bool in = mean >= band.lower && mean <= band.upper;
      inside[i] += in ? 1 : 0;
      above[i] += mean > band.upper ? 1 : 0;
      std::ostringstream cell;
      cell << std::fixed << std::setprecision(2) << mean << (in ? "  " : (mean > band.upper ? " ^" : " v"));
      std::cout << std::setw(i == 0 ? 16 : 17) << cell.str();
      if (csv) csv << "," << mean;
    }
    std::cout << "\n";
    if (csv) csv << "\n";
  }
  std::cout << "(^ above the band: optimistic, inconsistent; v below: pessimistic)\n";
  for (std::size_t i = 0; i < series.size(); ++i) {
    double e2 = 0.0;
    double a2 = 0.0;
    double segments = 0.0;
    int unhealthy = 0;
    for (const RunResult& r : series[i].runs) {
      e2 += r.final_error_m * r.final_error_m;
      a2 += r.final_error_rad * r.final_error_rad;
      segments += static_cast<double>(r.segments);
      unhealthy += r.unhealthy_checks;
    }
    std::cout << series[i].name << ": " << inside[i] << "/" << rows << " buckets inside the band, " << above[i]
              << " above; final pose error RMS " << std::setprecision(3) << std::sqrt(e2 / o.runs) << " m, "
              << std::sqrt(a2 / o.runs) * 180.0 / 3.14159265358979 << " deg; mean segments "
              << std::setprecision(1) << segments / o.runs << "; covariance checks failed: " << unhealthy << "\n";
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  po::options_description options(
      "lmf-nees: consistency of the robot local map (paper Fig. 4). Simulates --runs seeded single-robot\n"
      "missions (lmf/sim), runs one local map per mission with shipping disabled, with the perfect angular\n"
      "constraints on and off, and prints per time bucket the average over the runs of the robot pose NEES\n"
      "(e = ⊖x̂_LR ⊕ x_LR as (x, y, phi), NEES = eᵀ P_RR⁻¹ e, sampled at each bucket's last scan) against\n"
      "the 95 % band [chi2inv(.025, 3N)/N, chi2inv(.975, 3N)/N].\nOptions");
  options.add_options()("help,h", "print this help")(
      "runs", po::value(&o.runs)->default_value(20), "number of seeded missions (>= 1)")(
      "duration", po::value(&o.duration_s)->default_value(150.0), "mission length (s, > 0)")(
      "seed", po::value(&o.first_seed)->default_value(1), "seed of the first mission; run r uses seed + r")(
      "bucket", po::value(&o.bucket_s)->default_value(10.0), "time bucket (s, > 0)")(
      "config", po::value(&o.config_file),
      "JSON LocalMapConfig (defaults otherwise; shipping is always disabled). tools/lmf_nees_sim.json holds\n"
      "the extraction settings suited to the simulator's 5 cm laser noise")(
      "check-interval", po::value(&o.check_interval)->default_value(25),
      "scans between covariance checks (0: never)")(
      "csv", po::value(&o.csv_file), "also write the table as CSV to this file");
  const auto check = [&] {
    if (o.runs < 1) throw po::error("--runs must be >= 1");
    if (!(o.duration_s > 0.0)) throw po::error("--duration must be > 0");
    if (!(o.bucket_s > 0.0)) throw po::error("--bucket must be > 0");
  };
  if (const auto exit_code = lmf::tools::parse_command_line(argc, argv, options, "lmf-nees", check)) return *exit_code;
  return lmf::tools::run_reporting_errors("lmf-nees", [&] { return run(o); });
}
