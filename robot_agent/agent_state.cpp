#include "robot_agent/agent_state.hpp"

#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>

#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <system_error>
#include <utility>

#include "runtime/convert.hpp"

namespace lmf::robot_agent {
namespace {

constexpr char kMagic[8] = {'L', 'M', 'F', 'A', 'G', 'E', 'N', 'T'};
constexpr std::uint32_t kVersion = 1;
constexpr std::size_t kHeaderSize = sizeof(kMagic) + 4 + 8;
constexpr std::size_t kCrcSize = 4;

std::uint32_t crc32_of(const std::uint8_t* data, std::size_t size) {
  uLong crc = crc32(0L, Z_NULL, 0);
  // zlib takes uInt lengths: feed large buffers in pieces.
  while (size > 0) {
    const std::size_t n = std::min<std::size_t>(size, std::numeric_limits<uInt>::max());
    crc = crc32(crc, data, static_cast<uInt>(n));
    data += n;
    size -= n;
  }
  return static_cast<std::uint32_t>(crc);
}

class Writer {
 public:
  void u8(std::uint8_t v) { out_.push_back(v); }
  void u32(std::uint32_t v) {
    for (int k = 0; k < 4; ++k) out_.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
  }
  void u64(std::uint64_t v) {
    for (int k = 0; k < 8; ++k) out_.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
  }
  void i64(std::int64_t v) { u64(static_cast<std::uint64_t>(v)); }
  void f64(double v) { u64(std::bit_cast<std::uint64_t>(v)); }
  void pose(const Pose2& x) {
    f64(x.x);
    f64(x.y);
    f64(x.phi);
  }
  void bytes(const std::vector<std::uint8_t>& b) {
    u64(b.size());
    out_.insert(out_.end(), b.begin(), b.end());
  }
  std::vector<std::uint8_t>& out() { return out_; }

