// What a robot agent persists to resume after a crash (kill -9 and
// restart an agent, nothing the server acknowledged — nor anything shipped —
// is lost). One file per robot in the agent's --state folder.
//
// Granularity: the chain of local maps up to the ORIGIN of the map in progress
// (the scan where it began: its seq, time and odometry reading), every shipped
// map not yet acknowledged (the encoded local_map_t, resent after a restart),
// the final x_LR of shipped maps the server has not fused (chaining corrected
// frames), the latest corrected frame and the mission-end flag. The content of
// the map in progress is NOT persisted: the scans processed since its origin
// are lost with the process, and the restarted agent bridges them by odometry
// (LocalMap::resume: the first scan after the restart predicts with the motion
// since the origin's odometry reading).
//
// File format (little-endian): "LMFAGENT", u32 version, u64 payload size, the
// payload, u32 CRC-32 (zlib) of everything before it. Written atomically: a
// temporary file in the same folder, fsync, rename over the old one, fsync of
// the folder; a crash leaves either the old or the new file, never a mix.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "lmf/geometry/pose2.hpp"
#include "runtime/messages.hpp"

namespace lmf::robot_agent {

struct AgentState {
  // The scan where the local map in progress began (its origin L): the first
  // scan of the mission for map 0, else the scan that made the previous one ship.
  struct Origin {
    std::int64_t scan_seq = 0;
    std::int64_t utime = 0;
    Pose2 odometry;         // x_OR read with that scan
    runtime::ScanAck ack;   // what the agent acknowledged for it (re-sent if the player resends it)
  };
  struct Frame {  // the latest corrected frame: x_WL is the origin of local map map_seq
    std::int64_t map_seq = 0;
    std::int64_t fusion_count = 0;
    Pose2 x_WL;
  };

  int robot_id = 0;
  std::int64_t local_map_seq = 0;  // the local map in progress
  std::optional<Origin> origin;    // none before the first scan
  std::map<std::int64_t, std::vector<std::uint8_t>> unacknowledged;  // encoded local_map_t, by seq
  std::map<std::int64_t, Pose2> shipped_final_x_LR;                  // by seq, maps not known fused
  std::optional<Frame> frame;
  bool mission_ended = false;
  std::int64_t maps_shipped = 0;       // counters carried over for status messages
  std::int64_t maps_acknowledged = 0;
};

// A state file that exists but cannot be trusted (truncated, checksum or
// format error, another robot's) or cannot be read or written.
class AgentStateError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// <dir>/agent<robot_id>.state
std::filesystem::path agent_state_file(const std::filesystem::path& dir, int robot_id);

// The file's bytes, and back. decode checks the framing, the checksum, every
// size against the bytes left, finite poses, the ordering of sequence numbers
// and that every unacknowledged map decodes as this robot's local_map_t with
// its seq; throws AgentStateError saying what is wrong.
std::vector<std::uint8_t> encode_agent_state(const AgentState& state);
AgentState decode_agent_state(const std::vector<std::uint8_t>& bytes);

// Atomic write (see above). Throws AgentStateError with the path and the
// system's reason on any I/O failure (the old file is then left as it was).
void save_agent_state(const std::filesystem::path& file, const AgentState& state);
// std::nullopt if the file does not exist; throws AgentStateError (naming the
// file) if it cannot be read or decoded.
std::optional<AgentState> load_agent_state(const std::filesystem::path& file);

}  // namespace lmf::robot_agent
