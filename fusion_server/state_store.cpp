#include "fusion_server/state_store.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <thread>
#include <utility>


#include "lmf/fusion/global_map_archive.hpp"
#include "lmf/io/binary_archive.hpp"
#include "lmf/io/durable_file.hpp"

namespace lmf::server {
namespace {

namespace fs = std::filesystem;
using fusion::ArchiveError;
using io::ArchiveReader;
using io::ArchiveWriter;
using Clock = std::chrono::steady_clock;

constexpr std::string_view kStateMagic("LMFSTATE", 8);
constexpr std::uint32_t kLcmSync = 0xEDA1DA01u;
constexpr std::size_t kRecordHeader = 4 + 8 + 8 + 4 + 4;
constexpr std::size_t kMaxChannel = 1024;
constexpr std::size_t kMaxData = std::size_t{256} << 20;
constexpr const char* kSnapshot = "snapshot";
constexpr const char* kSnapshotPrev = "snapshot.prev";
constexpr const char* kSnapshotTmp = "snapshot.tmp";

std::string errno_text(const std::string& what, const fs::path& path) {
  return what + " " + path.string() + ": " + std::strerror(errno);
}

void put_be(std::string& out, std::uint64_t v, int bytes) {
  for (int i = bytes - 1; i >= 0; --i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}

std::uint64_t get_be(const char* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | static_cast<unsigned char>(p[i]);
  return v;
}

std::string journal_name(std::int64_t first_lsn) {
  std::ostringstream name;
  name << "journal-";
  name.width(16);
  name.fill('0');
  name << first_lsn << ".lcmlog";
  return name.str();
}

// first lsn -> path of every journal file in dir (names that do not parse are ignored).
std::map<std::int64_t, fs::path> journal_files(const fs::path& dir) {
  std::map<std::int64_t, fs::path> out;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (!e.is_regular_file() || name.rfind("journal-", 0) != 0 || e.path().extension() != ".lcmlog") continue;
    const std::string digits = name.substr(8, name.size() - 8 - 7);
    if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    out[std::stoll(digits)] = e.path();
  }
  return out;
}

// The durable-file primitives (lmf/io/durable_file.hpp), their errors as the store's.
template <typename Action>
void as_state_error(Action&& action) {
  try {
    action();
  } catch (const io::FileError& e) {
    throw StateError(e.what());
  }
}

void sync_dir(const fs::path& dir) {
  as_state_error([&] { io::sync_directory(dir); });
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw StateError("cannot read " + path.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string stamp() {
  return std::to_string(std::chrono::duration_cast<std::chrono::seconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count());
}

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

// A journal file parsed as far as it is good.
struct ParsedJournal {
  std::vector<JournalRecord> records;
  std::uint64_t good_bytes = 0;  // end of the last good record
  std::uint64_t size = 0;
  std::string problem;           // why parsing stopped before the end (empty: clean)
  bool torn = false;             // the problem is a record cut short (a crash mid-write)
};

ParsedJournal parse_journal(const std::string& bytes) {
  ParsedJournal out;
  out.size = bytes.size();
  std::size_t pos = 0;
  while (pos < bytes.size()) {
    const std::size_t left = bytes.size() - pos;
    const char* p = bytes.data() + pos;
    if (left < kRecordHeader) {
      out.problem = "a record header cut short (" + std::to_string(left) + " bytes)";
      out.torn = true;
      break;
    }
    if (get_be(p, 4) != kLcmSync) {
      out.problem = "no LCM sync word";
      break;
    }
    const auto lsn = static_cast<std::int64_t>(get_be(p + 4, 8));
    const auto utime = static_cast<std::int64_t>(get_be(p + 12, 8));
    const std::uint64_t channel_len = get_be(p + 20, 4);
    const std::uint64_t data_len = get_be(p + 24, 4);
    if (channel_len == 0 || channel_len > kMaxChannel || data_len < 4 || data_len > kMaxData) {
      out.problem = "implausible lengths (channel " + std::to_string(channel_len) + ", data " +
                    std::to_string(data_len) + ")";
      break;
    }
    if (left < kRecordHeader + channel_len + data_len) {
      out.problem = "a record cut short (" + std::to_string(left) + " of " +
                    std::to_string(kRecordHeader + channel_len + data_len) + " bytes)";
      out.torn = true;
      break;
    }
    const char* channel = p + kRecordHeader;
    const char* data = channel + channel_len;
    const std::size_t message_len = data_len - 4;
    std::uint32_t c = io::crc32_update(0, p + 4, 16);
    c = io::crc32_update(c, channel, channel_len);
    c = io::crc32_update(c, data, message_len);
    if (c != get_be(data + message_len, 4)) {
      out.problem = "checksum mismatch in record lsn " + std::to_string(lsn);
      break;
    }
    out.records.push_back({lsn, utime, std::string(channel, channel_len), std::string(data, message_len)});
    pos += kRecordHeader + channel_len + data_len;
    out.good_bytes = pos;
  }
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------
// Server state payload

std::string encode_server_state(const FusionContext& fusion, const runtime::auth::HighWater& taken_high_water) {
  const fusion::GlobalMap& map = fusion.map();
  const mission::TrajectoryBook& book = fusion.book();
  const FusionRecords& records = fusion.records();
  std::string out;
  // P's lower triangle dominates: one allocation instead of a doubling series of copies.
  const auto n = static_cast<std::size_t>(map.state().dimension());
  out.reserve(n * (n + 1) / 2 * sizeof(double) + map.state().entities().size() * 64 +
              records.fusions.size() * 256 + 65536);
  ArchiveWriter w(out);
  fusion::write_global_map(w, map);
  w.count(book.shipped().size());
  for (const auto& [robot_id, maps] : book.shipped()) {
    w.i32(robot_id);
    w.count(maps.size());
    for (const auto& [seq, shipped] : maps) {
      w.i64(seq);
      w.pose(shipped.x_LR);
      w.count(shipped.scan_poses.size());
      for (const ScanPose& p : shipped.scan_poses) {
        w.i64(p.utime);
        w.pose(p.x_LR);
      }
    }
  }
  w.count(records.fusions.size());
  for (const FusionRecord& f : records.fusions) {
    fusion::write_fusion_report(w, f.report);
    w.f64(f.queue_wait_ms);
  }
  w.count(records.sightings.size());
  for (const SightingRecord& s : records.sightings) {
    fusion::write_sighting(w, s.sighting);
    w.text(s.status);
  }
  w.f64(records.fusion_ms_sum);
  w.boolean(records.last_covariance_ok);
  w.boolean(records.covariance_always_ok);
  w.boolean(records.last_min_pivot.has_value());
  w.f64(records.last_min_pivot.value_or(0.0));
  w.i64(records.latest_utime);
  w.count(taken_high_water.size());
  for (const auto& [principal, seq] : taken_high_water) {
    w.text(principal);
    w.u64(seq);
  }
  return out;
}

ServerState decode_server_state(const std::string& payload) {
  ArchiveReader r(payload.data(), payload.size(), "server state");
  fusion::GlobalMap map = fusion::read_global_map(r);
  mission::TrajectoryBook book;
  FusionRecords records;
  runtime::auth::HighWater taken_high_water;
  const std::size_t robots = r.count(12);
  for (std::size_t i = 0; i < robots; ++i) {
    const int robot_id = r.i32();
    const std::size_t maps = r.count(40);
    for (std::size_t k = 0; k < maps; ++k) {
      LocalMapSnapshot shipped;
      shipped.robot_id = robot_id;
      shipped.seq = r.i64();
      shipped.x_LR = r.pose();
      shipped.scan_poses.resize(r.count(32));
      for (ScanPose& p : shipped.scan_poses) {
        p.utime = r.i64();
        p.x_LR = r.pose();
      }
      book.add(shipped);
    }
  }
  records.fusions.resize(r.count(64));
  for (FusionRecord& f : records.fusions) {
    f.report = fusion::read_fusion_report(r);
    f.queue_wait_ms = r.f64();
  }
  records.sightings.resize(r.count(64));
  for (SightingRecord& rec : records.sightings) {
    rec.sighting = fusion::read_sighting(r);
    rec.status = r.text();
  }
  records.fusion_ms_sum = r.f64();
  records.last_covariance_ok = r.boolean();
  records.covariance_always_ok = r.boolean();
  const bool has_pivot = r.boolean();
  const double pivot = r.f64();
  if (has_pivot) records.last_min_pivot = pivot;
  records.latest_utime = r.i64();
  const std::size_t signers = r.count(9);
  for (std::size_t i = 0; i < signers; ++i) {
    std::string principal = r.text();
    if (!runtime::auth::is_valid_principal(principal)) r.fail("corrupt: invalid principal in the replay high-water marks");
    taken_high_water[std::move(principal)] = r.u64();
  }
  if (r.remaining() != 0) r.fail("corrupt: " + std::to_string(r.remaining()) + " bytes after the server state");
  return ServerState{FusionContext(std::move(map), std::move(book), std::move(records)), std::move(taken_high_water)};
}

// ---------------------------------------------------------------------------
// The store

StateStore::StateStore(StateStoreOptions options) : options_(std::move(options)) {
  if (options_.dir.empty()) throw StateError("the state directory is empty");
  std::error_code ec;
  fs::create_directories(options_.dir, ec);
  if (ec) throw StateError("cannot create the state directory " + options_.dir.string() + ": " + ec.message());
  const fs::path lock = options_.dir / "lock";
  lock_fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock_fd_ < 0) throw StateError(errno_text("cannot open", lock));
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    char pid[32] = {};
    const ssize_t n = ::pread(lock_fd_, pid, sizeof pid - 1, 0);
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw StateError("the state directory " + options_.dir.string() + " is in use by another process" +
                     (n > 0 ? " (pid " + std::string(pid, static_cast<std::size_t>(n)) + ")" : std::string()));
  }
  const std::string pid = std::to_string(::getpid());
  if (::ftruncate(lock_fd_, 0) != 0 || ::pwrite(lock_fd_, pid.data(), pid.size(), 0) < 0) {
    std::cerr << "lmf-server: state: cannot write the pid into " << lock << '\n';
  }
}

StateStore::~StateStore() {
  {
    std::lock_guard lock(writer_mutex_);
    writer_stop_ = true;  // a submitted snapshot is still written first
  }
  writer_cv_.notify_all();
  if (writer_.joinable()) writer_.join();
  if (journal_fd_ >= 0) ::close(journal_fd_);
  if (lock_fd_ >= 0) ::close(lock_fd_);  // releases the flock
}

Recovery StateStore::recover() {
  Recovery rec;
  const fs::path& dir = options_.dir;
  const std::map<std::int64_t, fs::path> journals = journal_files(dir);
  bool any_snapshot = false;
  for (const char* name : {kSnapshot, kSnapshotPrev}) {
    const fs::path path = dir / name;
    if (!fs::exists(path)) continue;
    any_snapshot = true;
    if (rec.state) continue;  // the newer one is good; the older stays as it is
    try {
      std::ifstream in(path, std::ios::binary);
      if (!in) throw ArchiveError("cannot open");
      std::uint32_t version = 0;
      const std::string payload = io::read_framed(in, kStateMagic, kStateVersion, version);
      if (payload.size() < 8) throw ArchiveError("no lsn");
      std::uint64_t lsn = 0;
      std::memcpy(&lsn, payload.data(), sizeof lsn);
      if (lsn > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) throw ArchiveError("bad lsn");
      rec.state = decode_server_state(payload.substr(8));
      rec.snapshot_lsn = static_cast<std::int64_t>(lsn);
      rec.snapshot_file = name;
    } catch (const std::exception& e) {
      rec.problems.push_back(std::string(name) + " is unusable (" + e.what() +
                             "); moved to damaged/ if another snapshot is used");
      rec.set_aside.push_back(path);
    }
  }
  if (!fs::exists(dir / kSnapshot) && fs::exists(dir / kSnapshotPrev)) {
    rec.problems.push_back("snapshot missing (a crash between its renames): snapshot.prev is the newest");
  }
  rec.fresh = !any_snapshot && journals.empty();
  if (any_snapshot && !rec.state) {
    std::string why;
    for (const std::string& p : rec.problems) why += "\n  " + p;
    throw StateError("no valid snapshot in " + dir.string() + ":" + why +
                     "\nrefusing to start from an empty map; move the directory away to start a new mission");
  }

  // The journal after the snapshot: consecutive lsns from snapshot_lsn + 1.
  std::int64_t expected = rec.snapshot_lsn + 1;
  bool damaged = false;
  for (auto it = journals.begin(); it != journals.end(); ++it) {
    const fs::path& path = it->second;
    const std::string name = path.filename().string();
    if (damaged) {
      rec.problems.push_back(name + " follows a damaged journal record: not replayed, moved to damaged/");
      rec.set_aside.push_back(path);
      continue;
    }
    const auto next = std::next(it);
    if (next != journals.end() && next->first - 1 <= rec.snapshot_lsn) continue;  // all in the snapshot
    ParsedJournal parsed = parse_journal(read_file(path));
    std::string problem = parsed.problem;
    bool torn = parsed.torn;
    std::uint64_t good = parsed.good_bytes;
    std::int64_t file_lsn = it->first;  // what the next record of this file must carry
    std::uint64_t offset = 0;
    for (JournalRecord& r : parsed.records) {
      const std::uint64_t size = kRecordHeader + r.channel.size() + r.data.size() + 4;
      if (r.lsn != file_lsn || (r.lsn > rec.snapshot_lsn && r.lsn != expected)) {
        problem = r.lsn != file_lsn ? "record lsn " + std::to_string(r.lsn) + " where " + std::to_string(file_lsn) +
                                          " belongs"
                                    : "a gap: lsn " + std::to_string(expected) + " is missing, the next one is " +
                                          std::to_string(r.lsn);
        torn = false;
        good = offset;
        break;
      }
      ++file_lsn;
      if (r.lsn == expected) {
        rec.records.push_back(std::move(r));
        ++expected;
      }
      offset += size;
    }
    if (problem.empty()) continue;
    const bool last = next == journals.end();
    const std::uint64_t dropped = parsed.size - good;
    if (last && torn) {
      rec.problems.push_back(name + ": torn tail after lsn " + std::to_string(expected - 1) + " (" +
                             std::to_string(dropped) + " bytes, " + problem +
                             "; cut by a crash, never acknowledged): cut off, kept in damaged/");
    } else {
      rec.problems.push_back(name + ": DAMAGED at byte " + std::to_string(good) + " (" + problem + "); " +
                             std::to_string(dropped) + " bytes from there moved to damaged/; replay stops after lsn " +
                             std::to_string(expected - 1));
      damaged = true;
    }
    rec.cut.emplace_back(path, good);
  }
  if (!rec.state && !rec.records.empty() && rec.records.front().lsn != 1) {
    throw StateError("no snapshot in " + options_.dir.string() + " and the journal starts at lsn " +
                     std::to_string(rec.records.front().lsn) + ": the beginning of the mission is missing");
  }
  return rec;
}

void StateStore::start(const Recovery& recovery, std::int64_t lsn, const std::string& payload) {
  const fs::path& dir = options_.dir;
  const fs::path damaged = dir / "damaged";
  const std::string when = stamp();
  try {
    if (!recovery.set_aside.empty() || !recovery.cut.empty()) fs::create_directories(damaged);
    // Corrupt snapshots first: `snapshot` must not become snapshot.prev.
    for (const fs::path& f : recovery.set_aside) {
      const std::string name = f.filename().string();
      if (name == kSnapshot || name == kSnapshotPrev) fs::rename(f, damaged / (name + "." + when));
    }
    {
      std::lock_guard lock(snapshot_mutex_);
      if (fs::exists(dir / kSnapshot)) snapshot_lsn_ = recovery.snapshot_lsn;  // it was the one used
      if (fs::exists(dir / kSnapshotPrev) && recovery.snapshot_file == kSnapshotPrev) {
        prev_lsn_ = recovery.snapshot_lsn;
      }
    }
    // The state up to `lsn` is durable before anything of the journal is touched.
    write_snapshot_file(lsn, payload);
    for (const auto& [file, keep] : recovery.cut) {
      const std::string bytes = read_file(file);
      if (keep < bytes.size()) {
        std::ofstream tail(damaged / (file.filename().string() + "." + when + ".tail-at-" + std::to_string(keep)),
                           std::ios::binary);
        tail.write(bytes.data() + keep, static_cast<std::streamsize>(bytes.size() - keep));
        if (!tail) throw StateError("cannot write into " + damaged.string());
      }
      fs::resize_file(file, keep);
      const int fd = ::open(file.c_str(), O_WRONLY);
      if (fd >= 0) {
        ::fsync(fd);
        ::close(fd);
      }
    }
    for (const fs::path& f : recovery.set_aside) {
      const std::string name = f.filename().string();
      if (name != kSnapshot && name != kSnapshotPrev) fs::rename(f, damaged / (name + "." + when));
    }
    if (fs::exists(damaged)) sync_dir(damaged);
    sync_dir(dir);
  } catch (const fs::filesystem_error& e) {
    throw StateError(std::string("state directory: ") + e.what());
  }
  {
    std::lock_guard lock(journal_mutex_);
    next_lsn_ = lsn + 1;
    open_journal(next_lsn_);
  }
  std::optional<std::int64_t> covered;
  {
    std::lock_guard lock(snapshot_mutex_);
    covered = prev_lsn_;
  }
  if (covered) prune_journals(*covered);
}

void StateStore::write_snapshot_file(std::int64_t lsn, const std::string& payload) {
  const fs::path& dir = options_.dir;
  const fs::path tmp = dir / kSnapshotTmp;
  std::string framed_payload;
  ArchiveWriter w(framed_payload);
  w.u64(static_cast<std::uint64_t>(lsn));
  std::ostringstream framed;
  io::write_framed(framed, kStateMagic, kStateVersion, framed_payload + payload);
  const std::string bytes = framed.str();

  as_state_error([&] { io::write_file_synced(tmp, bytes); });

  bool pause = false;
  {
    std::lock_guard lock(snapshot_mutex_);
    pause = options_.test_pause_at > 0 && ++attempts_ == options_.test_pause_at;
  }
  if (pause) {
    std::cerr << "lmf-server: state: test pause of " << options_.test_pause.count() << " ms before renaming "
              << tmp << std::endl;
    std::this_thread::sleep_for(options_.test_pause);
  }
  std::lock_guard lock(snapshot_mutex_);
  const fs::path current = dir / kSnapshot;
  if (::access(current.c_str(), F_OK) == 0) {
    if (::rename(current.c_str(), (dir / kSnapshotPrev).c_str()) != 0) {
      throw StateError(errno_text("cannot rename", current));
    }
    prev_lsn_ = snapshot_lsn_;
  }
  if (::rename(tmp.c_str(), current.c_str()) != 0) throw StateError(errno_text("cannot rename", tmp));
  snapshot_lsn_ = lsn;
  ++stats_.written;
  stats_.last_bytes = bytes.size();
  sync_dir(dir);
}

bool StateStore::write_snapshot(std::int64_t lsn, const std::string& payload) {
  const auto started = Clock::now();
  try {
    write_snapshot_file(lsn, payload);
    {
      std::lock_guard lock(journal_mutex_);
      // A new file for the records after this snapshot, unless the open one is still empty.
      if (!journal_broken_ && journal_fd_ >= 0 && journal_size_ > 0) open_journal(next_lsn_);
    }
    std::optional<std::int64_t> covered;
    {
      std::lock_guard lock(snapshot_mutex_);
      covered = prev_lsn_;
      const double ms = ms_since(started);
      stats_.last_ms = ms;
      stats_.max_ms = std::max(stats_.max_ms, ms);
      stats_.total_ms += ms;
    }
    if (covered) prune_journals(*covered);
    return true;
  } catch (const std::exception& e) {
    std::lock_guard lock(snapshot_mutex_);
    ++stats_.failed;
    std::cerr << "lmf-server: state: SNAPSHOT NOT WRITTEN (" << e.what()
              << "); the journal keeps every input since the last one\n";
    return false;
  }
}

bool StateStore::submit_snapshot(std::int64_t lsn, std::string payload, std::string note) {
  {
    std::lock_guard lock(writer_mutex_);
    if (writer_busy_ || writer_stop_) return false;
    writer_busy_ = true;
    job_ = Job{lsn, std::move(payload), std::move(note)};
    if (!writer_.joinable()) writer_ = std::thread([this] { writer_loop(); });
  }
  writer_cv_.notify_all();
  return true;
}

bool StateStore::writer_busy() const {
  std::lock_guard lock(writer_mutex_);
  return writer_busy_;
}

void StateStore::wait_idle() const {
  std::unique_lock lock(writer_mutex_);
  writer_cv_.wait(lock, [this] { return !writer_busy_; });
}

void StateStore::writer_loop() {
  std::unique_lock lock(writer_mutex_);
  while (true) {
    writer_cv_.wait(lock, [this] { return job_.has_value() || writer_stop_; });
    if (!job_) return;
    Job job = std::move(*job_);
    job_.reset();
    lock.unlock();
    if (write_snapshot(job.lsn, job.payload)) {
      const SnapshotStats st = snapshot_stats();
      std::cerr << "lmf-server: state: snapshot " << st.written << " at lsn " << job.lsn << ": " << st.last_bytes
                << " bytes, write " << st.last_ms << " ms" << job.note << '\n';
    }
    lock.lock();
    writer_busy_ = false;
    writer_cv_.notify_all();
  }
}

void StateStore::open_journal(std::int64_t first_lsn) {
  const fs::path path = options_.dir / journal_name(first_lsn);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) throw StateError(errno_text("cannot create", path));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || st.st_size != 0) {
    ::close(fd);
    throw StateError("journal file " + path.string() + " already has data");
  }
  sync_dir(options_.dir);  // the new file's name is durable before a record in it is acknowledged
  if (journal_fd_ >= 0) ::close(journal_fd_);
  journal_fd_ = fd;
  journal_first_lsn_ = first_lsn;
  journal_size_ = 0;
}

std::int64_t StateStore::append(const std::string& channel, const void* data, std::size_t size, std::int64_t utime) {
  if (channel.empty() || channel.size() > kMaxChannel || size + 4 > kMaxData) {
    throw StateError("journal: message on '" + channel + "' of " + std::to_string(size) + " bytes cannot be recorded");
  }
  std::lock_guard lock(journal_mutex_);
  if (journal_fd_ < 0 || journal_broken_) throw StateError("journal: not open (start() not called, or broken)");
  const std::int64_t lsn = next_lsn_;
  std::string record;
  record.reserve(kRecordHeader + channel.size() + size + 4);
  put_be(record, kLcmSync, 4);
  put_be(record, static_cast<std::uint64_t>(lsn), 8);
  put_be(record, static_cast<std::uint64_t>(utime), 8);
  put_be(record, channel.size(), 4);
  put_be(record, size + 4, 4);
  record += channel;
  record.append(static_cast<const char*>(data), size);
  std::uint32_t c = io::crc32_update(0, record.data() + 4, 16);
  c = io::crc32_update(c, channel.data(), channel.size());
  c = io::crc32_update(c, data, size);
  put_be(record, c, 4);
  const fs::path path = options_.dir / journal_name(journal_first_lsn_);
  try {
    as_state_error([&] { io::write_all(journal_fd_, record, path); });
    if (::fdatasync(journal_fd_) != 0) throw StateError(errno_text("cannot fdatasync", path));
  } catch (...) {
    // Undo a partial record so later ones are not written after garbage.
    if (::ftruncate(journal_fd_, static_cast<off_t>(journal_size_)) != 0) journal_broken_ = true;
    throw;
  }
  journal_size_ += record.size();
  ++next_lsn_;
  ++appended_;
  return lsn;
}

void StateStore::prune_journals(std::int64_t covered_lsn) {
  std::int64_t open_first = 0;
  {
    std::lock_guard lock(journal_mutex_);
    open_first = journal_first_lsn_;
  }
  try {
    const std::map<std::int64_t, fs::path> files = journal_files(options_.dir);
    for (auto it = files.begin(); it != files.end(); ++it) {
      const auto next = std::next(it);
      if (next == files.end() || it->first >= open_first) break;
      if (next->first - 1 > covered_lsn) break;
      fs::remove(it->second);
    }
  } catch (const std::exception& e) {
    std::cerr << "lmf-server: state: old journal files not removed: " << e.what() << '\n';
  }
}

std::int64_t StateStore::last_appended_lsn() const {
  std::lock_guard lock(journal_mutex_);
  return next_lsn_ - 1;
}

SnapshotStats StateStore::snapshot_stats() const {
  std::lock_guard lock(snapshot_mutex_);
  return stats_;
}

std::int64_t StateStore::journal_records() const {
  std::lock_guard lock(journal_mutex_);
  return appended_;
}

}  // namespace lmf::server
