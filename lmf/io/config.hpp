// Strict JSON configuration reading (STYLE.md: "config is typed structs with
// documented defaults, parsed strictly").
//
// Each module keeps its own typed config struct with defaults; its parser reads
// the fields it knows with a JsonReader and then calls finish(), which rejects
// every key nobody read (a misspelt key is an error, never silently ignored).
// Every error is a std::invalid_argument whose message names the source (the
// file) and the key path, e.g.
//   "robot.json: local_map.ship_distance_m: must be > 0, got -1".
//
//   JsonReader r = JsonReader::from_file(path);
//   LocalMapConfig c;                       // defaults
//   r.read("ship_distance_m", c.ship_distance_m, positive());
//   if (JsonReader* e = r.optional_section("extraction")) e->read("min_points", c.extraction.min_points);
//   finish_and_validate(r, c);              // unknown keys (recursively), then the
//                                           // struct's own cross-field c.validate()
//
// Comments (`//`, `/* */`) are allowed in files. Not thread-safe.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmf/geometry/pose2.hpp"

namespace lmf::io {

// A condition on a numeric value, with the text used in the error message.
struct Requirement {
  std::function<bool(double)> ok;
  std::string text;  // completes "must be ...": "> 0", "in [0, 1]"
};
Requirement positive();                      // > 0
Requirement non_negative();                  // >= 0
Requirement at_least(double min);            // >= min
Requirement in_closed(double lo, double hi);  // [lo, hi]
Requirement in_open(double lo, double hi);    // (lo, hi), e.g. a probability alpha in (0, 1)

// Parses a JSON file (comments allowed). Throws std::invalid_argument naming the
// file when it cannot be read or is not valid JSON (with line and column).
nlohmann::json read_json_file(const std::filesystem::path& file);

class JsonReader {
 public:
  // `object` must be a JSON object (throws std::invalid_argument otherwise).
  // `source` names where it came from in messages (usually the file); `path` is
  // the key path of this object inside it ("" at the top).
  JsonReader(nlohmann::json object, std::string source, std::string path = "");
  static JsonReader from_file(const std::filesystem::path& file);
  static JsonReader from_string(const std::string& text, const std::string& source = "<string>");

  JsonReader(JsonReader&&) = default;
  JsonReader& operator=(JsonReader&&) = default;
  JsonReader(const JsonReader&) = delete;
  JsonReader& operator=(const JsonReader&) = delete;
  ~JsonReader() = default;

  bool has(const std::string& key) const { return object_.contains(key); }
  const std::string& source() const { return source_; }
  const std::string& path() const { return path_; }
  // All keys present in this object (sorted).
  std::vector<std::string> keys() const;

  // read(key, value[, requirement]): when the key is present, type-checks it,
  // stores it in `value` and marks it used; when absent, leaves the default.
  // Returns whether the key was present. Supported: bool, std::string, double,
  // float, any integer type (the JSON value must be an integer in range), and
  // std::vector of those; Pose2 as [x_m, y_m, theta_rad].
  template <typename T>
  bool read(const std::string& key, T& value);
  // The same with a numeric requirement on the value (each element of a vector).
  template <typename T>
  bool read(const std::string& key, T& value, const Requirement& requirement);

  // A key that must be present.
  template <typename T>
  T required(const std::string& key);
  template <typename T>
  T required(const std::string& key, const Requirement& requirement);

  // A string that must be one of `choices` (name -> value), e.g. an enum.
  template <typename E>
  bool read_choice(const std::string& key, E& value,
                   std::initializer_list<std::pair<const char*, E>> choices) {
    return read_choice_in(key, value, choices);
  }
  template <typename E, std::size_t N>
  bool read_choice(const std::string& key, E& value, const std::array<std::pair<const char*, E>, N>& choices) {
    return read_choice_in(key, value, choices);
  }

  // Nested objects. The child is owned by this reader and checked by finish().
  // section() throws when the key is absent or not an object; optional_section()
  // returns nullptr when absent.
  JsonReader& section(const std::string& key);
  JsonReader* optional_section(const std::string& key);
  // An array of objects (e.g. one per robot); empty when absent.
  std::vector<JsonReader*> section_array(const std::string& key);

  // Marks a key as deliberately unused (e.g. handled by another parser).
  void ignore(const std::string& key) { used_.insert(key); }

  // Throws std::invalid_argument naming every key of this object and of its
  // sections that was never read.
  void finish() const;

  // Throws std::invalid_argument "source: path.key: what".
  [[noreturn]] void fail(const std::string& key, const std::string& what) const;

