// Shared by the bag container fuzz targets: the input written to a file of
// this process's own, then read whole as lmf-offline --bag would (summary,
// every message decoded where its type is one lmf reads). A damaged file must
// give BagFormatError naming the file (or std::invalid_argument when it holds
// no scans); anything else thrown, or any crash, is a finding.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.hpp"
#include "lmf/bag/bag_file.hpp"
#include "lmf/bag/bag_scans.hpp"
#include "lmf/bag/ros_messages.hpp"
#include "lmf/bag/scan_bag_export.hpp"

namespace lmf::fuzz {

inline std::filesystem::path bag_fuzz_file(const char* extension) {
  return std::filesystem::temp_directory_path() / ("lmf-fuzz-bag-" + std::to_string(::getpid()) + extension);
}

inline void fuzz_bag_file(const uint8_t* data, size_t size, const char* extension) {
  const std::filesystem::path file = bag_fuzz_file(extension);
  std::ofstream(file, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  std::string_view outcome = "accepted";
  try {
    lmf::bag::summarize_bag(file);
    lmf::bag::for_each_bag_message(file, {}, [](const lmf::bag::BagMessage& m) {
      try {
        if (lmf::bag::is_laser_scan_type(m.type)) lmf::bag::decode_laser_scan(m.data, m.encoding);
        if (lmf::bag::is_odometry_type(m.type)) lmf::bag::decode_odometry(m.data, m.encoding);
        if (lmf::bag::is_tf_type(m.type)) lmf::bag::decode_tf_message(m.data, m.encoding);
      } catch (const lmf::bag::WireDecodeError&) {
      }
    });
    lmf::bag::read_bag_scans(file);
  } catch (const lmf::bag::BagFormatError& e) {
    if (std::string(e.what()).find(file.filename().string()) == std::string::npos) {
      throw std::logic_error(std::string("BagFormatError without the file's name: ") + e.what());
    }
    outcome = "format_error";
  } catch (const std::invalid_argument&) {
    outcome = "no_scans";
  }
  note_outcome(outcome);
}

// Bags of a few scans written by lmf-convert's writer, read back as bytes.
inline std::vector<Bytes> bag_fuzz_seeds(lmf::bag::BagFormat format, const std::vector<std::string>& compressions,
                                         const char* extension) {
  std::vector<LaserScan> scans;
  for (int k = 0; k < 3; ++k) {
    LaserScan s;
    s.utime = 1'000'000 + 100'000 * k;
    s.odometry = Pose2(0.1 * k, 0.0, 0.05 * k);
    s.angle_min_rad = -1.5;
    s.angle_increment_rad = 0.5;
    s.max_range_m = 30.0;
    s.ranges_m = {1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0};
    scans.push_back(s);
  }
  std::vector<Bytes> seeds;
  const std::filesystem::path file = bag_fuzz_file(extension);
  for (const auto& compression : compressions) {
    lmf::bag::write_scan_bag(file, scans, std::nullopt, {format, compression, false});
    std::ifstream in(file, std::ios::binary);
    seeds.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  return seeds;
}

}  // namespace lmf::fuzz
