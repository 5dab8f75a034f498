// Simulated wheel odometry: true motion increments plus noise. Two models:
//
// * Proportional (the paper's and datasets/README.md's model; noisy_increment): between
//   consecutive scans the true increment is u = between(x_WR(k-1), x_WR(k)) = (dx, dy, dphi)
//   in the robot frame at k-1, with d = |(dx, dy)|. The odometry reports
//     u_odo = (dx + n_x, dy + n_y, dphi + n_phi),
//     n_x, n_y ~ N(0, (translation_fraction * d)^2),
//     n_phi   ~ N(0, (rotation_fraction * |dphi| + heading_drift_rad_per_m * d)^2),
//   all independent, independent between increments (datasets/README.md: 8 %, 8 %, 0.01 rad/m;
//   the paper: odometry error proportional to the motion, 6-8 %). A filter predicting with the
//   same increments should use exactly this covariance (docs/design.md §4 step 1).
//
// * Real (RealOdometry): what the wheel odometry of a real differential-drive robot does
//   (docs/design.md §9), which no filter is told: systematic errors fixed per robot for the whole
//   mission, lateral slip, heading noise that does not vanish when driving straight, and
//   occasional glitches. See RealOdometryConfig for the model and the reasoning behind each
//   default.
//
// In both, the odometry pose is x_OR(k) = x_OR(k-1) ⊕ u_odo(k), starting at the true start pose.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "lmf/geometry/pose2.hpp"
#include "lmf/sim/random.hpp"

