#include "lmf/bag/ros1_bag.hpp"

#include <fstream>
#include <map>
#include <optional>

#include "lmf/bag/decompress.hpp"
#include "lmf/bag/container_support.hpp"

namespace lmf::bag::ros1 {
namespace {

constexpr std::uint8_t kMessageData = 0x02, kBagHeader = 0x03, kIndexData = 0x04, kChunk = 0x05, kConnection = 0x07;
constexpr std::uint64_t kMagicSize = 13;  // "#ROSBAG V2.0\n"

std::uint64_t little_endian(std::span<const std::uint8_t> bytes) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < bytes.size() && i < 8; ++i) v |= static_cast<std::uint64_t>(bytes[i]) << (8 * i);
  return v;
}

// A record header's fields: name -> value bytes. Throws BagFormatError.
std::map<std::string, std::span<const std::uint8_t>> fields(std::span<const std::uint8_t> header,
                                                            const std::filesystem::path& file, const std::string& where) {
  std::map<std::string, std::span<const std::uint8_t>> out;
  for (std::size_t at = 0; at < header.size();) {
    if (header.size() - at < 4) throw BagFormatError(file, where + ": a header field's length is cut");
    const auto n = static_cast<std::size_t>(little_endian(header.subspan(at, 4)));
    if (n > header.size() - at - 4) throw BagFormatError(file, where + ": a header field runs past the header");
    const auto field = header.subspan(at + 4, n);
    std::size_t eq = 0;
    while (eq < field.size() && field[eq] != '=') ++eq;
    if (eq == field.size()) throw BagFormatError(file, where + ": a header field without '='");
    out[std::string(field.begin(), field.begin() + static_cast<std::ptrdiff_t>(eq))] = field.subspan(eq + 1);
    at += 4 + n;
  }
  return out;
}

std::span<const std::uint8_t> field(const std::map<std::string, std::span<const std::uint8_t>>& f, const char* name,
                                    std::size_t size, const std::filesystem::path& file, const std::string& where) {
  const auto it = f.find(name);
  if (it == f.end() || (size != 0 && it->second.size() != size)) {
    throw BagFormatError(file, where + ": no " + (size != 0 ? std::to_string(size) + "-byte " : "") + "field \"" +
                                   name + "\"");
  }
  return it->second;
}

std::string text(std::span<const std::uint8_t> bytes) { return {bytes.begin(), bytes.end()}; }

struct Connection {
  std::string topic;
  std::string type;
};

// Walks the records; on_message(connection, log time, data) for each message.
class RecordWalker {
 public:
  RecordWalker(const std::filesystem::path& file, BagSummary& summary) : file_(file), summary_(summary) {}

  template <typename OnMessage>
  void walk(OnMessage&& on_message) {
    std::ifstream in(file_, std::ios::binary);
    if (!in) throw std::runtime_error(file_.string() + ": cannot open");
    const std::uint64_t size = std::filesystem::file_size(file_);
    std::uint64_t at = kMagicSize;
    std::vector<std::uint8_t> record;
    bool indexed = false;
    while (at < size) {
      const auto cut = [&](const std::string& why) {
        summary_.cut_short = why + " at byte " + std::to_string(at) + (indexed ? "" : " (the bag has no index)");
      };
      std::uint8_t word[4];
      if (size - at < 4) return cut("the file ends inside a record");
      in.seekg(static_cast<std::streamoff>(at));
      in.read(reinterpret_cast<char*>(word), 4);
      const std::uint64_t header_len = little_endian(word);
      if (header_len > size - at - 4 || size - at - 4 - header_len < 4) return cut("the file ends inside a record");
      record.resize(static_cast<std::size_t>(header_len) + 4);
      in.read(reinterpret_cast<char*>(record.data()), static_cast<std::streamsize>(record.size()));
      std::uint64_t data_len = little_endian(std::span(record).subspan(header_len, 4));
      const std::string where = "record at byte " + std::to_string(at);
      const auto f = fields(std::span(record).first(header_len), file_, where);
      const std::uint8_t op = field(f, "op", 1, file_, where)[0];
      // An index record (version 1) holds count entries of 12 bytes; rosbag of
      // 2010 wrote another data length on it, and rosbag reads the count.
      if (op == kIndexData && little_endian(field(f, "ver", 4, file_, where)) == 1) {
        data_len = 12 * little_endian(field(f, "count", 4, file_, where));
      }
      if (data_len > size - at - 8 - header_len) return cut("the file ends inside a record");
      if (op == kBagHeader) {
        indexed = little_endian(field(f, "index_pos", 8, file_, where)) != 0;
      } else if (op == kChunk || op == kConnection || op == kMessageData) {
        std::vector<std::uint8_t> data(static_cast<std::size_t>(data_len));
        in.read(reinterpret_cast<char*>(data.data()), static_cast<std::streamsize>(data.size()));
        if (op == kChunk) {
          chunk(f, data, where, on_message);
        } else {
          inner(op, f, data, where, on_message);
        }
      }
      at += 8 + header_len + data_len;
    }
    if (!indexed) summary_.cut_short = "the bag has no index (its recorder did not close it); read to its end";
  }

