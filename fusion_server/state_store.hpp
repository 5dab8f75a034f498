// The fusion server's durable state in --state DIR: a checksummed
// snapshot of everything the server knows, plus an append-only journal of
// every input accepted since, so that a server killed at any instant restarts
// with the same map it would have had, and nothing it acknowledged is lost.
//
// Files in DIR
//   lock                   flock()ed by the running server (a second server on
//                          the same DIR refuses to start); holds its pid
//   snapshot               the latest snapshot
//   snapshot.prev          the one before: the fallback if `snapshot` is corrupt
//   snapshot.tmp           a snapshot being written (ignored; replaced next time)
//   journal-<lsn>.lcmlog   journal files; <lsn> (16 digits) is the number of
//                          their first record; a new file starts at each snapshot
//   damaged/               anything recovery found corrupt and did not use
//                          (kept for inspection, never read again)
//
// Snapshot file: a framed archive (lmf/fusion/global_map_archive.hpp) with
// magic "LMFSTATE", version kStateVersion, CRC-32 over everything; its payload
// is u64 lsn (the last journal record reflected in it) followed by the
// server's state (encode_server_state: the GlobalMap archive payload, the
// TrajectoryBook, the fusion and sighting records of report.json, the
// authentication high-water marks).
//
// Journal record: one event of an LCM event log (lcm-logplayer/lcm-spy format,
// big-endian): sync word 0xEDA1DA01, i64 eventnum = lsn, i64 timestamp (wall
// clock at receipt, us), i32 channel length, i32 data length, the channel the
// message arrived on, data = the message bytes as received (an authenticated
// server keeps the trailer: recovery reads its signer and seq back into the
// replay windows and strips it before decoding) followed by a
// 4-byte big-endian CRC-32 of (eventnum, timestamp, channel, message). LSNs are
// 1, 2, 3, ... consecutive across files. (lmf processes would reject the
// 4-byte trailer: the journal is a record, not something to replay on a bus.)
//
// Write policy
//   * append(): one write() of the whole record, then fdatasync(), BEFORE the
//     caller hands the input to the fusion worker, so every input that was
//     acknowledged (acks follow the fusion) is on disk. A new journal file is
//     made durable by an fsync of DIR when it is created.
//   * write_snapshot(): snapshot.tmp written and fsync'ed, then
//     snapshot -> snapshot.prev, snapshot.tmp -> snapshot (rename), fsync of
//     DIR; then a new journal file is started and journal files whose records
//     are all covered by snapshot.prev are deleted (the fallback still has its
//     journal).
//
// Recovery (recover(), then start()): the newest valid snapshot (checksum,
// version, structure) — `snapshot`, else `snapshot.prev` — and the journal
// records after its lsn, in order, each checked (sync word, lengths, CRC,
// consecutive lsn). The first bad or missing record ends the replay: the good
// prefix is used and the problem reported. A torn tail of the last journal
// file (a record cut by a crash: never acknowledged) is cut off; any other
// damage (a corrupt snapshot, a bad record with data after it, a gap) is moved
// to damaged/ and reported. Snapshot files that all fail verification are a
// StateError: the server refuses to start rather than start from an empty map.
// A DIR with no snapshot and a journal from lsn 1 is replayed from the start.
//
// Threading: append() from the receiving thread, write_snapshot() or
// submit_snapshot() from the fusion worker, concurrently (a mutex guards the
// journal file); recover() and start() before either. submit_snapshot() hands
// an encoded snapshot to the store's own writer thread, so the fsyncs of a
// large snapshot (72 MB at 2000 segments) do not hold up the fusions.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "fusion_server/fusion_context.hpp"
#include "lmf/fusion/global_map.hpp"
#include "lmf/mission/trajectory_book.hpp"
#include "runtime/auth.hpp"
#include "runtime/messages.hpp"

namespace lmf::server {

// 3: the global map inside is kGlobalMapArchiveVersion 3 (robot footprints), fusion
// reports carry footprint_segments_removed. 4: archive version 4 (crossing
// segments), fusion reports carry crossing_segments_removed. 5: the global map
// inside is kGlobalMapArchiveVersion 5 (no transient re-entrancy flag). 6: archive
// version 6 (frame registration), fusion reports carry its outcome. 7: the
// authentication high-water marks (per signer, the highest seq of an input
// applied) follow the server state. 8: sighting records in the GlobalMap
// archive's layout (one serializer for fusion::RobotSighting). 9: fusion reports
// carry the robot's frame as predicted and as fused. 10: archive version 7
// (registration.confirm_pairings), fusion reports count the unconfirmed pairs.
inline constexpr std::uint32_t kStateVersion = 10;

// The state directory cannot be used (in use, unreadable, every snapshot corrupt, I/O error).
class StateError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One fusion as recorded for report.json.
// Everything the server keeps besides its loop-side counters.
struct ServerState {
  FusionContext fusion;
  runtime::auth::HighWater taken_high_water;  // empty unless signatures were verified
};

// The server state's bytes (the snapshot payload after the lsn) and back;
// decode throws fusion::ArchiveError for anything malformed.
std::string encode_server_state(const FusionContext& fusion, const runtime::auth::HighWater& taken_high_water);
ServerState decode_server_state(const std::string& payload);

struct JournalRecord {
  std::int64_t lsn = 0;
  std::int64_t utime = 0;  // wall clock at receipt, us
  std::string channel;
  std::string data;        // the message as received (with its authentication trailer when verified)
};

struct Recovery {
  bool fresh = true;                     // nothing in DIR: a new mission
  std::optional<ServerState> state;      // decoded from the snapshot used
  std::string snapshot_file;             // "snapshot" or "snapshot.prev" (empty if none)
  std::int64_t snapshot_lsn = 0;
  std::vector<JournalRecord> records;    // lsn snapshot_lsn + 1, + 2, ... in order
  std::vector<std::string> problems;     // what was corrupt, torn or missing, and what is done about it
  std::int64_t last_lsn() const { return records.empty() ? snapshot_lsn : records.back().lsn; }

