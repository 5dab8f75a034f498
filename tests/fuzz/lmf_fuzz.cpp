// lmf-fuzz: the standalone, deterministic fuzz driver (no libFuzzer needed,
// builds with g++). Runs one target of tests/fuzz over its seeds, then over
// --runs mutated inputs (mutator.hpp), and prints the outcomes, the input rate
// and the slowest input. Any crash, sanitizer report or failed property ends
// the process abnormally after naming the input and saving it to a file.
//
//   lmf-fuzz --list
//   lmf-fuzz decode_local_map --runs 50000 --seed 1
//   lmf-fuzz decode_local_map --seed 1 --only 4711       # rebuild and run one input
//   lmf-fuzz decode_local_map crash-decode_local_map-1-4711.bin   # run saved inputs
//   lmf-fuzz decode_local_map --write-seeds corpus/       # a libFuzzer seed corpus
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <boost/program_options.hpp>

#include "fuzz_registry.hpp"
#include "mutator.hpp"

namespace po = boost::program_options;

#if defined(__SANITIZE_ADDRESS__)
#define LMF_FUZZ_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define LMF_FUZZ_SANITIZED 1
#endif
#endif
#ifdef LMF_FUZZ_SANITIZED
extern "C" void __sanitizer_set_death_callback(void (*callback)());
#endif

// Sanitizer defaults for this binary (ASAN_OPTIONS / UBSAN_OPTIONS still
// override): any report aborts, so the crash handler saves the input.
extern "C" const char* __asan_default_options() { return "abort_on_error=1:detect_leaks=1"; }
extern "C" const char* __ubsan_default_options() { return "print_stacktrace=1:halt_on_error=1:abort_on_error=1"; }

namespace {

using lmf::fuzz::Bytes;

// What the crash handler needs, set before each input (async-signal-safe use only).
struct Current {
  const char* target = "";
  std::uint64_t seed = 0;
  std::uint64_t index = 0;
  bool is_seed = false;
  const Bytes* input = nullptr;
  char file[512] = {};
} g_current;

void write_all(int fd, const void* data, std::size_t size) {
  const auto* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd, p, size);
    if (n <= 0) return;
    p += n;
    size -= static_cast<std::size_t>(n);
  }
}

void write_text(const char* text) { write_all(2, text, std::strlen(text)); }

// Called from signal handlers and sanitizer death callbacks: no allocation.
void report_crash() {
  static volatile std::sig_atomic_t reported = 0;
  if (reported != 0 || g_current.input == nullptr) return;
  reported = 1;
  const int fd = ::open(g_current.file, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) {
    write_all(fd, g_current.input->data(), g_current.input->size());
    ::close(fd);
  }
  write_text("lmf-fuzz: CRASH in target ");
  write_text(g_current.target);
  write_text(g_current.is_seed ? " on a seed; " : " on a mutated input; ");
  write_text("input saved to ");
  write_text(g_current.file);
  write_text(" (run it with: lmf-fuzz <target> <file>)\n");
}

void on_signal(int signal_number) {
  if (signal_number == SIGALRM) write_text("lmf-fuzz: TIMEOUT: an input ran longer than --timeout-s\n");
  report_crash();
  std::signal(signal_number, SIG_DFL);
  std::raise(signal_number);
}

void install_crash_handlers() {
  for (const int s : {SIGSEGV, SIGABRT, SIGFPE, SIGILL, SIGBUS, SIGALRM}) std::signal(s, on_signal);
  std::set_terminate([] {
    write_text("lmf-fuzz: uncaught exception");
    if (const std::exception_ptr e = std::current_exception()) {
      try {
        std::rethrow_exception(e);
      } catch (const std::exception& x) {
        write_text(": ");
        write_text(x.what());
      } catch (...) {
      }
    }
    write_text("\n");
    std::abort();
  });
#ifdef LMF_FUZZ_SANITIZED
  __sanitizer_set_death_callback(report_crash);
#endif
}

