// MCAP files damaged the ways files get damaged: cut short by a killed
// recorder (read up to the cut, reported), a flipped bit in a chunk (CRC), an
// unknown compression, a chunk whose records run past its end.
#include <gtest/gtest.h>

#include <fstream>

#include "lmf/bag/bag_file.hpp"
#include "lmf/bag/bag_scans.hpp"
#include "lmf/bag/scan_bag_export.hpp"

namespace lmf::bag {
namespace {

std::vector<LaserScan> scans(int n) {
  std::vector<LaserScan> out;
  for (int k = 0; k < n; ++k) {
    LaserScan s;
    s.utime = 1'000'000 + 100'000 * k;
    s.odometry = Pose2(0.05 * k, 0.0, 0.0);
    s.angle_min_rad = -1.5f;
    s.angle_increment_rad = 0.01f;
    s.max_range_m = 30.0;
    s.ranges_m.assign(301, 2.0 + 0.01 * k);
    out.push_back(s);
  }
  return out;
}

std::vector<char> bytes_of(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}
void write_bytes(const std::filesystem::path& file, const std::vector<char>& bytes) {
  std::ofstream(file, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

class McapDamage : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("lmf-mcap-test-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    // 2000 scans of 301 beams: about 2.6 MB, so three chunks of ~1 MiB.
    write_scan_bag(good(), scans(2000), std::nullopt, {BagFormat::mcap, "none", false});
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path good() const { return dir_ / "good.mcap"; }
  std::filesystem::path damaged() const { return dir_ / "damaged.mcap"; }
  std::filesystem::path dir_;
};

TEST_F(McapDamage, AFileCutShortIsReadUpToTheCutAndSaysSo) {
  const BagSummary whole = summarize_bag(good());
  EXPECT_FALSE(whole.cut_short);
  EXPECT_EQ(whole.topics.size(), 3u);
  auto bytes = bytes_of(good());
  bytes.resize(bytes.size() * 2 / 3);  // inside the last chunk
  write_bytes(damaged(), bytes);
  const BagSummary cut = summarize_bag(damaged());
  ASSERT_TRUE(cut.cut_short);
  EXPECT_NE(cut.cut_short->find("byte"), std::string::npos);
  EXPECT_GT(cut.messages, 0u);
  EXPECT_LT(cut.messages, whole.messages);
  const BagScans read = read_bag_scans(damaged());
  EXPECT_FALSE(read.scans.empty());
  bool noted = false;
  for (const auto& note : read.notes) noted = noted || note.starts_with("CUT SHORT");
  EXPECT_TRUE(noted);
}

TEST_F(McapDamage, AFlippedBitInAChunkIsACrcMismatchNamingTheChunk) {
  auto bytes = bytes_of(good());
  bytes[bytes.size() / 2] ^= 0x10;
  write_bytes(damaged(), bytes);
  try {
    summarize_bag(damaged());
    FAIL() << "read";
  } catch (const BagFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("damaged.mcap"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("Chunk at byte"), std::string::npos);
  }
}

TEST_F(McapDamage, AnUnknownCompressionIsRefusedByName) {
  write_scan_bag(good(), scans(3), std::nullopt, {BagFormat::mcap, "zstd", false});
  auto bytes = bytes_of(good());
  const std::string zstd = "zstd";
  const auto at = std::search(bytes.begin(), bytes.end(), zstd.begin(), zstd.end());
  ASSERT_NE(at, bytes.end());
  std::copy_n("brot", 4, at);
  write_bytes(damaged(), bytes);
  try {
    summarize_bag(damaged());
    FAIL() << "read";
  } catch (const BagFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown compression \"brot\""), std::string::npos);
  }
}

TEST_F(McapDamage, AWrongMagicIsNotABag) {
  auto bytes = bytes_of(good());
  bytes[1] = 'X';
  write_bytes(damaged(), bytes);
  EXPECT_THROW(summarize_bag(damaged()), BagFormatError);
}

}  // namespace
}  // namespace lmf::bag
