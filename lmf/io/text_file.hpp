// Line-oriented text files that may be gzip-compressed (zlib reads plain files
// transparently). Used by the CARMEN and trajectory readers/writers.
#pragma once

#include <cstddef>
#include <filesystem>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lmf::io {

// Calls `on_line(text, line_number)` for every line (1-based; the trailing
// "\n" or "\r\n" removed; any length; a last line without newline included).
// Throws std::runtime_error when the file cannot be opened or decompressed;
// exceptions from `on_line` pass through.
void for_each_line(const std::filesystem::path& file,
                   const std::function<void(const std::string& text, std::size_t line_number)>& on_line);
// The same, also telling whether the line ended with a newline (false only
// for a last line without one: a file cut while it was being written).
void for_each_line(
    const std::filesystem::path& file,
    const std::function<void(const std::string& text, std::size_t line_number, bool terminated)>& on_line);

// Writes `text` to `file`, gzip-compressed when `gzip` is true or the name ends
// in ".gz". Throws std::runtime_error on I/O errors.
void write_text_file(const std::filesystem::path& file, const std::string& text, bool gzip);

// Microseconds as seconds with exactly six decimals ("-1.500001"), no rounding.
std::string seconds_text(int64_t utime);

// Whitespace-separated fields (spaces, tabs, carriage returns).
std::vector<std::string_view> split_fields(std::string_view text);

// The whole field as a double (a leading '+' allowed; "nan"/"inf" parse as
// such), or nullopt when it is not a number or out of range.
std::optional<double> parse_double(std::string_view field);

}  // namespace lmf::io
