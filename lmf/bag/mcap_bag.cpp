#include "lmf/bag/mcap_bag.hpp"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>

#include <zlib.h>

#include "lmf/bag/decompress.hpp"
#include "lmf/bag/container_support.hpp"

namespace lmf::bag::mcap {
namespace {

constexpr std::uint8_t kFooter = 0x02, kSchema = 0x03, kChannel = 0x04, kMessage = 0x05, kChunk = 0x06,
                       kDataEnd = 0x0F;
constexpr std::size_t kMagicSize = 8;

// Little-endian fields of one record's content; `base` is the content's file
// offset (or the chunk's, for records inside one) for error messages.
class Fields {
 public:
  Fields(const std::filesystem::path& file, std::span<const std::uint8_t> bytes, std::uint64_t base,
         const char* record)
      : file_(file), bytes_(bytes), base_(base), record_(record) {}

  std::uint64_t uint(std::size_t size, const char* what) {
    const std::uint8_t* p = take(size, what);
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < size; ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
    return v;
  }
  std::string string(const char* what) {
    const auto n = static_cast<std::size_t>(uint(4, what));
    const std::uint8_t* p = take(n, what);
    return {reinterpret_cast<const char*>(p), n};
  }
  std::span<const std::uint8_t> bytes(std::size_t n, const char* what) { return {take(n, what), n}; }
  std::span<const std::uint8_t> rest() { return bytes_.subspan(at_); }

 private:
  const std::uint8_t* take(std::size_t n, const char* what) {
    if (n > bytes_.size() - at_) {
      throw BagFormatError(file_, std::string("MCAP ") + record_ + " record at byte " + std::to_string(base_) +
                                      ": its " + what + " runs past the record's end");
    }
    const std::uint8_t* p = bytes_.data() + at_;
    at_ += n;
    return p;
  }
  const std::filesystem::path& file_;
  std::span<const std::uint8_t> bytes_;
  std::uint64_t base_;
  const char* record_;
  std::size_t at_ = 0;
};

struct Channel {
  std::string topic;
  std::string type;
  std::string encoding;
};

std::optional<MessageEncoding> message_encoding(const std::string& name) {
  if (name == "cdr") return MessageEncoding::cdr;
  if (name == "ros1") return MessageEncoding::ros1;
  return std::nullopt;
}

// Walks the data section; `on_message(channel, log_time, data)` for each message.
class DataWalker {
 public:
  DataWalker(const std::filesystem::path& file, BagSummary& summary) : file_(file), summary_(summary) {}

  template <typename OnMessage>
  void walk(OnMessage&& on_message) {
    std::ifstream in(file_, std::ios::binary);
    if (!in) throw std::runtime_error(file_.string() + ": cannot open");
    const std::uint64_t size = std::filesystem::file_size(file_);
    std::uint64_t at = kMagicSize;
    std::vector<std::uint8_t> content;
    while (at < size) {
      if (size - at < 9) {
        summary_.cut_short = "the file ends inside the record header at byte " + std::to_string(at);
        return;
      }
      std::uint8_t head[9];
      in.seekg(static_cast<std::streamoff>(at));
      in.read(reinterpret_cast<char*>(head), 9);
      const std::uint8_t opcode = head[0];
      std::uint64_t length = 0;
      for (int i = 0; i < 8; ++i) length |= static_cast<std::uint64_t>(head[1 + i]) << (8 * i);
      if (length > size - at - 9) {
        summary_.cut_short = "record 0x" + hex(opcode) + " at byte " + std::to_string(at) + " needs " +
                             std::to_string(length) + " bytes, the file ends after " + std::to_string(size - at - 9);
        return;
      }
      if (opcode == kFooter || opcode == kDataEnd) return;
      if (opcode == kSchema || opcode == kChannel || opcode == kMessage || opcode == kChunk) {
        content.resize(static_cast<std::size_t>(length));
        in.read(reinterpret_cast<char*>(content.data()), static_cast<std::streamsize>(length));
        if (opcode == kChunk) {
          chunk(content, at + 9, on_message);
        } else {
          record(opcode, content, at + 9, on_message);
        }
      }
      at += 9 + length;
    }
    summary_.cut_short = "the file ends without a Data End or Footer record";
  }

  std::set<std::string> compressions;  // of the chunks read ("none" for uncompressed)

 private:
  static std::string hex(std::uint8_t v) {
    const char* digits = "0123456789abcdef";
    return {digits[v >> 4], digits[v & 15]};
  }