 private:
  std::string key_path(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  static std::string describe(const nlohmann::json& v);

  template <typename T>
  void convert(const std::string& key, const nlohmann::json& j, T& out) const;
  template <typename E, typename Choices>
  bool read_choice_in(const std::string& key, E& value, const Choices& choices);
  void check(const std::string& key, double v, const Requirement& requirement) const;
  void collect_unused(std::vector<std::string>& out) const;

  nlohmann::json object_;
  std::string source_;
  std::string path_;
  std::set<std::string> used_;
  std::map<std::string, std::unique_ptr<JsonReader>> sections_;
  std::map<std::string, std::vector<std::unique_ptr<JsonReader>>> arrays_;
};

// ---------------------------------------------------------------------------
// Implementation of the templates.

namespace config_detail {
template <typename T>
struct is_vector : std::false_type {};
template <typename T, typename A>
struct is_vector<std::vector<T, A>> : std::true_type {};
}  // namespace config_detail

template <typename T>
void JsonReader::convert(const std::string& key, const nlohmann::json& j, T& out) const {
  if constexpr (std::is_same_v<T, bool>) {
    if (!j.is_boolean()) fail(key, "expected true or false, got " + describe(j));
    out = j.get<bool>();
  } else if constexpr (std::is_same_v<T, std::string>) {
    if (!j.is_string()) fail(key, "expected a string, got " + describe(j));
    out = j.get<std::string>();
  } else if constexpr (std::is_floating_point_v<T>) {
    if (!j.is_number()) fail(key, "expected a number, got " + describe(j));
    const double v = j.get<double>();
    if (!std::isfinite(v) || std::abs(v) > static_cast<double>(std::numeric_limits<T>::max())) {
      fail(key, "number out of range: " + describe(j));
    }
    out = static_cast<T>(v);
  } else if constexpr (std::is_integral_v<T>) {
    if (!j.is_number_integer()) fail(key, "expected an integer, got " + describe(j));
    bool in_range = false;
    if (j.is_number_unsigned()) {
      const auto v = j.get<std::uint64_t>();
      in_range = v <= static_cast<std::uint64_t>(std::numeric_limits<T>::max());
      if (in_range) out = static_cast<T>(v);
    } else {
      const auto v = j.get<std::int64_t>();
      if constexpr (std::is_signed_v<T>) {
        in_range = v >= static_cast<std::int64_t>(std::numeric_limits<T>::min()) &&
                   v <= static_cast<std::int64_t>(std::numeric_limits<T>::max());
      } else {
        in_range = v >= 0 && static_cast<std::uint64_t>(v) <= std::numeric_limits<T>::max();
      }
      if (in_range) out = static_cast<T>(v);
    }
    if (!in_range) fail(key, "integer out of range for this field: " + describe(j));
  } else if constexpr (std::is_same_v<T, Pose2>) {
    if (!j.is_array() || j.size() != 3) fail(key, "expected [x_m, y_m, theta_rad], got " + describe(j));
    double v[3];
    for (std::size_t i = 0; i < 3; ++i) convert(key + "[" + std::to_string(i) + "]", j[i], v[i]);
    out = Pose2(v[0], v[1], wrap_angle(v[2]));
  } else if constexpr (config_detail::is_vector<T>::value) {
    if (!j.is_array()) fail(key, "expected an array, got " + describe(j));
    T result;
    result.resize(j.size());
    for (std::size_t i = 0; i < j.size(); ++i) {
      typename T::value_type element{};
      convert(key + "[" + std::to_string(i) + "]", j[i], element);
      result[i] = std::move(element);
    }
    out = std::move(result);
  } else {
    static_assert(sizeof(T) == 0, "JsonReader::read: unsupported type");
  }
}

template <typename T>
bool JsonReader::read(const std::string& key, T& value) {
  used_.insert(key);
  const auto it = object_.find(key);
  if (it == object_.end()) return false;
  convert(key, *it, value);
  return true;
}

template <typename T>
bool JsonReader::read(const std::string& key, T& value, const Requirement& requirement) {
  T candidate = value;
  if (!read(key, candidate)) return false;
  if constexpr (config_detail::is_vector<T>::value) {
    for (std::size_t i = 0; i < candidate.size(); ++i) {
      check(key + "[" + std::to_string(i) + "]", static_cast<double>(candidate[i]), requirement);
    }
  } else {
    static_assert(std::is_arithmetic_v<T> && !std::is_same_v<T, bool>, "requirements apply to numbers");
    check(key, static_cast<double>(candidate), requirement);
  }
  value = std::move(candidate);
  return true;
}

template <typename T>
T JsonReader::required(const std::string& key) {
  T value{};
  if (!read(key, value)) fail(key, "missing (required)");
  return value;
}

template <typename T>
T JsonReader::required(const std::string& key, const Requirement& requirement) {
  T value{};
  if (!read(key, value, requirement)) fail(key, "missing (required)");
  return value;
}

template <typename E, typename Choices>
bool JsonReader::read_choice_in(const std::string& key, E& value, const Choices& choices) {
  std::string name;
  if (!read(key, name)) return false;
  std::string list;
  for (const auto& [choice, v] : choices) {
    if (name == choice) {
      value = v;
      return true;
    }
    list += list.empty() ? "" : ", ";
    list += std::string("\"") + choice + "\"";
  }
  fail(key, "\"" + name + "\" is not one of " + list);
}

// The end of every config parse: finish() (unknown keys), then the struct's own
// cross-field config.validate(), its message prefixed with the reader's source.
template <typename Config>
void finish_and_validate(const JsonReader& reader, const Config& config) {
  reader.finish();
  try {
    config.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(reader.source() + ": " + e.what());
  }
}

}  // namespace lmf::io
