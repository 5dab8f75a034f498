// Fuzz target: the ROS message decoders of lmf/bag (decode_laser_scan,
// decode_odometry, decode_tf_message) in both encodings. The first byte picks
// the message and the encoding, the rest is the message. A malformed message
// must throw WireDecodeError at an offset inside it; anything else thrown is a
// crash, and a decoded scan's ranges must fit the bytes it came from.
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "fuzz_support.hpp"
#include "lmf/bag/ros_messages.hpp"
#include "lmf/bag/wire_encoder.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  using lmf::bag::MessageEncoding;
  const MessageEncoding encoding = (data[0] & 1) != 0 ? MessageEncoding::cdr : MessageEncoding::ros1;
  const std::span<const std::uint8_t> message(data + 1, size - 1);
  std::string_view outcome = "accepted";
  try {
    switch ((data[0] >> 1) % 3) {
      case 0: {
        const auto scan = lmf::bag::decode_laser_scan(message, encoding);
        if (scan.ranges.size() * 4 > message.size()) throw std::logic_error("more ranges than bytes");
        break;
      }
      case 1:
        lmf::bag::decode_odometry(message, encoding);
        break;
      default:
        lmf::bag::decode_tf_message(message, encoding);
        break;
    }
  } catch (const lmf::bag::WireDecodeError& e) {
    if (e.offset() > message.size()) throw std::logic_error("WireDecodeError offset past the message");
    outcome = "decode_error";
  }
  lmf::fuzz::note_outcome(outcome);
  return 0;
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  using lmf::bag::MessageEncoding;
  lmf::bag::RosLaserScan scan;
  scan.header = {1'000'000'000, "laser"};
  scan.angle_min = -1.5f;
  scan.angle_max = 1.5f;
  scan.angle_increment = 0.5f;
  scan.range_max = 30.0f;
  scan.ranges = {1.0f, 2.0f, 3.0f, 4.0f, 5.0f, 6.0f, 7.0f};
  lmf::bag::RosOdometry odometry;
  odometry.header = {1'000'000'000, "odom"};
  odometry.child_frame_id = "base_link";
  lmf::bag::RosTransform transform;
  transform.header = {1'000'000'000, "base_link"};
  transform.child_frame_id = "laser";
  std::vector<lmf::fuzz::Bytes> seeds;
  for (const MessageEncoding encoding : {MessageEncoding::ros1, MessageEncoding::cdr}) {
    const std::uint8_t e = encoding == MessageEncoding::cdr ? 1 : 0;
    const auto add = [&](std::uint8_t kind, const std::vector<std::uint8_t>& bytes) {
      lmf::fuzz::Bytes seed{static_cast<std::uint8_t>((kind << 1) | e)};
      seed.insert(seed.end(), bytes.begin(), bytes.end());
      seeds.push_back(std::move(seed));
    };
    add(0, lmf::bag::encode_laser_scan(scan, encoding));
    add(1, lmf::bag::encode_odometry(odometry, encoding));
    add(2, lmf::bag::encode_tf_message({transform, transform}, encoding));
  }
  return seeds;
}
