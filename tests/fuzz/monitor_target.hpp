// The body shared by the targets of the messages only monitors read
// (agent_status_t, server_status_t, global_map_t): runtime::decode_message,
// the round trip of an accepted message (it re-encodes to bytes that decode
// and re-encode identically), runtime::from_message as lmf-monitor decodes it,
// then what lmf-monitor does with it: MonitorState, its JSON line (which must
// dump and parse back), its text table and its two SVG drawings.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "decode_target.hpp"
#include "fuzz_support.hpp"
#include "monitor/monitor_state.hpp"
#include "runtime/convert.hpp"

namespace lmf::fuzz {

template <class Msg, class Feed>
int fuzz_monitor_message(const std::uint8_t* data, std::size_t size, Feed feed) {
  const std::string name = Msg::getTypeName();
  const runtime::Checked<Msg> decoded = runtime::decode_message<Msg>(data, size);
  if (!decoded) {
    check_rejection(decoded.rejection(), name);
    note_outcome(runtime::reason_name(decoded.rejection().reason));
    return 0;
  }
  const Bytes bytes = runtime::encode_message(decoded.value());
  const runtime::Checked<Msg> again = runtime::decode_message<Msg>(bytes.data(), bytes.size());
  if (!again) fail(name + ": a re-encoded accepted message is rejected: " + again.rejection().describe());
  if (runtime::encode_message(again.value()) != bytes) fail(name + ": the round trip changed the message");

  const auto value = runtime::from_message(decoded.value());
  if (!value) {
    check_rejection(value.rejection(), name);
    note_outcome(runtime::reason_name(value.rejection().reason));
    return 0;
  }
  const auto seed = [](const auto& msg) { return runtime::from_message(msg).value(); };  // the corpus is valid

  // The monitor has already seen the seed messages, so the input meets rows,
  // windows and a map (differences of times, sums of counts).
  const std::int64_t now_utime = 1'700'000'000'000'000;
  monitor::MonitorState state;
  for (const auto& m : corpus().agent_statuses) state.on_agent_status(seed(m), now_utime - 1'000'000);
  for (const auto& m : corpus().server_statuses) state.on_server_status(seed(m), now_utime - 900'000);
  for (const auto& m : corpus().global_maps) state.on_global_map(seed(m), now_utime - 800'000);
  feed(state, value.value(), now_utime);
  const std::string line = state.to_json(now_utime).dump();  // throws on invalid UTF-8
  const nlohmann::json parsed = nlohmann::json::parse(line, nullptr, false);
  if (parsed.is_discarded()) fail(name + ": the monitor's JSON line does not parse: " + line.substr(0, 200));
  if (state.table(now_utime).empty()) fail(name + ": empty monitor table");
  state.write_map_svg(scratch_file(nullptr, 0));
  state.write_timing_svg(scratch_file(nullptr, 0));
  note_outcome("accepted");
  return 0;
}

}  // namespace lmf::fuzz