  template <typename OnMessage>
  void record(std::uint8_t opcode, std::span<const std::uint8_t> content, std::uint64_t base, OnMessage& on_message) {
    if (opcode == kSchema) {
      Fields f(file_, content, base, "Schema");
      const auto id = static_cast<std::uint16_t>(f.uint(2, "id"));
      schemas_[id] = f.string("name");
    } else if (opcode == kChannel) {
      Fields f(file_, content, base, "Channel");
      const auto id = static_cast<std::uint16_t>(f.uint(2, "id"));
      const auto schema_id = static_cast<std::uint16_t>(f.uint(2, "schema_id"));
      Channel c;
      c.topic = f.string("topic");
      c.encoding = f.string("message_encoding");
      const auto schema = schemas_.find(schema_id);
      if (schema_id != 0 && schema == schemas_.end()) {
        throw BagFormatError(file_, "MCAP Channel record at byte " + std::to_string(base) + " (" + c.topic +
                                        ") names schema " + std::to_string(schema_id) + ", which came before it nowhere");
      }
      c.type = schema_id == 0 ? "" : schema->second;
      channels_[id] = std::move(c);
    } else if (opcode == kMessage) {
      Fields f(file_, content, base, "Message");
      const auto channel_id = static_cast<std::uint16_t>(f.uint(2, "channel_id"));
      f.uint(4, "sequence");
      const auto log_time = static_cast<std::int64_t>(f.uint(8, "log_time"));
      f.uint(8, "publish_time");
      const auto channel = channels_.find(channel_id);
      if (channel == channels_.end()) {
        throw BagFormatError(file_, "MCAP Message record at byte " + std::to_string(base) + " is on channel " +
                                        std::to_string(channel_id) + ", which no Channel record before it defines");
      }
      on_message(channel->second, log_time, f.rest(), base);
    }
  }

  template <typename OnMessage>
  void chunk(std::span<const std::uint8_t> content, std::uint64_t base, OnMessage& on_message) {
    Fields f(file_, content, base, "Chunk");
    f.uint(8, "message_start_time");
    f.uint(8, "message_end_time");
    const std::uint64_t uncompressed_size = f.uint(8, "uncompressed_size");
    const auto crc = static_cast<std::uint32_t>(f.uint(4, "uncompressed_crc"));
    const std::string compression = f.string("compression");
    const std::span<const std::uint8_t> records = f.bytes(static_cast<std::size_t>(f.uint(8, "records length")), "records");
    const std::string where = "MCAP Chunk at byte " + std::to_string(base);
    compressions.insert(compression.empty() ? "none" : compression);

    std::span<const std::uint8_t> plain = records;
    if (!compression.empty()) {
      try {
        buffer_ = decompress(compression, records, uncompressed_size);
      } catch (const std::runtime_error& e) {
        throw BagFormatError(file_, where + ": " + e.what() + " (none, zstd and lz4 are read)");
      }
      plain = buffer_;
    } else if (uncompressed_size != records.size()) {
      throw BagFormatError(file_, where + ": uncompressed, but uncompressed_size differs from the records' length");
    }
    if (crc != 0) {
      const auto actual = static_cast<std::uint32_t>(crc32(0L, plain.data(), static_cast<uInt>(plain.size())));
      if (actual != crc) throw BagFormatError(file_, where + ": CRC-32 mismatch (the chunk is damaged)");
    }
    for (std::size_t at = 0; at < plain.size();) {
      Fields r(file_, plain.subspan(at), base, "Chunk");
      const auto opcode = static_cast<std::uint8_t>(r.uint(1, "record opcode"));
      const std::uint64_t length = r.uint(8, "record length");
      const std::span<const std::uint8_t> inner = r.bytes(static_cast<std::size_t>(length), "record");
      record(opcode, inner, base, on_message);
      at += 9 + static_cast<std::size_t>(length);
    }
  }

  const std::filesystem::path& file_;
  BagSummary& summary_;
  std::map<std::uint16_t, std::string> schemas_;
  std::map<std::uint16_t, Channel> channels_;
  std::vector<std::uint8_t> buffer_;
};

}  // namespace

BagSummary summarize(const std::filesystem::path& file) {
  SummaryCounter counter(BagFormat::mcap);
  DataWalker walker(file, counter.summary());
  walker.walk([&](const Channel& c, std::int64_t log_time, std::span<const std::uint8_t>, std::uint64_t) {
    counter.count(c.topic, c.type, log_time);
  });
  return counter.finish(walker.compressions);
}

void for_each_message(const std::filesystem::path& file, const std::set<std::string>& topics,
                      const std::function<void(const BagMessage&)>& visit) {
  BagSummary summary;
  TimeOrderedMessages messages;
  DataWalker walker(file, summary);
  walker.walk([&](const Channel& c, std::int64_t log_time, std::span<const std::uint8_t> data, std::uint64_t at) {
    if (!topics.empty() && !topics.contains(c.topic)) return;
    const auto encoding = message_encoding(c.encoding);
    if (!encoding) {
      throw BagFormatError(file, "MCAP message at byte " + std::to_string(at) + " on " + c.topic + ": encoding \"" +
                                     c.encoding + "\" is not read (cdr and ros1 are)");
    }
    messages.add(c.topic, c.type, log_time, *encoding, data);
  });
  messages.visit_in_time_order(visit);
}

}  // namespace lmf::bag::mcap
