// Fuzz target: the CARMEN log reader (io::read_carmen_log) on a whole file,
// plain or gzip (zlib reads both), held in memory. Errors must be a
// CarmenParseError naming the file and a line, or a std::runtime_error for
// data zlib cannot decompress; a plain log must read exactly as its lines
// parsed one by one (line numbers included).
#include <zlib.h>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "carmen_target.hpp"

namespace {

// What parsing the '\n'-separated lines one by one gives: the log, or the line
// number of the first error.
struct LineByLine {
  lmf::io::CarmenLog log;
  std::optional<std::size_t> error_line;
};

LineByLine parse_lines(std::string_view text, const std::filesystem::path& file) {
  LineByLine out;
  std::size_t line_number = 0;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string line(text.substr(start, end - start));
    while (!line.empty() && (line.back() == '\r' || line.back() == '\n')) line.pop_back();
    ++line_number;
    const bool terminated = end < text.size();
    try {
      lmf::io::parse_carmen_line(line, file, line_number, {}, out.log);
    } catch (const lmf::io::CarmenParseError&) {
      // A last line without its newline that does not parse was cut: read up to it.
      if (terminated) out.error_line = line_number;
      return out;
    }
    start = end + 1;
  }
  return out;
}

lmf::fuzz::Bytes gzip(const std::string& text) {
  z_stream z{};
  if (deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) lmf::fuzz::fail("deflateInit2");
  lmf::fuzz::Bytes out(deflateBound(&z, static_cast<uLong>(text.size())) + 32);
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
  z.avail_in = static_cast<uInt>(text.size());
  z.next_out = out.data();
  z.avail_out = static_cast<uInt>(out.size());
  if (deflate(&z, Z_FINISH) != Z_STREAM_END) lmf::fuzz::fail("deflate");
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path file = lmf::fuzz::scratch_file(data, size);
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  // zlib reads a file that does not start with the gzip magic as plain text.
  const bool plain = size < 2 || data[0] != 0x1f || data[1] != 0x8b;
  const LineByLine expected = plain ? parse_lines(text, file) : LineByLine{};
  try {
    const lmf::io::CarmenLog log = lmf::io::read_carmen_log(file);
    lmf::fuzz::check_log(log, "carmen log");
    if (plain && expected.error_line) {
      lmf::fuzz::fail("read_carmen_log accepted a log whose line " + std::to_string(*expected.error_line) + " is malformed");
    }
    if (plain && (log.scans.size() != expected.log.scans.size() || log.odometry.size() != expected.log.odometry.size() ||
                  log.params != expected.log.params || log.skipped != expected.log.skipped)) {
      lmf::fuzz::fail("read_carmen_log read a plain log differently from its lines");
    }
    lmf::fuzz::note_outcome("accepted");
  } catch (const lmf::io::CarmenParseError& e) {
    if (plain && expected.error_line != e.line()) {
      lmf::fuzz::fail("read_carmen_log reported line " + std::to_string(e.line()) + ", the lines' first error is " +
                      (expected.error_line ? std::to_string(*expected.error_line) : std::string("none")) + ": " +
                      e.what());
    }
    lmf::fuzz::check_parse_error(e, file, e.line());
    lmf::fuzz::note_outcome("parse_error");
  } catch (const std::runtime_error& e) {
    if (plain) lmf::fuzz::fail(std::string("read_carmen_log failed on a plain file: ") + e.what());
    lmf::fuzz::note_outcome("io_error");
  }
  return 0;
}

std::vector<lmf::fuzz::Bytes> LmfFuzzSeeds() {
  std::string log = "# lmf fuzz seed\n";
  for (const std::string& line : lmf::fuzz::corpus().carmen_lines) log += line + "\n";
  std::string crlf;
  for (const char c : log) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  return {lmf::fuzz::Bytes(log.begin(), log.end()), lmf::fuzz::Bytes(crlf.begin(), crlf.end()), gzip(log)};
}
