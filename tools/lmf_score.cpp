// lmf-score: ATE/RPE of estimated trajectories against references
// (datasets/README.md): poses associated by timestamp, one rigid SE(2)
// alignment over all the given pairs of files, RMSE of position and heading,
// and relative errors over 1 m and 10 m of travel.
#include <cmath>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>
#include <nlohmann/json.hpp>

#include "lmf/eval/trajectory_error.hpp"
#include "lmf/io/trajectory.hpp"

namespace po = boost::program_options;

int main(int argc, char** argv) {
  po::options_description options(
      "lmf-score: scores trajectories (`t x y theta`) against references (`t x y theta` or `index t x y theta`).\n"
      "Usage: lmf-score --est FILE --ref FILE [--est FILE --ref FILE ...] [--json]\n"
      "All pairs share one rigid alignment (robots mapped in one frame).\n\nOptions");
  std::vector<std::string> estimates;
  std::vector<std::string> references;
  options.add_options()("help,h", "print this help")("est", po::value(&estimates), "estimated trajectory (repeatable)")(
      "ref", po::value(&references), "its reference, in the same order (repeatable)")(
      "json", "print one JSON object instead of text")(
      "no-align", "compare as given, without the rigid alignment (estimates in the reference's frame)");
  po::variables_map vm;
  try {
    po::store(po::parse_command_line(argc, argv, options), vm);
    po::notify(vm);
  } catch (const std::exception& e) {
    std::cerr << "lmf-score: " << e.what() << "\n";
    return 2;
  }
  if (vm.count("help") != 0u) {
    std::cout << options << "\n";
    return 0;
  }
  if (estimates.empty() || estimates.size() != references.size()) {
    std::cerr << "lmf-score: give as many --ref as --est (at least one)\n";
    return 2;
  }
  try {
    std::vector<lmf::eval::PosePair> all;
    double sum_t1 = 0, sum_r1 = 0, sum_t10 = 0, sum_r10 = 0;
    std::size_t n1 = 0, n10 = 0;
    for (std::size_t i = 0; i < estimates.size(); ++i) {
      const auto pairs = lmf::eval::associate_by_time(lmf::io::read_trajectory(estimates[i]),
                                                      lmf::io::read_trajectory(references[i]));
      const auto rpe1 = lmf::eval::relative_pose_error(pairs, 1.0);
      const auto rpe10 = lmf::eval::relative_pose_error(pairs, 10.0);
      const auto n1_i = static_cast<double>(rpe1.count);
      const auto n10_i = static_cast<double>(rpe10.count);
      sum_t1 += n1_i * rpe1.translation_rmse_m * rpe1.translation_rmse_m;
      sum_r1 += n1_i * rpe1.rotation_rmse_deg * rpe1.rotation_rmse_deg;
      sum_t10 += n10_i * rpe10.translation_rmse_m * rpe10.translation_rmse_m;
      sum_r10 += n10_i * rpe10.rotation_rmse_deg * rpe10.rotation_rmse_deg;
      n1 += rpe1.count;
      n10 += rpe10.count;
      all.insert(all.end(), pairs.begin(), pairs.end());
    }
    const auto ate = lmf::eval::absolute_trajectory_error(all, vm.count("no-align") == 0u);
    const auto rms = [](double sum, std::size_t n) { return n == 0 ? 0.0 : std::sqrt(sum / static_cast<double>(n)); };
    if (vm.count("json") != 0u) {
      std::cout << nlohmann::json{{"poses", ate.count},
                                  {"ate_position_rmse_m", ate.position_rmse_m},
                                  {"ate_heading_rmse_deg", ate.heading_rmse_deg},
                                  {"rpe_1m_translation_rmse_m", rms(sum_t1, n1)},
                                  {"rpe_1m_rotation_rmse_deg", rms(sum_r1, n1)},
                                  {"rpe_10m_translation_rmse_m", rms(sum_t10, n10)},
                                  {"rpe_10m_rotation_rmse_deg", rms(sum_r10, n10)}}
                       .dump()
                << "\n";
    } else {
      std::cout << "poses " << ate.count << "  ATE " << ate.position_rmse_m << " m, " << ate.heading_rmse_deg
                << " deg  RPE(1 m) " << rms(sum_t1, n1) << " m, " << rms(sum_r1, n1) << " deg  RPE(10 m) "
                << rms(sum_t10, n10) << " m, " << rms(sum_r10, n10) << " deg\n";
    }
  } catch (const std::exception& e) {
    std::cerr << "lmf-score: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
