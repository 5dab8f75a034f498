#include "lmf/io/config.hpp"

#include <fstream>
#include <sstream>

namespace lmf::io {
namespace {

std::string number_text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

Requirement positive() {
  return {[](double v) { return v > 0.0; }, "> 0"};
}

Requirement non_negative() {
  return {[](double v) { return v >= 0.0; }, ">= 0"};
}

Requirement at_least(double min) {
  return {[min](double v) { return v >= min; }, ">= " + number_text(min)};
}

Requirement in_closed(double lo, double hi) {
  return {[lo, hi](double v) { return v >= lo && v <= hi; }, "in [" + number_text(lo) + ", " + number_text(hi) + "]"};
}

Requirement in_open(double lo, double hi) {
  return {[lo, hi](double v) { return v > lo && v < hi; }, "in (" + number_text(lo) + ", " + number_text(hi) + ")"};
}

nlohmann::json read_json_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::invalid_argument(file.string() + ": cannot open config file");
  std::stringstream text;
  text << in.rdbuf();
  if (in.bad()) throw std::invalid_argument(file.string() + ": cannot read config file");
  try {
    return nlohmann::json::parse(text.str(), nullptr, /*allow_exceptions=*/true, /*ignore_comments=*/true);
  } catch (const nlohmann::json::parse_error& e) {
    // e.what() carries "at line L, column C".
    throw std::invalid_argument(file.string() + ": invalid JSON: " + e.what());
  }
}

JsonReader::JsonReader(nlohmann::json object, std::string source, std::string path)
    : object_(std::move(object)), source_(std::move(source)), path_(std::move(path)) {
  if (!object_.is_object()) {
    throw std::invalid_argument(source_ + ": " + (path_.empty() ? std::string("top level") : path_) +
                                ": expected a JSON object, got " + describe(object_));
  }
}

JsonReader JsonReader::from_file(const std::filesystem::path& file) {
  return JsonReader(read_json_file(file), file.string());
}

JsonReader JsonReader::from_string(const std::string& text, const std::string& source) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text, nullptr, true, true);
  } catch (const nlohmann::json::parse_error& e) {
    throw std::invalid_argument(source + ": invalid JSON: " + e.what());
  }
  return JsonReader(std::move(j), source);
}

std::vector<std::string> JsonReader::keys() const {
  std::vector<std::string> out;
  for (const auto& item : object_.items()) out.push_back(item.key());
  return out;  // nlohmann::json objects are std::map-ordered
}

std::string JsonReader::describe(const nlohmann::json& v) {
  std::string text = v.dump();
  if (text.size() > 60) text = text.substr(0, 57) + "...";
  return std::string(v.type_name()) + " " + text;
}

void JsonReader::fail(const std::string& key, const std::string& what) const {
  throw std::invalid_argument(source_ + ": " + key_path(key) + ": " + what);
}

void JsonReader::check(const std::string& key, double v, const Requirement& requirement) const {
  if (!requirement.ok(v)) fail(key, "must be " + requirement.text + ", got " + number_text(v));
}

JsonReader& JsonReader::section(const std::string& key) {
  JsonReader* s = optional_section(key);
  if (s == nullptr) fail(key, "missing (required section)");
  return *s;
}

JsonReader* JsonReader::optional_section(const std::string& key) {
  used_.insert(key);
  const auto it = object_.find(key);
  if (it == object_.end()) return nullptr;
  auto& slot = sections_[key];
  if (!slot) {
    if (!it->is_object()) fail(key, "expected an object, got " + describe(*it));
    slot = std::make_unique<JsonReader>(*it, source_, key_path(key));
  }
  return slot.get();
}

std::vector<JsonReader*> JsonReader::section_array(const std::string& key) {
  used_.insert(key);
  std::vector<JsonReader*> out;
  const auto it = object_.find(key);
  if (it == object_.end()) return out;
  auto& slot = arrays_[key];
  if (slot.empty()) {
    if (!it->is_array()) fail(key, "expected an array of objects, got " + describe(*it));
    for (std::size_t i = 0; i < it->size(); ++i) {
      const std::string element = key + "[" + std::to_string(i) + "]";
      if (!(*it)[i].is_object()) fail(element, "expected an object, got " + describe((*it)[i]));
      slot.push_back(std::make_unique<JsonReader>((*it)[i], source_, key_path(element)));
    }
  }
  for (const auto& s : slot) out.push_back(s.get());
  return out;
}

void JsonReader::collect_unused(std::vector<std::string>& out) const {
  for (const auto& item : object_.items()) {
    if (used_.count(item.key()) == 0) out.push_back(key_path(item.key()));
  }
  for (const auto& [key, s] : sections_) s->collect_unused(out);
  for (const auto& [key, list] : arrays_) {
    for (const auto& s : list) s->collect_unused(out);
  }
}

void JsonReader::finish() const {
  std::vector<std::string> unused;
  collect_unused(unused);
  if (unused.empty()) return;
  std::string list;
  for (const std::string& k : unused) list += (list.empty() ? "" : ", ") + k;
  throw std::invalid_argument(source_ + ": unknown key" + (unused.size() > 1 ? "s " : " ") + list);
}

}  // namespace lmf::io
