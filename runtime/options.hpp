// Command-line flags every lmf process shares, and strict parsing (STYLE:
// bad options print a clear error and exit non-zero).
//
//   --lcm-url URL          LCM provider; default $LCM_DEFAULT_URL, else LCM's
//                          built-in udpm://239.255.76.67:7667?ttl=0
//   --channel-prefix P     prefix of every channel name (default LMF_)
//   --keys FILE            sign and verify every message (runtime/auth.hpp);
//                          without it nothing is signed or checked
//   --identity PRINCIPAL   the principal to sign as (default: the process's own,
//                          e.g. robot<id> for lmf-agent, server for lmf-server)
//   --help                 print the usage and exit 0
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include <boost/program_options/options_description.hpp>
#include <boost/program_options/variables_map.hpp>

#include "runtime/auth.hpp"
#include "runtime/bus.hpp"
#include "runtime/channels.hpp"

namespace lmf::runtime {

struct CommonOptions {
  std::string lcm_url;  // empty: let LCM pick (LCM_DEFAULT_URL, then its default)
  std::string channel_prefix = std::string(kDefaultChannelPrefix);
  std::string keys_file;  // empty: no authentication
  std::string identity;   // empty: the process's default principal
  SimulatedLoss loss;     // testing: --simulate-loss, --simulate-duplicates, --simulate-seed
};

// Adds --lcm-url, --channel-prefix, --keys, --identity, the --simulate-* test
// flags and --help, writing into `options`.
void add_common_options(boost::program_options::options_description& description, CommonOptions& options);

struct ParseResult {
  enum class Status { kOk, kHelp, kError } status = Status::kOk;
  std::string message;  // the usage text (kHelp) or the error (kError)
};

// Parses argv strictly (unknown options and positional arguments are errors)
// into `description` (which must contain the common options) and runs its
// notifiers. Also rejects a malformed --channel-prefix. Never exits.
ParseResult parse_options(int argc, const char* const argv[], const boost::program_options::options_description& description,
                          std::string_view program, std::string_view summary,
                          boost::program_options::variables_map* variables = nullptr);

// parse_options() for main(): prints the usage and exits 0 on --help; prints
// "<program>: error: ..." and a hint to stderr and exits 2 on an error.
void parse_options_or_exit(int argc, const char* const argv[],
                           const boost::program_options::options_description& description, std::string_view program,
                           std::string_view summary, boost::program_options::variables_map* variables = nullptr);

// The Bus authentication of --keys/--identity: nullopt without --keys; else
// the keys file loaded (permissions checked) and the identity (given, or
// `default_identity`) validated against it. Throws std::invalid_argument
// naming the file and line, or for --identity without --keys.
std::optional<auth::Config> auth_config(const CommonOptions& options, std::string_view default_identity);
// auth_config() for main(): prints "<program>: error: ..." and exits 2 on an error.
std::optional<auth::Config> auth_config_or_exit(const CommonOptions& options, std::string_view default_identity,
                                                std::string_view program);

// Applies the --simulate-* flags to the process's bus (a no-op without them);
// prints "<program>: error: ..." and exits 2 for a bad probability.
void simulate_loss_or_exit(Bus& bus, const CommonOptions& options, std::string_view program);

// Prints "<program>: error: <message>" to stderr and exits with `exit_code`
// (e.g. after a config file or the bus fails to load).
[[noreturn]] void exit_with_error(std::string_view program, std::string_view message, int exit_code = 1);

}  // namespace lmf::runtime