  // For start(): files to move to damaged/ whole, and journal files to cut
  // at a byte offset (the cut-off tail is copied to damaged/ first).
  std::vector<std::filesystem::path> set_aside;
  std::vector<std::pair<std::filesystem::path, std::uint64_t>> cut;
};

struct StateStoreOptions {
  std::filesystem::path dir;
  // Testing only (crash tests): sleep this long after snapshot.tmp is written
  // and synced, before it is renamed, in the test_pause_at-th snapshot this
  // process writes (1: the one start() writes).
  int test_pause_at = 0;  // 0: never
  std::chrono::milliseconds test_pause{0};
};

struct SnapshotStats {
  std::int64_t written = 0;
  std::int64_t failed = 0;
  std::uint64_t last_bytes = 0;
  double last_ms = 0.0;  // encode not included: file write + fsyncs + renames + rotation
  double max_ms = 0.0;
  double total_ms = 0.0;
};

class StateStore {
 public:
  // Creates DIR if needed and locks it. Throws StateError if it is locked by
  // another process or cannot be created.
  explicit StateStore(StateStoreOptions options);
  ~StateStore();
  StateStore(const StateStore&) = delete;
  StateStore& operator=(const StateStore&) = delete;

  // Reads DIR (see the header comment); changes nothing on disk. Throws
  // StateError if snapshot files exist and none is valid, or DIR is unreadable.
  Recovery recover();

  // After the caller re-applied `recovery`: writes the snapshot of state `lsn`
  // (= recovery.last_lsn()), sets aside what recovery found damaged, and opens
  // the journal at lsn + 1. Throws StateError on I/O failure.
  void start(const Recovery& recovery, std::int64_t lsn, const std::string& payload);

  // Appends one received message to the journal, durably; returns its lsn.
  // Throws StateError on I/O failure (the message must then not be applied).
  std::int64_t append(const std::string& channel, const void* data, std::size_t size, std::int64_t utime);

  // Writes the snapshot of state `lsn` (every record up to lsn applied).
  // Returns false (and reports on stderr) on I/O failure: the journal then
  // keeps growing and the previous snapshot stays valid.
  bool write_snapshot(std::int64_t lsn, const std::string& payload);

  // write_snapshot() on the writer thread. False (nothing taken) while the
  // previous one is still being written: the caller stays dirty and tries
  // again later (the journal holds everything meanwhile). `note` is appended
  // to the line logged on stderr once it is written.
  bool submit_snapshot(std::int64_t lsn, std::string payload, std::string note = {});
  bool writer_busy() const;
  void wait_idle() const;  // until no snapshot is being written

  const std::filesystem::path& dir() const { return options_.dir; }
  std::int64_t last_appended_lsn() const;
  SnapshotStats snapshot_stats() const;
  std::int64_t journal_records() const;  // appended by this process

 private:
  void write_snapshot_file(std::int64_t lsn, const std::string& payload);  // throws StateError
  void open_journal(std::int64_t first_lsn);  // journal mutex held
  void prune_journals(std::int64_t covered_lsn);

  StateStoreOptions options_;
  int lock_fd_ = -1;
  mutable std::mutex journal_mutex_;
  int journal_fd_ = -1;
  std::int64_t journal_first_lsn_ = 0;  // of the open journal file
  std::uint64_t journal_size_ = 0;
  bool journal_broken_ = false;         // a failed append could not be undone
  std::int64_t next_lsn_ = 1;
  std::int64_t appended_ = 0;
  mutable std::mutex snapshot_mutex_;
  std::optional<std::int64_t> snapshot_lsn_;  // of `snapshot`, if any
  std::optional<std::int64_t> prev_lsn_;  // of `snapshot.prev`, if any
  std::int64_t attempts_ = 0;             // snapshot files written (for the test pause)
  SnapshotStats stats_;

  // The writer thread (started on the first submit_snapshot()).
  void writer_loop();
  struct Job {
    std::int64_t lsn = 0;
    std::string payload;
    std::string note;
  };
  mutable std::mutex writer_mutex_;
  mutable std::condition_variable writer_cv_;
  std::optional<Job> job_;
  bool writer_busy_ = false;
  bool writer_stop_ = false;
  std::thread writer_;
};

}  // namespace lmf::server
