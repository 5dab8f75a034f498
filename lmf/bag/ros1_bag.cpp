#include "lmf/bag/ros1_bag.hpp"

#include <fstream>
#include <map>
#include <set>

#include <ros/serialization.h>
#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>

namespace lmf::bag::ros1 {
namespace {

std::int64_t nanoseconds(const ros::Time& t) { return static_cast<std::int64_t>(t.toNSec()); }

// Runs `body` with the bag open; any error of the library becomes a BagFormatError naming the file.
template <typename Body>
void with_bag(const std::filesystem::path& file, Body&& body) {
  try {
    rosbag::Bag bag;
    bag.open(file.string(), rosbag::bagmode::Read);
    body(bag);
  } catch (const rosbag::BagException& e) {
    throw BagFormatError(file, std::string("ROS 1 bag: ") + e.what());
  } catch (const ros::Exception& e) {
    throw BagFormatError(file, std::string("ROS 1 bag: ") + e.what());
  } catch (const std::bad_alloc&) {
    throw BagFormatError(file, "ROS 1 bag: a record asks for more memory than there is (a corrupt size field)");
  }
}

std::uint32_t read_u32(std::istream& in) {
  unsigned char b[4];
  if (!in.read(reinterpret_cast<char*>(b), 4)) return 0;
  return b[0] | (b[1] << 8) | (b[2] << 16) | (static_cast<std::uint32_t>(b[3]) << 24);
}

// The compressions its chunk records name, from walking the records (bag
// format 2.0: each record is a header of `len name=value` fields and data, both
// length-prefixed); the library does not tell. Stops quietly at anything
// malformed: the library reports damage.
std::string chunk_compressions(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  in.seekg(13);  // "#ROSBAG V2.0\n"
  std::set<std::string> found;
  const auto size = static_cast<std::uint64_t>(std::filesystem::file_size(file));
  while (in) {
    const std::uint32_t header_len = read_u32(in);
    if (!in || static_cast<std::uint64_t>(in.tellg()) + header_len > size) break;
    std::string header(header_len, '\0');
    in.read(header.data(), header_len);
    std::map<std::string, std::string> fields;
    for (std::size_t at = 0; at + 4 <= header.size();) {
      const auto* b = reinterpret_cast<const unsigned char*>(header.data() + at);
      const std::uint32_t n = b[0] | (b[1] << 8) | (b[2] << 16) | (static_cast<std::uint32_t>(b[3]) << 24);
      if (n > header.size() - at - 4) break;
      const std::string field = header.substr(at + 4, n);
      const auto eq = field.find('=');
      if (eq != std::string::npos) fields[field.substr(0, eq)] = field.substr(eq + 1);
      at += 4 + n;
    }
    if (fields["op"] == std::string(1, '\x05')) found.insert(fields["compression"]);
    const std::uint32_t data_len = read_u32(in);
    in.seekg(data_len, std::ios::cur);
  }
  std::string list;
  for (const auto& c : found) list += (list.empty() ? "" : ",") + c;
  return list.empty() ? "none" : list;
}

}  // namespace

BagSummary summarize(const std::filesystem::path& file) {
  BagSummary summary;
  summary.format = BagFormat::ros1;
  with_bag(file, [&](rosbag::Bag& bag) {
    std::map<std::string, BagTopic> topics;
    rosbag::View view(bag);
    for (const rosbag::MessageInstance& m : view) {
      BagTopic& t = topics[m.getTopic()];
      const std::int64_t ns = nanoseconds(m.getTime());
      if (t.count == 0) {
        t.name = m.getTopic();
        t.type = m.getDataType();
        t.first_ns = ns;
      }
      t.last_ns = ns;
      ++t.count;
      if (summary.messages == 0) summary.start_ns = ns;
      summary.end_ns = ns;
      ++summary.messages;
    }
    for (auto& [name, topic] : topics) summary.topics.push_back(std::move(topic));
    summary.compression = chunk_compressions(file);
  });
  return summary;
}

void for_each_message(const std::filesystem::path& file, const std::set<std::string>& topics,
                      const std::function<void(const BagMessage&)>& visit) {
  with_bag(file, [&](rosbag::Bag& bag) {
    rosbag::View view(bag);
    std::vector<std::uint8_t> data;
    for (const rosbag::MessageInstance& m : view) {
      if (!topics.empty() && !topics.contains(m.getTopic())) continue;
      data.resize(m.size());
      ros::serialization::OStream stream(data.data(), static_cast<std::uint32_t>(data.size()));
      m.write(stream);
      visit(BagMessage{m.getTopic(), m.getDataType(), nanoseconds(m.getTime()), MessageEncoding::ros1, data});
    }
  });
}

}  // namespace lmf::bag::ros1
