#include "runtime/channels.hpp"

#include <charconv>
#include <limits>
#include <stdexcept>

namespace lmf::runtime {

Channels::Channels(std::string prefix) : prefix_(std::move(prefix)) {
  for (const char c : prefix_) {
    const bool allowed = (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
    if (!allowed) {
      throw std::invalid_argument("channel prefix \"" + prefix_ +
                                  "\": only upper-case letters, digits and '_' are allowed");
    }
  }
}

std::string Channels::scan(int robot_id) const {
  if (robot_id < 0) throw std::invalid_argument("Channels::scan: negative robot id " + std::to_string(robot_id));
  return with_prefix(channel_suffix::kScan) + std::to_string(robot_id);
}

std::string Channels::scan_any() const { return with_prefix(channel_suffix::kScan) + "[0-9]+"; }

std::optional<int> Channels::scan_robot(std::string_view channel) const {
  const std::string head = with_prefix(channel_suffix::kScan);
  if (channel.size() <= head.size() || channel.substr(0, head.size()) != head) return std::nullopt;
  const std::string_view digits = channel.substr(head.size());
  for (const char c : digits) {
    if (c < '0' || c > '9') return std::nullopt;
  }
  int id = 0;
  const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), id);
  if (error != std::errc() || end != digits.data() + digits.size()) return std::nullopt;
  return id;
}

}  // namespace lmf::runtime
