// LCM channel names, defined once (docs/design.md §7): upper case, with a common prefix
// that every process takes from --channel-prefix (default "LMF_"), so two
// systems can share one network without hearing each other.
//
//   <P>SCAN_<id>          laser_scan_t        player -> agent <id>
//   <P>SCAN_ACK           scan_ack_t          agent -> player (lockstep replay)
//   <P>LOCAL_MAP          local_map_t         agent -> server, resent until acked
//   <P>LOCAL_MAP_ACK      local_map_ack_t     server -> agent
//   <P>CORRECTED_FRAMES   corrected_frames_t  server -> agents, after each fusion and periodically
//   <P>SIGHTING           sighting_t          player -> server (a robot sees another), resent until acked
//   <P>SIGHTING_ACK       sighting_ack_t      server -> player
//   <P>GLOBAL_MAP         global_map_t        server -> monitors
//   <P>AGENT_STATUS       agent_status_t      agents -> monitors
//   <P>SERVER_STATUS      server_status_t     server -> monitors
//   <P>MISSION_END        mission_end_t       player -> all (the replay is over)
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace lmf::runtime {

inline constexpr std::string_view kDefaultChannelPrefix = "LMF_";

// The part after the prefix; the only place these strings appear.
namespace channel_suffix {
inline constexpr std::string_view kScan = "SCAN_";  // followed by the robot id in decimal
inline constexpr std::string_view kScanAck = "SCAN_ACK";
inline constexpr std::string_view kLocalMap = "LOCAL_MAP";
inline constexpr std::string_view kLocalMapAck = "LOCAL_MAP_ACK";
inline constexpr std::string_view kCorrectedFrames = "CORRECTED_FRAMES";
inline constexpr std::string_view kSighting = "SIGHTING";
inline constexpr std::string_view kSightingAck = "SIGHTING_ACK";
inline constexpr std::string_view kGlobalMap = "GLOBAL_MAP";
inline constexpr std::string_view kAgentStatus = "AGENT_STATUS";
inline constexpr std::string_view kServerStatus = "SERVER_STATUS";
inline constexpr std::string_view kMissionEnd = "MISSION_END";
}  // namespace channel_suffix

// Immutable; cheap to copy.
class Channels {
 public:
  // Throws std::invalid_argument unless `prefix` is made of A-Z, 0-9 and '_'
  // (it may be empty). Those characters are also literal in an LCM regex.
  explicit Channels(std::string prefix = std::string(kDefaultChannelPrefix));

  const std::string& prefix() const { return prefix_; }

  // <P>SCAN_<id>; throws std::invalid_argument for a negative id.
  std::string scan(int robot_id) const;
  // An LCM subscription regex matching every robot's scan channel (not SCAN_ACK).
  std::string scan_any() const;
  // The robot id of a scan channel name, or nullopt if `channel` is not one.
  std::optional<int> scan_robot(std::string_view channel) const;

  std::string scan_ack() const { return with_prefix(channel_suffix::kScanAck); }
  std::string local_map() const { return with_prefix(channel_suffix::kLocalMap); }
  std::string local_map_ack() const { return with_prefix(channel_suffix::kLocalMapAck); }
  std::string corrected_frames() const { return with_prefix(channel_suffix::kCorrectedFrames); }
  std::string sighting() const { return with_prefix(channel_suffix::kSighting); }
  std::string sighting_ack() const { return with_prefix(channel_suffix::kSightingAck); }
  std::string global_map() const { return with_prefix(channel_suffix::kGlobalMap); }
  std::string agent_status() const { return with_prefix(channel_suffix::kAgentStatus); }
  std::string server_status() const { return with_prefix(channel_suffix::kServerStatus); }
  std::string mission_end() const { return with_prefix(channel_suffix::kMissionEnd); }

  // Every channel of the system as an LCM regex ("<P>.*"), e.g. for a logger.
  std::string all() const { return prefix_ + ".*"; }

 private:
  std::string with_prefix(std::string_view suffix) const { return prefix_ + std::string(suffix); }
  std::string prefix_;
};

}  // namespace lmf::runtime
