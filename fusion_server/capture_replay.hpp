// Re-fusing a captured mission: the local maps and sightings of an lcm-logger
// capture, fed to a ServerNode in capture order, as if they arrived live.
//
// Use: `lmf-server --replay run.lcmlog --config other.json --out DIR` — the same
// node, checks and FIFO fusion as the live server, on a private memq:// bus (no
// network), with another global_map configuration if wanted; the outputs are
// the server's (map.json, map.svg, trajectories, report.json). Resent copies in
// the capture are answered DUPLICATE and fused once, as live. The order is the
// capture's arrival order, which is the live server's unless it deferred a
// local map on a full queue (then it fused the later resend; the replay never
// defers: it waits for room in the worker queue before each message).
//
// Events on other channels (acks, status, scans) are skipped. A capture of a
// system running with --keys is verified when the replaying Bus has keys
// (signer and replay window per sender as live), else read with its trailers
// dropped unverified.
//
// Threading: call from the loop's thread, with the loop not running.
#pragma once

#include <cstdint>
#include <filesystem>

#include "fusion_server/server_node.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"
#include "runtime/event_loop.hpp"

namespace lmf::server {

struct CaptureReplayStats {
  std::int64_t events = 0;      // every event of the capture
  std::int64_t local_maps = 0;  // fed to the node (duplicates included)
  std::int64_t sightings = 0;
  std::int64_t unread_bytes = 0;  // after the last readable event (a truncated capture)
};

// Feeds the capture's local maps and sightings to `node` (subscribed on `bus`,
// which must be an in-process memq:// bus), then waits until the worker has
// applied them all and their outcomes reached the loop. Throws
// std::runtime_error naming the file if it cannot be opened or holds bytes but
// no readable event; a capture readable up to some point is used up to there
// (unread_bytes says how much was left).
CaptureReplayStats replay_capture(const std::filesystem::path& capture, runtime::Bus& bus, runtime::EventLoop& loop,
                                  const ServerNode& node, const runtime::Channels& channels);

}  // namespace lmf::server
