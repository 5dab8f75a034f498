// lmf-accuracy: the accuracy table of scripts/accuracy.sh. Reads the report.json that
// lmf-offline wrote for each case (and the case's measured wall and CPU time) and prints one
// table; optionally writes it as JSON and as a markdown table. It runs nothing itself.
//
// A case folder holds report.json (lmf-offline --out) and time.txt ("wall_s user_s sys_s", as
// bash's `time` with TIMEFORMAT='%R %U %S' prints it). A case without report.json failed: its
// row says so (stderr.txt is quoted in the JSON) and the tool exits 1 after writing everything.
//
// Frame registration (report.json fusions[].registration): "relocated" counts the fusions whose
// frame moved to where the nearby walls put it; "refused" those whose registration disagreed
// with the predicted frame but was ambiguous or degenerate, so nothing moved.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <iostream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <boost/program_options.hpp>
#include <nlohmann/json.hpp>

#include "tools/tool_support.hpp"

namespace po = boost::program_options;
using nlohmann::json;

namespace {

std::string slurp(const std::string& file) {
  std::ifstream in(file);
  if (!in) return {};
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// "NAME=DIR"
std::pair<std::string, std::string> split_case(const std::string& arg) {
  const auto eq = arg.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == arg.size()) {
    throw std::invalid_argument("--case wants NAME=DIR, got \"" + arg + "\"");
  }
  return {arg.substr(0, eq), arg.substr(eq + 1)};
}

double number_at(const json& j, const json::json_pointer& p) {
  return j.contains(p) && j.at(p).is_number() ? j.at(p).get<double>() : std::nan("");
}

json nullable(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// The number at `p` as report.json has it (an integer stays one), or null.
json number_or_null(const json& j, const json::json_pointer& p) {
  return j.contains(p) && j.at(p).is_number() ? j.at(p) : json(nullptr);
}

// One row of the table as JSON (every key always present; null where not known).
json read_case(const std::string& name, const std::string& dir) {
  json row = {{"case", name}, {"dir", dir}};
  std::istringstream times(slurp(dir + "/time.txt"));
  double wall = std::nan(""), user = 0.0, sys = 0.0;
  if (!(times >> wall >> user >> sys)) wall = std::nan("");
  row["wall_s"] = nullable(wall);
  row["cpu_s"] = nullable(std::isfinite(wall) ? user + sys : std::nan(""));

  const std::string text = slurp(dir + "/report.json");
  json report;
  if (!text.empty()) report = json::parse(text, nullptr, /*allow_exceptions=*/false);
  const bool ok = report.is_object() && report.contains("score");
  row["status"] = ok ? "ok" : "failed";
  if (!ok) {
    std::string err = slurp(dir + "/stderr.txt");
    if (err.size() > 2000) err = err.substr(err.size() - 2000);
    row["error"] = report.is_object() ? "report.json has no score (no robot with a reference)" : err;
  }
  using P = json::json_pointer;
  row["inputs"] = ok ? report.value("inputs", "") : "";
  row["ate_m"] = nullable(number_at(report, P("/score/ate/position_rmse_m")));
  row["ate_deg"] = nullable(number_at(report, P("/score/ate/heading_rmse_deg")));
  row["rpe_1m_m"] = nullable(number_at(report, P("/score/rpe_1m/translation_rmse_m")));
  row["rpe_1m_deg"] = nullable(number_at(report, P("/score/rpe_1m/rotation_rmse_deg")));
  row["rpe_10m_m"] = nullable(number_at(report, P("/score/rpe_10m/translation_rmse_m")));
  row["rpe_10m_deg"] = nullable(number_at(report, P("/score/rpe_10m/rotation_rmse_deg")));
  row["map_rms_m"] = nullable(number_at(report, P("/map_error/rms_m")));
  row["map_segments"] = number_or_null(report, P("/map_error/segments"));
  row["segments_matching_no_wall"] = number_or_null(report, P("/map_error/unmatched_segments"));

  // Odometry alone, for comparison: RMS over the robots of each robot's own aligned odometry ATE.
  double odo2 = 0.0;
  double odo_n = 0.0;
  int robots = 0, joined = 0;
  long shipped = 0, fused = 0;
  bool local_psd = true;
  if (ok) {
    for (const json& r : report.at("score").value("robots", json::array())) {
      const double e = number_at(r, P("/odometry_ate/position_rmse_m"));
      const double n = number_at(r, P("/odometry_ate/count"));
      if (std::isfinite(e) && std::isfinite(n)) {
        odo2 += n * e * e;
        odo_n += n;
      }
    }
    for (const json& r : report.value("robots", json::array())) {
      ++robots;
      if (r.value("joined", false)) ++joined;
      shipped += r.value("local_maps_shipped", 0L);
      fused += r.value("local_maps_fused", 0L);
      if (!r.value("covariance_always_ok", false)) local_psd = false;
    }
  }
  // The front end (local maps and scan matches against the reference), over all robots.
  double lm_nees_sum = 0.0, lm_worst_m = 0.0, lm_worst_rad = 0.0, match_nees_sum = 0.0, chain_nees_sum = 0.0;
  long lm_count = 0, match_count = 0, chain_count = 0, fallbacks = 0;
  // A robot's {count, mean} at `key` added to a mean over all robots.
  const auto add_mean = [](const json& robot, const std::string& key, double& sum, long& count) {
    const double n = number_at(robot, P("/" + key + "/count"));
    const double mean = number_at(robot, P("/" + key + "/mean"));
    if (std::isfinite(n) && n > 0 && std::isfinite(mean)) {
      sum += mean * n;
      count += static_cast<long>(n);
    }
  };
  if (ok) {
    for (const json& r : report.value("robots", json::array())) {
      for (const json& c : r.value("local_map_consistency", json::array())) {
        lm_nees_sum += c.value("nees", 0.0);
        lm_worst_m = std::max(lm_worst_m, c.value("error_m", 0.0));
        lm_worst_rad = std::max(lm_worst_rad, c.value("error_rad", 0.0));
        ++lm_count;
      }
      add_mean(r, "match_nees", match_nees_sum, match_count);
      add_mean(r, "match_chain_nees", chain_nees_sum, chain_count);
      fallbacks += r.value("match_fallbacks", 0L);
    }
  }
  const double none = std::nan("");
  row["local_map_nees_mean"] = nullable(lm_count > 0 ? lm_nees_sum / static_cast<double>(lm_count) : none);
  row["local_map_worst_m"] = nullable(lm_count > 0 ? lm_worst_m : none);
  row["local_map_worst_deg"] = nullable(lm_count > 0 ? lm_worst_rad * 180.0 / std::numbers::pi : none);
  row["match_nees_mean"] = nullable(match_count > 0 ? match_nees_sum / static_cast<double>(match_count) : none);
  row["match_chain_nees_mean"] = nullable(chain_count > 0 ? chain_nees_sum / static_cast<double>(chain_count) : none);
  row["match_fallbacks"] = fallbacks;
  row["odometry_ate_m"] = nullable(odo_n > 0 ? std::sqrt(odo2 / odo_n) : std::nan(""));
  row["robots"] = robots;
  row["robots_joined"] = joined;
  row["local_maps_shipped"] = shipped;
  row["local_maps_fused"] = fused;

  long relocated = 0;
  long refused = 0;
  const json fusions = ok ? report.value("fusions", json::array()) : json::array();
  for (const json& f : fusions) {
    const std::string outcome = f.value("registration", std::string());
    if (outcome == "relocated") ++relocated;
    if (outcome == "ambiguous" || outcome == "degenerate") ++refused;
  }
  row["fusions"] = fusions.size();
  row["frames_relocated"] = relocated;
  row["relocations_refused"] = refused;
  const bool global_psd = ok && report.value("global_covariance_always_ok", false);
  row["global_psd_throughout"] = global_psd;
  row["local_psd_throughout"] = ok && local_psd;
  row["psd_throughout"] = global_psd && local_psd;
  return row;
}

std::string cell(const json& v, const char* format) {
  if (v.is_null()) return "-";
  char s[64];
  std::snprintf(s, sizeof s, format, v.get<double>());
  return s;
}

std::string pair_cell(const json& m, const json& deg) {
  if (m.is_null()) return "-";
  return cell(m, "%.3f") + " / " + cell(deg, "%.2f");
}

struct Column {
  const char* title;
  std::string (*format)(const json&);
};

const std::vector<Column>& columns() {
  static const std::vector<Column> c = {
      {"case", [](const json& r) { return r["case"].get<std::string>(); }},
      {"ATE m", [](const json& r) { return r["status"] == "ok" ? cell(r["ate_m"], "%.3f") : std::string("FAILED"); }},
      {"ATE deg", [](const json& r) { return cell(r["ate_deg"], "%.2f"); }},
      {"RPE 1 m (m / deg)", [](const json& r) { return pair_cell(r["rpe_1m_m"], r["rpe_1m_deg"]); }},
      {"RPE 10 m (m / deg)", [](const json& r) { return pair_cell(r["rpe_10m_m"], r["rpe_10m_deg"]); }},
      {"map RMS m", [](const json& r) { return cell(r["map_rms_m"], "%.3f"); }},
      {"segments no wall",
       [](const json& r) {
         if (r["segments_matching_no_wall"].is_null()) return std::string("-");
         return cell(r["segments_matching_no_wall"], "%.0f") + " / " + cell(r["map_segments"], "%.0f");
       }},
      {"relocated / refused / fusions",
       [](const json& r) {
         return std::to_string(r["frames_relocated"].get<long>()) + " / " +
                std::to_string(r["relocations_refused"].get<long>()) + " / " + std::to_string(r["fusions"].get<long>());
       }},
      {"LM NEES", [](const json& r) { return cell(r["local_map_nees_mean"], "%.1f"); }},
      {"LM worst (m / deg)", [](const json& r) { return pair_cell(r["local_map_worst_m"], r["local_map_worst_deg"]); }},
      {"match NEES", [](const json& r) { return cell(r["match_nees_mean"], "%.1f"); }},
      {"match NEES 10", [](const json& r) { return cell(r["match_chain_nees_mean"], "%.1f"); }},
      {"fallbacks", [](const json& r) { return std::to_string(r["match_fallbacks"].get<long>()); }},
      {"P PSD", [](const json& r) { return std::string(r["psd_throughout"].get<bool>() ? "yes" : "NO"); }},
      {"odom ATE m", [](const json& r) { return cell(r["odometry_ate_m"], "%.2f"); }},
      {"wall s", [](const json& r) { return cell(r["wall_s"], "%.1f"); }},
      {"CPU s", [](const json& r) { return cell(r["cpu_s"], "%.1f"); }},
  };
  return c;
}

std::string text_table(const json& rows) {
  std::vector<std::vector<std::string>> cells;
  std::vector<std::size_t> width;
  for (const Column& c : columns()) width.push_back(std::string(c.title).size());
  for (const json& r : rows) {
    std::vector<std::string> line;
    for (std::size_t i = 0; i < columns().size(); ++i) {
      line.push_back(columns()[i].format(r));
      width[i] = std::max(width[i], line.back().size());
    }
    cells.push_back(std::move(line));
  }
  std::ostringstream out;
  const auto print = [&](const std::vector<std::string>& line) {
    for (std::size_t i = 0; i < line.size(); ++i) {
      out << (i == 0 ? "" : "  ") << line[i] << std::string(width[i] - line[i].size(), ' ');
    }
    out << "\n";
  };
  std::vector<std::string> titles;
  for (const Column& c : columns()) titles.emplace_back(c.title);
  print(titles);
  for (const auto& line : cells) print(line);
  return out.str();
}

std::string markdown_table(const json& rows) {
  std::ostringstream out;
  out << "|";
  for (const Column& c : columns()) out << " " << c.title << " |";
  out << "\n|";
  for (std::size_t i = 0; i < columns().size(); ++i) out << (i == 0 ? " --- |" : " ---: |");
  out << "\n";
  for (const json& r : rows) {
    out << "|";
    for (const Column& c : columns()) out << " " << c.format(r) << " |";
    out << "\n";
  }
  return out.str();
}

void write_file(const std::string& file, const std::string& text) {
  std::ofstream out(file);
  out << text;
  if (!out) throw std::runtime_error(file + ": cannot write");
}

}  // namespace

int main(int argc, char** argv) {
  po::options_description options(
      "lmf-accuracy: the accuracy table over lmf-offline case folders (scripts/accuracy.sh).\n"
      "Usage: lmf-accuracy --case NAME=DIR [--case ...] [--json FILE] [--markdown FILE] [--note TEXT...]\n\n"
      "Options");
  std::vector<std::string> cases;
  std::vector<std::string> notes;
  std::string json_file;
  std::string markdown_file;
  double total_wall_s = std::nan("");
  options.add_options()("help,h", "print this help")(
      "case", po::value(&cases), "a case: NAME=DIR, DIR holding report.json and time.txt (repeatable, in order)")(
      "json", po::value(&json_file), "write the table as JSON to this file")(
      "markdown", po::value(&markdown_file), "write the table as markdown to this file")(
      "total-wall-s", po::value(&total_wall_s), "the whole run's wall time (recorded in the JSON)")(
      "note", po::value(&notes), "a line recorded in the JSON and under the markdown table (repeatable)");
  if (const auto exit_code = lmf::tools::parse_command_line(argc, argv, options, "lmf-accuracy")) return *exit_code;
  return lmf::tools::run_reporting_errors("lmf-accuracy", [&] {
    json rows = json::array();
    bool all_ok = true;
    double cpu = 0.0;
    for (const std::string& arg : cases) {
      const auto [name, dir] = split_case(arg);
      rows.push_back(read_case(name, dir));
      all_ok = all_ok && rows.back()["status"] == "ok";
      if (rows.back()["cpu_s"].is_number()) cpu += rows.back()["cpu_s"].get<double>();
    }
    notes.emplace_back(
        "LM NEES: mean end-pose NEES of the shipped local maps against the reference (3 if consistent); LM worst: "
        "the largest local-map end error; match NEES: mean NEES of the scan-matched motions against the "
        "reference motion (3 if consistent); match NEES 10: the same over chains of 10 consecutive matches, where "
        "an error of one scan's own (or of the reference's at that scan) cancels as it does along a local map; "
        "fallbacks: scans whose match failed (odometry alone)");
    notes.emplace_back(
        "relocated / refused / fusions: fusions whose frame the registration against the nearby map moved; "
        "whose registration disagreed with the predicted frame but was ambiguous or degenerate (nothing moved); "
        "all fusions");
    const std::string table = text_table(rows);
    std::cout << table;
    for (const std::string& n : notes) std::cout << "note: " << n << "\n";
    if (!json_file.empty()) {
      const json doc = {{"cases", rows},
                        {"total_wall_s", nullable(total_wall_s)},
                        {"total_cpu_s", cpu},
                        {"all_ok", all_ok},
                        {"notes", notes}};
      write_file(json_file, doc.dump(1) + "\n");
    }
    if (!markdown_file.empty()) {
      std::string md = markdown_table(rows);
      for (const std::string& n : notes) md += "\n" + n + "\n";
      write_file(markdown_file, md);
    }
    return all_ok ? 0 : 1;
  });
}
