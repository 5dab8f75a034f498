// accuracy-json-check FILE [MIN_CASES]: exits 0 when FILE is the JSON that
// scripts/accuracy.sh --json writes (lmf-accuracy): an object with "cases" (at
// least MIN_CASES, default 1, each with every key of a table row and status "ok"),
// "total_wall_s", "total_cpu_s", "all_ok" true and "notes". Prints what is wrong
// otherwise (exit 1). Used by the System.AccuracySmoke test.
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

#include <nlohmann/json.hpp>

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    std::cerr << "usage: accuracy-json-check FILE [MIN_CASES]\n";
    return 2;
  }
  const std::size_t min_cases = argc == 3 ? std::strtoul(argv[2], nullptr, 10) : 1;
  std::ifstream in(argv[1]);
  const nlohmann::json doc = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  int problems = 0;
  const auto fail = [&](const std::string& what) {
    std::cerr << argv[1] << ": " << what << "\n";
    ++problems;
  };
  if (!doc.is_object()) {
    fail("not a JSON object");
    return 1;
  }
  for (const char* key : {"cases", "total_wall_s", "total_cpu_s", "all_ok", "notes"}) {
    if (!doc.contains(key)) fail(std::string("no \"") + key + "\"");
  }
  if (problems != 0) return 1;
  if (doc["all_ok"] != true) fail("all_ok is not true");
  if (!doc["total_wall_s"].is_number() || !doc["total_cpu_s"].is_number()) fail("total times are not numbers");
  const nlohmann::json& cases = doc["cases"];
  if (!cases.is_array() || cases.size() < min_cases) {
    fail("fewer than " + std::to_string(min_cases) + " cases");
    return 1;
  }
  // Numbers a scored case always has; the others may be null (map error on a real log).
  const char* numbers[] = {"ate_m", "ate_deg", "rpe_1m_m", "rpe_1m_deg", "rpe_10m_m", "rpe_10m_deg",
                           "wall_s", "cpu_s", "fusions", "frames_relocated", "relocations_refused",
                           "robots", "robots_joined"};
  const char* nullable[] = {"map_rms_m", "map_segments", "segments_matching_no_wall", "odometry_ate_m"};
  const char* booleans[] = {"psd_throughout", "global_psd_throughout", "local_psd_throughout"};
  for (const nlohmann::json& c : cases) {
    const std::string name = c.value("case", std::string("?"));
    if (c.value("status", std::string()) != "ok") fail(name + ": status is not ok");
    for (const char* k : numbers) {
      if (!c.contains(k) || !c[k].is_number()) fail(name + ": " + k + " is not a number");
    }
    for (const char* k : nullable) {
      if (!c.contains(k) || !(c[k].is_number() || c[k].is_null())) fail(name + ": " + k + " is missing");
    }
    for (const char* k : booleans) {
      if (!c.contains(k) || !c[k].is_boolean()) fail(name + ": " + k + " is not true/false");
    }
  }
  if (problems == 0) std::cout << argv[1] << ": " << cases.size() << " case(s), keys as expected\n";
  return problems == 0 ? 0 : 1;
}