void set_current(const Bytes& input, std::uint64_t index, bool is_seed) {
  g_current.input = &input;
  g_current.index = index;
  g_current.is_seed = is_seed;
  std::snprintf(g_current.file, sizeof g_current.file, "crash-%s-%s%llu-%llu.bin", g_current.target,
                is_seed ? "seed-" : "", static_cast<unsigned long long>(g_current.seed),
                static_cast<unsigned long long>(index));
}

struct Options {
  std::string target;
  std::uint64_t runs = 10000;
  std::uint64_t seed = 1;
  std::size_t max_length = 1 << 20;
  unsigned timeout_s = 20;
  std::optional<std::uint64_t> only;
  std::string write_seeds;
  bool expect_seeds_accepted = false;
  std::vector<std::string> files;
};

class Stats {
 public:
  void add(std::string_view outcome, double seconds, std::uint64_t index) {
    ++outcomes_[std::string(outcome.empty() ? "(none)" : outcome)];
    if (seconds > slowest_s_) {
      slowest_s_ = seconds;
      slowest_index_ = index;
    }
    ++inputs_;
  }
  void print(const Options& o, double seconds) const {
    std::cout << "lmf-fuzz " << o.target << ": " << inputs_ << " inputs in " << seconds << " s ("
              << static_cast<double>(inputs_) / std::max(seconds, 1e-9) << " inputs/s), seed " << o.seed
              << ", 0 crashes\n  slowest: input " << slowest_index_ << " took " << slowest_s_ * 1e3 << " ms\n  outcomes:";
    for (const auto& [name, count] : outcomes_) std::cout << ' ' << name << '=' << count;
    std::cout << '\n';
  }
  std::int64_t count(const std::string& outcome) const {
    const auto it = outcomes_.find(outcome);
    return it == outcomes_.end() ? 0 : it->second;
  }

 private:
  std::map<std::string, std::int64_t> outcomes_;
  std::uint64_t inputs_ = 0;
  double slowest_s_ = 0.0;
  std::uint64_t slowest_index_ = 0;
};

unsigned g_timeout_s = 0;

