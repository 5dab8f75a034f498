#include "lmf/bag/wire_encoder.hpp"

#include <cstring>
#include <string>

namespace lmf::bag {
namespace {

// Little-endian; CDR with its encapsulation header and alignment.
class WireEncoder {
 public:
  explicit WireEncoder(MessageEncoding encoding) : encoding_(encoding) {
    if (encoding_ == MessageEncoding::cdr) bytes_ = {0x00, 0x01, 0x00, 0x00};
  }
  void u32(std::uint32_t v) { put(&v, 4); }
  void i32(std::int32_t v) { put(&v, 4); }
  void f32(float v) { put(&v, 4); }
  void f64(double v) { put(&v, 8); }
  void string(const std::string& s) {
    const bool cdr = encoding_ == MessageEncoding::cdr;
    u32(static_cast<std::uint32_t>(s.size() + (cdr ? 1 : 0)));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    if (cdr) bytes_.push_back(0);
  }
  void time(std::int64_t ns) {
    const std::int64_t sec = ns >= 0 ? ns / 1'000'000'000 : -((-ns + 999'999'999) / 1'000'000'000);
    const auto nsec = static_cast<std::uint32_t>(ns - sec * 1'000'000'000);
    if (encoding_ == MessageEncoding::ros1) {
      u32(static_cast<std::uint32_t>(sec));
    } else {
      i32(static_cast<std::int32_t>(sec));
    }
    u32(nsec);
  }
  void header(const RosHeader& h) {
    if (encoding_ == MessageEncoding::ros1) u32(0);  // seq
    time(h.stamp_ns);
    string(h.frame_id);
  }
  void pose(const RosPose3& p) {
    for (int i = 0; i < 3; ++i) f64(p.translation[i]);
    f64(p.rotation.x());
    f64(p.rotation.y());
    f64(p.rotation.z());
    f64(p.rotation.w());
  }
  void zeros_f64(int n) {
    for (int i = 0; i < n; ++i) f64(0.0);
  }
  std::vector<std::uint8_t> take() { return std::move(bytes_); }

 private:
  void put(const void* v, std::size_t size) {
    if (encoding_ == MessageEncoding::cdr) {
      while ((bytes_.size() - 4) % size != 0) bytes_.push_back(0);
    }
    const auto* p = static_cast<const std::uint8_t*>(v);
    bytes_.insert(bytes_.end(), p, p + size);  // the hosts lmf builds on are little-endian
  }
  MessageEncoding encoding_;
  std::vector<std::uint8_t> bytes_;
};

}  // namespace

std::vector<std::uint8_t> encode_laser_scan(const RosLaserScan& scan, MessageEncoding encoding) {
  WireEncoder e(encoding);
  e.header(scan.header);
  e.f32(scan.angle_min);
  e.f32(scan.angle_max);
  e.f32(scan.angle_increment);
  e.f32(0.0f);  // time_increment
  e.f32(0.0f);  // scan_time
  e.f32(scan.range_min);
  e.f32(scan.range_max);
  e.u32(static_cast<std::uint32_t>(scan.ranges.size()));
  for (const float r : scan.ranges) e.f32(r);
  e.u32(0);  // intensities
  return e.take();
}

std::vector<std::uint8_t> encode_odometry(const RosOdometry& odometry, MessageEncoding encoding) {
  WireEncoder e(encoding);
  e.header(odometry.header);
  e.string(odometry.child_frame_id);
  e.pose(odometry.pose);
  e.zeros_f64(36 + 6 + 36);  // pose covariance, twist, twist covariance
  return e.take();
}

std::vector<std::uint8_t> encode_tf_message(const std::vector<RosTransform>& transforms, MessageEncoding encoding) {
  WireEncoder e(encoding);
  e.u32(static_cast<std::uint32_t>(transforms.size()));
  for (const auto& t : transforms) {
    e.header(t.header);
    e.string(t.child_frame_id);
    e.pose(t.transform);
  }
  return e.take();
}

}  // namespace lmf::bag
