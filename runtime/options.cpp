#include "runtime/options.hpp"

#include <cstdlib>
#include <iostream>
#include <sstream>
#include <stdexcept>

#include <boost/program_options/parsers.hpp>
#include <boost/program_options/value_semantic.hpp>

namespace lmf::runtime {

namespace po = boost::program_options;

void add_common_options(po::options_description& description, CommonOptions& options) {
  const char* env_url = std::getenv("LCM_DEFAULT_URL");
  options.lcm_url = env_url != nullptr ? env_url : "";
  description.add_options()
      ("help,h", "print this help and exit")
      ("lcm-url", po::value<std::string>(&options.lcm_url)->default_value(options.lcm_url),
       "LCM provider URL (default: $LCM_DEFAULT_URL; when empty, LCM's udpm://239.255.76.67:7667?ttl=0); "
       "memq:// keeps every message inside the process")
      ("channel-prefix", po::value<std::string>(&options.channel_prefix)->default_value(options.channel_prefix),
       "prefix of every LCM channel name: upper-case letters, digits and '_'")
      ("keys", po::value<std::string>(&options.keys_file),
       "keys file (lines 'principal hex-key', mode 600): sign every message published and accept only messages "
       "signed by its principals, fresh and allowed for the sender; without it nothing is signed or checked")
      ("identity", po::value<std::string>(&options.identity),
       "principal to sign as with --keys (default: server, player, monitor or robot<id>, by process)")
      ("simulate-loss", po::value(&options.loss.drop)->default_value(options.loss.drop),
       "testing: lose this fraction [0, 1) of the messages this process publishes, as a lossy network would")
      ("simulate-duplicates", po::value(&options.loss.duplicate)->default_value(options.loss.duplicate),
       "testing: send this fraction [0, 1) of the messages not lost twice")
      ("simulate-seed", po::value(&options.loss.seed)->default_value(options.loss.seed),
       "testing: seed of --simulate-loss and --simulate-duplicates");
}

void simulate_loss_or_exit(Bus& bus, const CommonOptions& options, std::string_view program) {
  if (options.loss.drop == 0.0 && options.loss.duplicate == 0.0) return;
  try {
    bus.simulate_loss(options.loss);
  } catch (const std::exception& e) {
    exit_with_error(program, e.what(), 2);
  }
  std::cerr << program << ": simulating a lossy network: " << options.loss.drop * 100.0 << " % of what it publishes lost, "
            << options.loss.duplicate * 100.0 << " % duplicated (seed " << options.loss.seed << ")\n";
}

std::optional<auth::Config> auth_config(const CommonOptions& options, std::string_view default_identity) {
  if (options.keys_file.empty()) {
    if (!options.identity.empty()) throw std::invalid_argument("--identity needs --keys");
    return std::nullopt;
  }
  auth::Config config;
  config.identity = options.identity.empty() ? std::string(default_identity) : options.identity;
  config.keys = std::make_shared<const auth::KeyRing>(auth::load_keys_file(options.keys_file));
  config.validate(options.keys_file);
  return config;
}

std::optional<auth::Config> auth_config_or_exit(const CommonOptions& options, std::string_view default_identity,
                                                std::string_view program) {
  try {
    return auth_config(options, default_identity);
  } catch (const std::exception& e) {
    exit_with_error(program, e.what(), 2);
  }
}

ParseResult parse_options(int argc, const char* const argv[], const po::options_description& description,
                          std::string_view program, std::string_view summary, po::variables_map* variables) {
  po::variables_map local;
  po::variables_map& vm = variables != nullptr ? *variables : local;
  std::ostringstream usage;
  usage << "Usage: " << program << " [options]\n" << summary << "\n\n" << description;
  try {
    const po::parsed_options parsed = po::command_line_parser(argc, argv).options(description).run();
    // Without a positional description Boost keeps stray words silently: refuse them.
    const auto stray = po::collect_unrecognized(parsed.options, po::include_positional);
    if (!stray.empty()) return {ParseResult::Status::kError, "unexpected argument '" + stray.front() + "'"};
    po::store(parsed, vm);
    if (vm.count("help") != 0) return {ParseResult::Status::kHelp, usage.str()};
    po::notify(vm);
    if (vm.count("channel-prefix") != 0) Channels{vm["channel-prefix"].as<std::string>()};  // validates
  } catch (const std::exception& e) {
    return {ParseResult::Status::kError, e.what()};
  }
  return {ParseResult::Status::kOk, {}};
}

void parse_options_or_exit(int argc, const char* const argv[], const po::options_description& description,
                           std::string_view program, std::string_view summary, po::variables_map* variables) {
  const ParseResult result = parse_options(argc, argv, description, program, summary, variables);
  switch (result.status) {
    case ParseResult::Status::kOk: return;
    case ParseResult::Status::kHelp:
      std::cout << result.message;
      std::exit(0);
    case ParseResult::Status::kError:
      std::cerr << program << ": error: " << result.message << "\nTry '" << program << " --help'.\n";
      std::exit(2);
  }
}

void exit_with_error(std::string_view program, std::string_view message, int exit_code) {
  std::cerr << program << ": error: " << message << "\n";
  std::exit(exit_code);
}

}  // namespace lmf::runtime
