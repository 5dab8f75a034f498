#include "robot_agent/agent_state.hpp"

#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <string_view>
#include <system_error>
#include <utility>

#include "lmf/io/binary_archive.hpp"
#include "lmf/io/durable_file.hpp"
#include "runtime/convert.hpp"

namespace lmf::robot_agent {
namespace {

constexpr std::string_view kMagic("LMFAGENT", 8);
constexpr std::uint32_t kVersion = 1;

// A finite double from the archive (a NaN or inf anywhere in the state is corruption).
double finite(io::ArchiveReader& r, const char* what) {
  const double v = r.f64();
  if (!std::isfinite(v)) throw AgentStateError(std::string("non-finite ") + what);
  return v;
}

Pose2 finite_pose(io::ArchiveReader& r, const char* what) {
  Pose2 x;
  x.x = finite(r, what);
  x.y = finite(r, what);
  x.phi = finite(r, what);
  return x;
}

void write_ack(io::ArchiveWriter& w, const runtime::ScanAck& ack) {
  w.i64(ack.utime);
  w.i64(ack.robot_id);
  w.i64(ack.seq);
  w.i64(ack.local_map_seq);
  w.pose(ack.x_LR);
  for (Eigen::Index i = 0; i < 3; ++i) {
    for (Eigen::Index j = 0; j < 3; ++j) w.f64(ack.covariance(i, j));
  }
}

runtime::ScanAck read_ack(io::ArchiveReader& r) {
  runtime::ScanAck ack;
  ack.utime = r.i64();
  ack.robot_id = static_cast<int>(r.i64());
  ack.seq = r.i64();
  ack.local_map_seq = r.i64();
  ack.x_LR = finite_pose(r, "acknowledged pose");
  for (Eigen::Index i = 0; i < 3; ++i) {
    for (Eigen::Index j = 0; j < 3; ++j) ack.covariance(i, j) = finite(r, "acknowledged covariance");
  }
  return ack;
}

AgentState read_payload(io::ArchiveReader& r) {
  AgentState s;
  const std::int64_t robot_id = r.i64();
  if (robot_id < 0 || robot_id > std::numeric_limits<int>::max()) {
    throw AgentStateError("bad robot id " + std::to_string(robot_id));
  }
  s.robot_id = static_cast<int>(robot_id);
  s.local_map_seq = r.i64();
  if (s.local_map_seq < 0) throw AgentStateError("negative local map seq");
  if (r.boolean()) {
    AgentState::Origin o;
    o.scan_seq = r.i64();
    o.utime = r.i64();
    o.odometry = finite_pose(r, "origin odometry");
    o.ack = read_ack(r);
    if (o.scan_seq < 0) throw AgentStateError("negative origin scan seq");
    s.origin = o;
  } else if (s.local_map_seq != 0) {
    throw AgentStateError("local map " + std::to_string(s.local_map_seq) + " in progress without an origin");
  }
  if (r.boolean()) {
    AgentState::Frame f;
    f.map_seq = r.i64();
    f.fusion_count = r.i64();
    f.x_WL = finite_pose(r, "corrected frame");
    if (f.map_seq < 0 || f.map_seq > s.local_map_seq) throw AgentStateError("corrected frame of an unknown map");
    s.frame = f;
  }
  s.mission_ended = r.boolean();
  s.maps_shipped = r.i64();
  s.maps_acknowledged = r.i64();
  const std::size_t finals = r.count(8 + 24);
  for (std::size_t k = 0; k < finals; ++k) {
    const std::int64_t seq = r.i64();
    if (seq < 0 || seq >= s.local_map_seq || s.shipped_final_x_LR.count(seq) != 0u) {
      throw AgentStateError("final pose of map " + std::to_string(seq) + " out of order");
    }
    s.shipped_final_x_LR[seq] = finite_pose(r, "final pose");
  }
  const std::size_t pending = r.count(8 + 8);
  for (std::size_t k = 0; k < pending; ++k) {
    const std::int64_t seq = r.i64();
    if (seq < 0 || seq >= s.local_map_seq || s.unacknowledged.count(seq) != 0u) {
      throw AgentStateError("unacknowledged map " + std::to_string(seq) + " out of order");
    }
    const std::string text = r.text();
    std::vector<std::uint8_t> map(text.begin(), text.end());
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
  if (r.remaining() != 0) throw AgentStateError("trailing bytes after the payload");
  return s;
}

}  // namespace

std::filesystem::path agent_state_file(const std::filesystem::path& dir, int robot_id) {
  return dir / ("agent" + std::to_string(robot_id) + ".state");
}

std::vector<std::uint8_t> encode_agent_state(const AgentState& s) {
  std::string payload;
  io::ArchiveWriter p(payload);
  p.i64(s.robot_id);
  p.i64(s.local_map_seq);
  p.boolean(s.origin.has_value());
  if (s.origin) {
    p.i64(s.origin->scan_seq);
    p.i64(s.origin->utime);
    p.pose(s.origin->odometry);
    write_ack(p, s.origin->ack);
  }
  p.boolean(s.frame.has_value());
  if (s.frame) {
    p.i64(s.frame->map_seq);
    p.i64(s.frame->fusion_count);
    p.pose(s.frame->x_WL);
  }
  p.boolean(s.mission_ended);
  p.i64(s.maps_shipped);
  p.i64(s.maps_acknowledged);
  p.count(s.shipped_final_x_LR.size());
  for (const auto& [seq, x_LR] : s.shipped_final_x_LR) {
    p.i64(seq);
    p.pose(x_LR);
  }
  p.count(s.unacknowledged.size());
  for (const auto& [seq, bytes] : s.unacknowledged) {
    p.i64(seq);
    p.text(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
  }
  std::ostringstream file;
  io::write_framed(file, kMagic, kVersion, payload);
  const std::string framed = file.str();
  return {framed.begin(), framed.end()};
}

AgentState decode_agent_state(const std::vector<std::uint8_t>& bytes) {
  std::istringstream in(std::string(bytes.begin(), bytes.end()));
  try {
    std::uint32_t version = 0;
    const std::string payload = io::read_framed(in, kMagic, kVersion, version);
    if (in.peek() != std::char_traits<char>::eof()) throw AgentStateError("trailing bytes after the checksum");
    io::ArchiveReader r(payload.data(), payload.size(), "agent state");
    return read_payload(r);
  } catch (const io::ArchiveError& e) {
    throw AgentStateError(e.what());
  }
}

void save_agent_state(const std::filesystem::path& file, const AgentState& state) {
  const std::vector<std::uint8_t> bytes = encode_agent_state(state);
  try {
    io::replace_file_durably(file, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
  } catch (const io::FileError& e) {
    throw AgentStateError(e.what());
  }
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
