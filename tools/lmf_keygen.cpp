// lmf-keygen: the keys files of one system for authenticated messages
// (runtime/auth.hpp): a fresh random key per principal, and per process a file
// DIR/<principal>.keys (mode 600) holding its own key and only the keys of the
// senders it reads, so that no robot can sign as another robot.
#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "runtime/auth.hpp"

namespace po = boost::program_options;
namespace auth = lmf::runtime::auth;

int main(int argc, char** argv) {
  constexpr const char* kProgram = "lmf-keygen";
  int robots = 0;
  std::vector<int> robot_ids;
  std::string out_dir;
  po::options_description options(
      "lmf-keygen: writes the keys files of one lmf system, one per process, for --keys.\n"
      "Usage: lmf-keygen --robots N --out DIR [--force]\n"
      "Writes DIR/server.keys, DIR/player.keys, DIR/monitor.keys and DIR/robot<N>.keys (mode 600). Each holds\n"
      "the process's own key and those of the principals whose messages it reads:\n"
      "  server: player and every robot; player: server and every robot; monitor: everyone; robot<N>: server and player.\n"
      "Copy each file to its machine only; run a process with --keys DIR/<its principal>.keys.\n\nOptions");
  options.add_options()
      ("help,h", "print this help and exit")
      ("robots", po::value(&robots), "robots 0 .. N-1")
      ("robot-id", po::value(&robot_ids), "a robot id (repeatable), instead of --robots")
      ("out", po::value(&out_dir)->required(), "folder for the files (created with mode 700 if missing)")
      ("force", "overwrite existing keys files (the old keys stop working)");
  po::variables_map vm;
  try {
    const po::parsed_options parsed = po::command_line_parser(argc, argv).options(options).run();
    po::store(parsed, vm);
    if (vm.count("help") != 0u) {
      std::cout << options << "\n";
      return 0;
    }
    po::notify(vm);
    if (!po::collect_unrecognized(parsed.options, po::include_positional).empty()) {
      throw std::invalid_argument("unexpected argument");
    }
    if ((robots > 0) == !robot_ids.empty()) throw std::invalid_argument("give --robots N (N >= 1) or --robot-id");
    for (int id = 0; id < robots; ++id) robot_ids.push_back(id);
  } catch (const std::exception& e) {
    std::cerr << kProgram << ": error: " << e.what() << "\nTry '" << kProgram << " --help'.\n";
    return 2;
  }

  try {
    const std::filesystem::path dir(out_dir);
    if (!std::filesystem::exists(dir)) {
      std::filesystem::create_directories(dir);
      if (::chmod(dir.c_str(), 0700) != 0) throw std::runtime_error(dir.string() + ": " + std::strerror(errno));
    }
    const bool overwrite = vm.count("force") != 0u;
    const auto files = auth::make_system_keys(robot_ids);
    // Refuse before writing anything, so a refusal leaves a consistent set.
    for (const auto& [principal, keys] : files) {
      const auto path = dir / (principal + ".keys");
      if (!overwrite && std::filesystem::exists(path)) {
        throw std::invalid_argument(path.string() + " exists (give --force to replace every keys file)");
      }
    }
    for (const auto& [principal, keys] : files) {
      const auto path = dir / (principal + ".keys");
      auth::write_keys_file(path, keys,
                            "lmf keys of '" + principal + "' (written by lmf-keygen): its own key and those of the "
                            "senders it accepts.\nSecret: keep mode 600; copy only to the machine that runs '" +
                                principal + "'.",
                            overwrite);
      std::cout << path.string() << ": ";
      const auto names = keys.principals();
      for (std::size_t i = 0; i < names.size(); ++i) std::cout << (i == 0 ? "" : " ") << names[i];
      std::cout << "\n";
    }
  } catch (const std::exception& e) {
    std::cerr << kProgram << ": error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
