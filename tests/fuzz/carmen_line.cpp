// Fuzz target: the CARMEN line parser (io::parse_carmen_line), one line per
// '\n'-separated piece of the input, all into one log as the reader does.
// A malformed line must throw CarmenParseError naming the file and the line;
// anything else thrown is a crash.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "carmen_target.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const std::filesystem::path file = "fuzz.log";
  lmf::io::CarmenLog log;
  std::size_t line_number = 0;
  std::size_t start = 0;
  std::string_view outcome = "accepted";
  while (start <= text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string line(text.substr(start, end - start));
    while (!line.empty() && line.back() == '\r') line.pop_back();  // as io::for_each_line does
    ++line_number;
    try {
      lmf::io::parse_carmen_line(line, file, line_number, {}, log);
    } catch (const lmf::io::CarmenParseError& e) {
      lmf::fuzz::check_parse_error(e, file, line_number);
      outcome = "parse_error";
    }
    start = end + 1;
  }
  lmf::fuzz::check_log(log, "carmen line");
  lmf::fuzz::note_outcome(outcome);
  return 0;
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  std::vector<lmf::fuzz::Bytes> seeds;
  for (const std::string& line : lmf::fuzz::corpus().carmen_lines) seeds.emplace_back(line.begin(), line.end());
  return seeds;
}