double run_one(const lmf::fuzz::Target& target, const Bytes& input, std::string_view* outcome) {
  const auto start = std::chrono::steady_clock::now();
  if (g_timeout_s > 0) ::alarm(g_timeout_s);
  try {
    target.one_input(input.data(), input.size());
  } catch (...) {
    std::terminate();  // an exception out of a target is a crash (the terminate handler names it)
  }
  if (g_timeout_s > 0) ::alarm(0);
  *outcome = lmf::fuzz::take_outcome();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::optional<Options> parse(int argc, char** argv) {
  Options o;
  po::options_description visible("lmf-fuzz: deterministic mutation fuzzing of one target (tests/fuzz)\n"
                                  "usage: lmf-fuzz <target> [options] [input files...]\nOptions");
  visible.add_options()
      ("help,h", "print this help")
      ("list", "list the targets")
      ("runs", po::value(&o.runs)->default_value(o.runs), "mutated inputs after the seeds")
      ("seed", po::value(&o.seed)->default_value(o.seed), "run seed: the same seed gives the same inputs")
      ("max-len", po::value(&o.max_length)->default_value(o.max_length), "longest input in bytes")
      ("timeout-s", po::value(&o.timeout_s)->default_value(o.timeout_s),
       "an input running longer is a failure (a hang), saved like a crash; 0: no limit")
      ("only", po::value<std::uint64_t>(), "run only mutated input number N of this seed")
      ("write-seeds", po::value(&o.write_seeds), "write the seeds into this directory and exit")
      ("expect-seeds-accepted", po::bool_switch(&o.expect_seeds_accepted),
       "fail unless every seed's outcome is 'accepted' (seeds must reach deep)");
  po::options_description hidden;
  hidden.add_options()("target", po::value(&o.target))("files", po::value(&o.files));
  po::options_description all;
  all.add(visible).add(hidden);
  po::positional_options_description positional;
  positional.add("target", 1).add("files", -1);
  po::variables_map vm;
  po::store(po::command_line_parser(argc, argv).options(all).positional(positional).run(), vm);
  po::notify(vm);
  if (vm.count("help")) {
    std::cout << visible << "\nTargets:";
    for (const auto& t : lmf::fuzz::targets()) std::cout << ' ' << t.name;
    std::cout << '\n';
    return std::nullopt;
  }
  if (vm.count("list")) {
    for (const auto& t : lmf::fuzz::targets()) std::cout << t.name << '\n';
    return std::nullopt;
  }
  if (vm.count("only")) o.only = vm["only"].as<std::uint64_t>();
  if (o.target.empty()) throw std::invalid_argument("no target given (see --list)");
  if (o.max_length < 1) throw std::invalid_argument("--max-len must be >= 1");
  return o;
}

int run(const Options& o) {
  const auto& all = lmf::fuzz::targets();
  const auto it = std::find_if(all.begin(), all.end(), [&](const auto& t) { return o.target == t.name; });
  if (it == all.end()) throw std::invalid_argument("unknown target '" + o.target + "' (see --list)");
  const lmf::fuzz::Target& target = *it;
  g_current.target = target.name;
  g_current.seed = o.seed;
  g_timeout_s = o.timeout_s;
  install_crash_handlers();

  const std::vector<Bytes> seeds = target.seeds();
  if (seeds.empty()) throw std::runtime_error(o.target + ": no seeds");
  if (!o.write_seeds.empty()) {
    std::filesystem::create_directories(o.write_seeds);
    for (std::size_t i = 0; i < seeds.size(); ++i) {
      const auto file = std::filesystem::path(o.write_seeds) / ("seed-" + std::to_string(i));
      std::ofstream out(file, std::ios::binary);
      out.write(reinterpret_cast<const char*>(seeds[i].data()), static_cast<std::streamsize>(seeds[i].size()));
      if (!out) throw std::runtime_error("cannot write " + file.string());
    }
    std::cout << "lmf-fuzz " << o.target << ": " << seeds.size() << " seeds written to " << o.write_seeds << '\n';
    return 0;
  }

  Stats stats;
  std::string_view outcome;
  const auto start = std::chrono::steady_clock::now();
  if (!o.files.empty()) {
    for (std::size_t i = 0; i < o.files.size(); ++i) {
      std::ifstream in(o.files[i], std::ios::binary);
      if (!in) throw std::runtime_error("cannot read " + o.files[i]);
      const Bytes input((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      set_current(input, i, false);
      const double seconds = run_one(target, input, &outcome);
      stats.add(outcome, seconds, i);
      std::cout << o.files[i] << ": " << (outcome.empty() ? "(none)" : outcome) << '\n';
    }
  } else if (o.only) {
    lmf::fuzz::Mutator mutator(seeds, o.max_length);
    const Bytes input = mutator.input(o.seed, *o.only);
    set_current(input, *o.only, false);
    const double seconds = run_one(target, input, &outcome);
    stats.add(outcome, seconds, *o.only);
    std::cout << "input " << *o.only << " (" << input.size() << " bytes): " << (outcome.empty() ? "(none)" : outcome)
              << '\n';
  } else {
    for (std::size_t i = 0; i < seeds.size(); ++i) {
      set_current(seeds[i], i, true);
      const double seconds = run_one(target, seeds[i], &outcome);
      if (o.expect_seeds_accepted && outcome != "accepted") {
        std::cerr << "lmf-fuzz " << o.target << ": seed " << i << " was not accepted ("
                  << (outcome.empty() ? "(none)" : outcome) << ")\n";
        return 1;
      }
      stats.add(outcome, seconds, i);
    }
    lmf::fuzz::Mutator mutator(seeds, o.max_length);
    Bytes input;
    for (std::uint64_t i = 0; i < o.runs; ++i) {
      input = mutator.input(o.seed, i);
      set_current(input, i, false);
      const double seconds = run_one(target, input, &outcome);
      stats.add(outcome, seconds, i);
    }
  }
  g_current.input = nullptr;
  stats.print(o, std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::optional<Options> options = parse(argc, argv);
    if (!options) return 0;
    return run(*options);
  } catch (const std::exception& e) {
    std::cerr << "lmf-fuzz: " << e.what() << '\n';
    return 2;
  }
}