 private:
  std::vector<std::uint8_t> out_;
};

class Reader {
 public:
  Reader(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  std::uint8_t u8() {
    need(1, "a byte");
    return data_[pos_++];
  }
  std::uint32_t u32() {
    need(4, "a 32-bit field");
    std::uint32_t v = 0;
    for (int k = 0; k < 4; ++k) v |= static_cast<std::uint32_t>(data_[pos_++]) << (8 * k);
    return v;
  }
  std::uint64_t u64() {
    need(8, "a 64-bit field");
    std::uint64_t v = 0;
    for (int k = 0; k < 8; ++k) v |= static_cast<std::uint64_t>(data_[pos_++]) << (8 * k);
    return v;
  }
  std::int64_t i64() { return static_cast<std::int64_t>(u64()); }
  double f64(const char* what) {
    const double v = std::bit_cast<double>(u64());
    if (!std::isfinite(v)) throw AgentStateError(std::string("non-finite ") + what);
    return v;
  }
  Pose2 pose(const char* what) {
    Pose2 x;
    x.x = f64(what);
    x.y = f64(what);
    x.phi = f64(what);
    return x;
  }
  bool flag(const char* what) {
    const std::uint8_t v = u8();
    if (v > 1) throw AgentStateError(std::string("bad flag ") + what);
    return v == 1;
  }
  std::vector<std::uint8_t> bytes() {
    const std::uint64_t n = u64();
    if (n > size_ - pos_) throw AgentStateError("a block of " + std::to_string(n) + " bytes runs past the end");
    std::vector<std::uint8_t> b(data_ + pos_, data_ + pos_ + n);
    pos_ += static_cast<std::size_t>(n);
    return b;
  }
  // A count of items of at least `item_size` bytes each: bounded by what is left.
  std::size_t count(std::size_t item_size, const char* what) {
    const std::uint64_t n = u64();
    if (n > (size_ - pos_) / item_size) {
      throw AgentStateError("count of " + std::string(what) + " (" + std::to_string(n) + ") exceeds the data");
    }
    return static_cast<std::size_t>(n);
  }
  bool at_end() const { return pos_ == size_; }

 private:
  void need(std::size_t n, const char* what) const {
    if (size_ - pos_ < n) throw AgentStateError(std::string("truncated: ") + what + " runs past the end");
  }
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

void write_ack(Writer& w, const runtime::ScanAck& ack) {
  w.i64(ack.utime);
  w.i64(ack.robot_id);
  w.i64(ack.seq);
  w.i64(ack.local_map_seq);
  w.pose(ack.x_LR);
  for (Eigen::Index i = 0; i < 3; ++i) {
    for (Eigen::Index j = 0; j < 3; ++j) w.f64(ack.covariance(i, j));
  }
}

runtime::ScanAck read_ack(Reader& r) {
  runtime::ScanAck ack;
  ack.utime = r.i64();
  ack.robot_id = static_cast<int>(r.i64());
  ack.seq = r.i64();
  ack.local_map_seq = r.i64();
  ack.x_LR = r.pose("acknowledged pose");
  for (Eigen::Index i = 0; i < 3; ++i) {
    for (Eigen::Index j = 0; j < 3; ++j) ack.covariance(i, j) = r.f64("acknowledged covariance");
  }
  return ack;
}

std::string system_error_text(int error) { return std::generic_category().message(error); }

// Closes a file descriptor on scope exit.
struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

std::filesystem::path agent_state_file(const std::filesystem::path& dir, int robot_id) {
  return dir / ("agent" + std::to_string(robot_id) + ".state");
}

std::vector<std::uint8_t> encode_agent_state(const AgentState& s) {
  Writer p;  // payload
  p.i64(s.robot_id);
  p.i64(s.local_map_seq);
  p.u8(s.origin ? 1 : 0);
  if (s.origin) {
    p.i64(s.origin->scan_seq);
    p.i64(s.origin->utime);
    p.pose(s.origin->odometry);
    write_ack(p, s.origin->ack);
  }
  p.u8(s.frame ? 1 : 0);
  if (s.frame) {
    p.i64(s.frame->map_seq);
    p.i64(s.frame->fusion_count);
    p.pose(s.frame->x_WL);
  }
  p.u8(s.mission_ended ? 1 : 0);
  p.i64(s.maps_shipped);
  p.i64(s.maps_acknowledged);
  p.u64(s.shipped_final_x_LR.size());
  for (const auto& [seq, x_LR] : s.shipped_final_x_LR) {
    p.i64(seq);
    p.pose(x_LR);
  }
  p.u64(s.unacknowledged.size());
  for (const auto& [seq, bytes] : s.unacknowledged) {
    p.i64(seq);
    p.bytes(bytes);
  }

  Writer file;
  for (const char c : kMagic) file.u8(static_cast<std::uint8_t>(c));
  file.u32(kVersion);
  file.u64(p.out().size());
  std::vector<std::uint8_t>& out = file.out();
  out.insert(out.end(), p.out().begin(), p.out().end());
  file.u32(crc32_of(out.data(), out.size()));
  return std::move(out);
}

AgentState decode_agent_state(const std::vector<std::uint8_t>& bytes) {
  if (bytes.size() < kHeaderSize + kCrcSize) {
    throw AgentStateError("truncated: " + std::to_string(bytes.size()) + " bytes, shorter than the header");
  }
  if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) throw AgentStateError("not an lmf agent state file");
  Reader header(bytes.data() + sizeof(kMagic), kHeaderSize - sizeof(kMagic));
  const std::uint32_t version = header.u32();
  if (version != kVersion) throw AgentStateError("unsupported version " + std::to_string(version));
  const std::uint64_t payload_size = header.u64();
  if (payload_size != bytes.size() - kHeaderSize - kCrcSize) {
    throw AgentStateError("truncated or extended: the header announces " + std::to_string(payload_size) +
                          " payload bytes, the file holds " + std::to_string(bytes.size() - kHeaderSize - kCrcSize));
  }
  Reader tail(bytes.data() + bytes.size() - kCrcSize, kCrcSize);
  const std::uint32_t stored_crc = tail.u32();
  if (stored_crc != crc32_of(bytes.data(), bytes.size() - kCrcSize)) throw AgentStateError("checksum mismatch");

  Reader r(bytes.data() + kHeaderSize, static_cast<std::size_t>(payload_size));
  AgentState s;
  const std::int64_t robot_id = r.i64();
  if (robot_id < 0 || robot_id > std::numeric_limits<int>::max()) {
    throw AgentStateError("bad robot id " + std::to_string(robot_id));
  }
  s.robot_id = static_cast<int>(robot_id);
  s.local_map_seq = r.i64();
  if (s.local_map_seq < 0) throw AgentStateError("negative local map seq");
  if (r.flag("origin")) {
    AgentState::Origin o;
    o.scan_seq = r.i64();
    o.utime = r.i64();
    o.odometry = r.pose("origin odometry");
    o.ack = read_ack(r);
    if (o.scan_seq < 0) throw AgentStateError("negative origin scan seq");
    s.origin = o;
  } else if (s.local_map_seq != 0) {
    throw AgentStateError("local map " + std::to_string(s.local_map_seq) + " in progress without an origin");
  }
  if (r.flag("frame")) {
    AgentState::Frame f;
    f.map_seq = r.i64();
    f.fusion_count = r.i64();
    f.x_WL = r.pose("corrected frame");
    if (f.map_seq < 0 || f.map_seq > s.local_map_seq) throw AgentStateError("corrected frame of an unknown map");
    s.frame = f;
  }
  s.mission_ended = r.flag("mission end");
  s.maps_shipped = r.i64();
  s.maps_acknowledged = r.i64();
  const std::size_t finals = r.count(8 + 24, "final poses");
  for (std::size_t k = 0; k < finals; ++k) {
    const std::int64_t seq = r.i64();
    if (seq < 0 || seq >= s.local_map_seq || s.shipped_final_x_LR.count(seq) != 0u) {
      throw AgentStateError("final pose of map " + std::to_string(seq) + " out of order");
    }
    s.shipped_final_x_LR[seq] = r.pose("final pose");
  }
  const std::size_t pending = r.count(8 + 8, "unacknowledged maps");
  for (std::size_t k = 0; k < pending; ++k) {
    const std::int64_t seq = r.i64();
    if (seq < 0 || seq >= s.local_map_seq || s.unacknowledged.count(seq) != 0u) {
      throw AgentStateError("unacknowledged map " + std::to_string(seq) + " out of order");
    }
    std::vector<std::uint8_t> map = r.bytes();
    const auto decoded = runtime::decode<LocalMapSnapshot>(map.data(), map.size());
    if (!decoded) {
      throw AgentStateError("unacknowledged map " + std::to_string(seq) + ": " + decoded.rejection().describe());
    }
    if (decoded.value().robot_id != s.robot_id || decoded.value().seq != seq) {
      throw AgentStateError("unacknowledged map " + std::to_string(seq) + " holds robot " +
                            std::to_string(decoded.value().robot_id) + " map " + std::to_string(decoded.value().seq));
    }
    s.unacknowledged[seq] = std::move(map);
  }
  if (!r.at_end()) throw AgentStateError("trailing bytes after the payload");
  return s;
}

void save_agent_state(const std::filesystem::path& file, const AgentState& state) {
  const std::vector<std::uint8_t> bytes = encode_agent_state(state);
  const std::filesystem::path temp = file.string() + ".tmp";
  const auto fail = [&](const std::string& what, const std::filesystem::path& path) {
    throw AgentStateError("cannot " + what + " " + path.string() + ": " + system_error_text(errno));
  };
  {
    Fd out{::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644)};
    if (out.fd < 0) fail("create", temp);
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(out.fd, bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) fail("write", temp);
      done += static_cast<std::size_t>(n);
    }
    if (::fsync(out.fd) != 0) fail("fsync", temp);
    const int fd = out.fd;
    out.fd = -1;
    if (::close(fd) != 0) fail("close", temp);
  }
  if (::rename(temp.c_str(), file.c_str()) != 0) fail("rename onto", file);
  // The rename is durable once the folder's entry is.
  const std::filesystem::path dir = file.has_parent_path() ? file.parent_path() : std::filesystem::path(".");
  Fd folder{::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC)};
  if (folder.fd < 0) fail("open folder", dir);
  if (::fsync(folder.fd) != 0) fail("fsync folder", dir);
}

std::optional<AgentState> load_agent_state(const std::filesystem::path& file) {
  std::error_code error;
  if (!std::filesystem::exists(file, error)) {
    if (error) throw AgentStateError("cannot read " + file.string() + ": " + error.message());
    return std::nullopt;
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) throw AgentStateError("cannot open " + file.string());
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw AgentStateError("cannot read " + file.string());
  try {
    return decode_agent_state(bytes);
  } catch (const AgentStateError& e) {
    throw AgentStateError(file.string() + ": " + e.what());
  }
}

}  // namespace lmf::robot_agent