namespace lmf::sim {

// ---------------------------------------------------------------------------
// The proportional model.

struct OdometryNoiseConfig {
  double translation_fraction = 0.08;     // standard deviation per metre of translation, in [0, 1]
  double rotation_fraction = 0.08;        // standard deviation per radian of rotation, in [0, 1]
  double heading_drift_rad_per_m = 0.01;  // extra heading standard deviation per metre, in [0, 1]
  // Throws std::invalid_argument when out of range.
  void validate() const;
};

// The covariance of the increment noise for a true increment u (diagonal, see above).
Eigen::Matrix3d odometry_noise_covariance(const Pose2& u, const OdometryNoiseConfig& config);

// The increment as the odometry reports it (3 normals are drawn from rng, always).
Pose2 noisy_increment(const Pose2& u, const OdometryNoiseConfig& config, Rng& rng);

// ---------------------------------------------------------------------------
// The real-robot model.
//
// For a true increment u = (dx, dy, dphi), d = |(dx, dy)|, and the robot's systematic errors
// (s_t, s_r, b) drawn once per robot (RealOdometryErrors), the odometry reports
//   dx_odo   = s_t dx + n_x + g_t            n_x ~ N(0, (translation_noise_fraction d)^2)
//   dy_odo   = s_t dy + n_y                  n_y ~ N(0, (slip_per_m d + slip_per_rad |dphi|)^2)
//   dphi_odo = s_r dphi + b d + n_phi + g_phi
//       n_phi ~ N(0, (rotation_noise_fraction |dphi|)^2 + heading_noise_rad2_per_m d
//                    + heading_noise_per_step_rad^2 [the wheels turned])
// with glitches g_phi (probability 1 - exp(-heading_glitch_rate_per_m d) per step, magnitude
// uniform in [heading_glitch_min_rad, heading_glitch_max_rad], random sign) and g_t (probability
// 1 - exp(-translation_glitch_rate_per_m d), magnitude uniform in [translation_glitch_min_m,
// translation_glitch_max_m], forward: a spinning wheel over-reports). A robot standing still
// (u = 0) reports exactly 0: its encoders do not tick.
//
// The defaults are what an ordinary, uncalibrated indoor differential-drive robot (pneumatic or
// rubber tyres, ~0.4 m wheelbase, office floors) does; they were chosen from the references
// below before any run and are not fitted to any dataset or result:
// * Scale of translation, s_t = 1 + N(0, 0.02^2): the effective wheel radius depends on tyre
//   pressure, load and wear; a nominal radius is off by 1-3 % (Borenstein & Feng 1996, UMBmark:
//   the "average wheel diameter" error; calibration reduces it tenfold, so uncalibrated 2 %).
// * Scale of rotation, s_r = 1 + N(0, 0.03^2): the effective wheelbase of wide contact patches
//   is uncertain by a few percent (Borenstein & Feng's wheelbase error E_b, their dominant
//   systematic error), and turning scrubs the tyres; 3 %.
// * Heading bias per metre, b ~ N(0, 0.005^2) rad/m: unequal wheel diameters (E_d = 1.002-1.005
//   uncalibrated) make the robot think it curves when it drives straight: b = (E_d - 1) / wheelbase
//   = 0.005-0.0125 rad/m at 0.4 m; 0.005 rad/m (0.29 deg/m) is the moderate case.
// * Random part of translation, 2 % of d, and of rotation, 3 % of |dphi|: encoder quantisation,
//   uneven floors, the time offset between encoder and laser readings (Chong & Kleeman 1997 report
//   non-systematic errors a few times below the systematic ones).
// * Heading random walk, heading_noise_rad2_per_m = 1e-4 rad^2/m (0.01 rad, 0.57 deg, after 1 m
//   driving straight): floor joints and tiles kick the heading independently of the commanded turn.
// * Heading noise per step, 0.003 rad (0.17 deg) whenever the wheels turn: the encoder/laser time
//   offset jitters by a few ms, which at 0.5 rad/s is 0.0025 rad, plus encoder quantisation.
// * Lateral slip, 0.01 m per metre and 0.02 m per radian: a differential drive cannot move
//   sideways, but castors and tyre deformation push the centre sideways, most when turning.
// * Heading glitches, one per 50 m (0.02 /m) of 2-8 deg: door sills, cables and carpet edges make
//   one wheel slip or lift; several degrees at once is what such a bump does to a 0.4 m wheelbase
//   (1-5 cm of one wheel's travel lost).
// * Translation glitches, one per 100 m (0.01 /m) of 5-20 cm forward: a wheel spinning on a slippery
//   patch or on a threshold reports travel that did not happen.
struct RealOdometryConfig {
  double translation_scale_sigma = 0.02;     // s_t - 1 ~ N(0, sigma^2), in [0, 0.2]
  double rotation_scale_sigma = 0.03;        // s_r - 1 ~ N(0, sigma^2), in [0, 0.2]
  double heading_bias_sigma_rad_per_m = 0.005;  // b ~ N(0, sigma^2), in [0, 0.1]
  double translation_noise_fraction = 0.02;  // in [0, 1]
  double rotation_noise_fraction = 0.03;     // in [0, 1]
  double heading_noise_rad2_per_m = 1e-4;    // heading variance per metre, in [0, 0.1]
  double heading_noise_per_step_rad = 0.003; // in [0, 0.2]
  double slip_per_m = 0.01;                  // lateral standard deviation per metre, in [0, 1]
  double slip_per_rad = 0.02;                // lateral standard deviation (m) per radian, in [0, 1]
  double heading_glitch_rate_per_m = 0.02;   // expected glitches per metre, in [0, 10]
  double heading_glitch_min_rad = 0.035;     // 2 deg; 0 <= min <= max <= pi/2
  double heading_glitch_max_rad = 0.14;      // 8 deg
  double translation_glitch_rate_per_m = 0.01;  // in [0, 10]
  double translation_glitch_min_m = 0.05;    // 0 <= min <= max <= 2
  double translation_glitch_max_m = 0.20;
  // Throws std::invalid_argument naming the first bad field (negative, NaN, out of range,
  // min > max).
  void validate() const;
};

// The systematic errors of one robot, fixed for its whole mission.
struct RealOdometryErrors {
  double translation_scale = 1.0;     // s_t
  double rotation_scale = 1.0;        // s_r
  double heading_bias_rad_per_m = 0;  // b
};

// One robot's real odometry: draws its systematic errors at construction, then one reported
// increment per true increment. Deterministic given the config and the rng's seed; every
// increment draws the same number of values from the rng, glitch or not.
class RealOdometry {
 public:
  // Validates `config` (std::invalid_argument) and draws the systematic errors from `rng`.
  RealOdometry(const RealOdometryConfig& config, Rng& rng);
  // The systematic errors given explicitly (tests).
  RealOdometry(const RealOdometryConfig& config, const RealOdometryErrors& errors);

  const RealOdometryErrors& errors() const { return errors_; }
  // The increment as the odometry reports it for the true increment u.
  Pose2 increment(const Pose2& u, Rng& rng) const;

 private:
  RealOdometryConfig config_;
  RealOdometryErrors errors_;
};

// ---------------------------------------------------------------------------
// One robot's odometry under the model a mission chose.

enum class OdometryModel { kProportional, kReal };

// "proportional" / "real"; parse throws std::invalid_argument for anything else.
const char* odometry_model_name(OdometryModel model);
OdometryModel parse_odometry_model(const std::string& name);

class RobotOdometry {
 public:
  // The random stream is seeded with `seed`; under kReal the robot's systematic errors are
  // its first draws.
  RobotOdometry(OdometryModel model, const OdometryNoiseConfig& proportional, const RealOdometryConfig& real,
                uint64_t seed);
  // The reported increment for the true increment u.
  Pose2 increment(const Pose2& u);
  // The systematic errors under kReal; identity scales and no bias under kProportional.
  RealOdometryErrors errors() const;

 private:
  OdometryModel model_;
  OdometryNoiseConfig proportional_;
  Rng rng_;
  std::optional<RealOdometry> real_;
};

}  // namespace lmf::sim
