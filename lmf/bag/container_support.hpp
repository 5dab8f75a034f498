// What the container readers (ros1_bag.cpp, mcap_bag.cpp, sqlite_bag.cpp)
// share: the summary's per-topic counts, and messages handed on in log-time
// order.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "lmf/bag/bag_file.hpp"

namespace lmf::bag {

// Counts messages per topic and their time spans into a BagSummary.
class SummaryCounter {
 public:
  explicit SummaryCounter(BagFormat format) { summary_.format = format; }
  BagSummary& summary() { return summary_; }

  void count(const std::string& topic, const std::string& type, std::int64_t log_time_ns) {
    BagTopic& t = topics_[topic];
    if (t.count == 0) {
      t.name = topic;
      t.type = type;
      t.first_ns = t.last_ns = log_time_ns;
    }
    t.first_ns = std::min(t.first_ns, log_time_ns);
    t.last_ns = std::max(t.last_ns, log_time_ns);
    ++t.count;
    summary_.start_ns = summary_.messages == 0 ? log_time_ns : std::min(summary_.start_ns, log_time_ns);
    summary_.end_ns = summary_.messages == 0 ? log_time_ns : std::max(summary_.end_ns, log_time_ns);
    ++summary_.messages;
  }

  // The summary, with the chunks' compressions ("none" for none).
  BagSummary finish(const std::set<std::string>& compressions) {
    for (auto& [name, topic] : topics_) summary_.topics.push_back(std::move(topic));
    summary_.compression.clear();
    for (const auto& c : compressions) summary_.compression += (summary_.compression.empty() ? "" : ",") + c;
    if (summary_.compression.empty()) summary_.compression = "none";
    return std::move(summary_);
  }

 private:
  BagSummary summary_;
  std::map<std::string, BagTopic> topics_;
};

// Messages gathered from a container whose chunks may overlap in time, handed
// on in log-time order (stable: equal times keep the file's order).
class TimeOrderedMessages {
 public:
  void add(const std::string& topic, const std::string& type, std::int64_t log_time_ns, MessageEncoding encoding,
           std::span<const std::uint8_t> data) {
    const auto& names = *names_.try_emplace(topic, type).first;
    messages_.push_back({log_time_ns, &names.first, &names.second, encoding, {data.begin(), data.end()}});
  }

  void visit_in_time_order(const std::function<void(const BagMessage&)>& visit) {
    std::stable_sort(messages_.begin(), messages_.end(),
                     [](const Message& a, const Message& b) { return a.log_time_ns < b.log_time_ns; });
    for (const Message& m : messages_) visit(BagMessage{*m.topic, *m.type, m.log_time_ns, m.encoding, m.data});
  }

 private:
  struct Message {
    std::int64_t log_time_ns;
    const std::string* topic;
    const std::string* type;
    MessageEncoding encoding;
    std::vector<std::uint8_t> data;
  };
  std::map<std::string, std::string> names_;  // topic -> type; stable addresses
  std::vector<Message> messages_;
};

}  // namespace lmf::bag