  std::set<std::string> compressions;

 private:
  template <typename OnMessage>
  void chunk(const std::map<std::string, std::span<const std::uint8_t>>& f, std::span<const std::uint8_t> data,
             const std::string& where, OnMessage& on_message) {
    const std::string compression = text(field(f, "compression", 0, file_, where));
    const std::uint64_t size = little_endian(field(f, "size", 4, file_, where));
    compressions.insert(compression);
    std::vector<std::uint8_t> plain;
    if (compression == "none") {
      if (size != data.size()) throw BagFormatError(file_, where + ": an uncompressed chunk of another size than it says");
      plain.assign(data.begin(), data.end());
    } else {
      try {
        plain = decompress(compression, data, size);
      } catch (const std::runtime_error& e) {
        throw BagFormatError(file_, "chunk " + where + ": " + e.what() + " (none, bz2 and lz4 are read)");
      }
    }
    const std::span<const std::uint8_t> bytes(plain);
    for (std::size_t at = 0; at < bytes.size();) {
      const std::string inner_where = "chunk " + where + ", offset " + std::to_string(at);
      if (bytes.size() - at < 4) throw BagFormatError(file_, inner_where + ": a record runs past the chunk");
      const auto header_len = static_cast<std::size_t>(little_endian(bytes.subspan(at, 4)));
      if (header_len > bytes.size() - at - 4 || bytes.size() - at - 4 - header_len < 4) {
        throw BagFormatError(file_, inner_where + ": a record runs past the chunk");
      }
      const auto data_len = static_cast<std::size_t>(little_endian(bytes.subspan(at + 4 + header_len, 4)));
      if (data_len > bytes.size() - at - 8 - header_len) {
        throw BagFormatError(file_, inner_where + ": a record runs past the chunk");
      }
      const auto inner_fields = fields(bytes.subspan(at + 4, header_len), file_, inner_where);
      const std::uint8_t op = field(inner_fields, "op", 1, file_, inner_where)[0];
      inner(op, inner_fields, bytes.subspan(at + 8 + header_len, data_len), inner_where, on_message);
      at += 8 + header_len + data_len;
    }
  }

  template <typename OnMessage>
  void inner(std::uint8_t op, const std::map<std::string, std::span<const std::uint8_t>>& f,
             std::span<const std::uint8_t> data, const std::string& where, OnMessage& on_message) {
    if (op == kConnection) {
      const auto id = static_cast<std::uint32_t>(little_endian(field(f, "conn", 4, file_, where)));
      const auto connection_header = fields(data, file_, where + " (connection header)");
      Connection c;
      c.topic = text(field(f, "topic", 0, file_, where));
      c.type = text(field(connection_header, "type", 0, file_, where + " (connection header)"));
      connections_[id] = std::move(c);
    } else if (op == kMessageData) {
      const auto id = static_cast<std::uint32_t>(little_endian(field(f, "conn", 4, file_, where)));
      const auto time = field(f, "time", 8, file_, where);
      const auto connection = connections_.find(id);
      if (connection == connections_.end()) {
        throw BagFormatError(file_, where + ": a message on connection " + std::to_string(id) +
                                        ", which no connection record before it defines");
      }
      const auto sec = static_cast<std::int64_t>(little_endian(time.first(4)));
      const auto nsec = static_cast<std::int64_t>(little_endian(time.subspan(4, 4)));
      on_message(connection->second, sec * 1'000'000'000 + nsec, data);
    }
  }

  const std::filesystem::path& file_;
  BagSummary& summary_;
  std::map<std::uint32_t, Connection> connections_;
};

}  // namespace

BagSummary summarize(const std::filesystem::path& file) {
  SummaryCounter counter(BagFormat::ros1);
  RecordWalker walker(file, counter.summary());
  walker.walk([&](const Connection& c, std::int64_t t, std::span<const std::uint8_t>) { counter.count(c.topic, c.type, t); });
  return counter.finish(walker.compressions);
}

void for_each_message(const std::filesystem::path& file, const std::set<std::string>& topics,
                      const std::function<void(const BagMessage&)>& visit) {
  BagSummary summary;
  TimeOrderedMessages messages;
  RecordWalker walker(file, summary);
  walker.walk([&](const Connection& c, std::int64_t t, std::span<const std::uint8_t> data) {
    if (topics.empty() || topics.contains(c.topic)) messages.add(c.topic, c.type, t, MessageEncoding::ros1, data);
  });
  messages.visit_in_time_order(visit);
}

}  // namespace lmf::bag::ros1
