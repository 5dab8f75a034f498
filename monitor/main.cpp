// lmf-monitor: the system at a glance (docs/design.md §1), live from LCM or from an
// lcm-logger file; a refreshing table or JSON lines; optional SVG map and the
// paper's Fig. 8 timing plot.
#include <unistd.h>

#include <iostream>
#include <string>

#include <boost/program_options.hpp>

#include "monitor/monitor_node.hpp"
#include "runtime/bus.hpp"
#include "runtime/event_loop.hpp"
#include "runtime/options.hpp"

namespace po = boost::program_options;

int main(int argc, char** argv) {
  constexpr const char* kProgram = "lmf-monitor";
  lmf::runtime::CommonOptions common;
  lmf::monitor::MonitorOptions options;
  std::string log_file;
  std::string map_svg;
  std::string timing_svg;
  int refresh_ms = static_cast<int>(options.refresh.count());

  po::options_description description("Options");
  description.add_options()
      ("json", po::bool_switch(&options.json), "print one JSON object per refresh (JSON lines) instead of the table")
      ("log", po::value<std::string>(&log_file),
       "read this lcm-logger file instead of the network, process every event, print, exit (with --keys: "
       "only correctly signed, fresh, allowed messages; the others are counted and reported)")
      ("svg", po::value<std::string>(&map_svg), "write the global map (from global_map_t) to this SVG file")
      ("timing-svg", po::value<std::string>(&timing_svg),
       "write the per-robot update times over the mission with the 200 ms bound (paper Fig. 8) to this SVG file")
      ("refresh-ms", po::value<int>(&refresh_ms)->default_value(refresh_ms),
       "refresh period, ms (of log time with --log)");
  lmf::runtime::add_common_options(description, common);
  lmf::runtime::parse_options_or_exit(
      argc, argv, description, kProgram,
      "Shows the robots and the fusion server: a table redrawn in place on a terminal, or JSON lines;\n"
      "live from LCM or from an lcm-logger file (--log).");

  try {
    options.refresh = std::chrono::milliseconds(refresh_ms);
    if (!map_svg.empty()) options.map_svg = map_svg;
    if (!timing_svg.empty()) options.timing_svg = timing_svg;
    options.redraw_in_place = !options.json && log_file.empty() && isatty(STDOUT_FILENO) != 0;
    options.validate();
    const lmf::runtime::Channels channels(common.channel_prefix);

    if (!log_file.empty()) {
      // With --keys the capture's signatures are checked as the live monitor would.
      const auto keys = lmf::runtime::auth_config_or_exit(common, "monitor", kProgram);
      lmf::monitor::MonitorNode node(channels, options, std::cout);
      const std::int64_t events = node.replay_log(log_file, keys);
      std::cerr << kProgram << ": " << events << " events read from " << log_file;
      if (keys) {
        std::cerr << "; signatures checked, " << node.log_rejections().total() << " rejected";
        for (const auto& [reason, count] : node.log_rejections().nonzero()) std::cerr << ' ' << reason << '=' << count;
      }
      std::cerr << '\n';
      return 0;
    }

    lmf::runtime::Bus bus(common.lcm_url, lmf::runtime::auth_config_or_exit(common, "monitor", kProgram));
    if (!bus.good()) lmf::runtime::exit_with_error(kProgram, "cannot open LCM at '" + bus.url() + "'");
    lmf::runtime::EventLoop loop(bus);
    lmf::monitor::MonitorNode node(bus, loop, channels, options, std::cout);
    loop.run();
    return 0;
  } catch (const std::exception& e) {
    lmf::runtime::exit_with_error(kProgram, e.what());
  }
}
