#include "fusion_server/sighting_conversion.hpp"

namespace lmf::server {

fusion::RobotSighting to_robot_sighting(const runtime::Sighting& s) {
  fusion::RobotSighting out;
  out.utime = s.utime;
  out.observer_id = s.observer_id;
  out.observed_id = s.observed_id;
  out.observer_seq = s.observer_seq;
  out.x_LA = s.x_LA;
  out.cov_LA = s.cov_LA;
  out.x_AB = s.x_AB;
  out.cov_AB = s.covariance;
  out.observed_seq = s.observed_seq;
  out.x_LB = s.x_LB;
  out.cov_LB = s.cov_LB;
  return out;
}

}  // namespace lmf::server
