// lmf_bench_auth: what authenticated messages (runtime/auth.hpp) cost per
// message: signing (HMAC-SHA256 + trailer + copy, what Bus::publish adds) and
// sign + verify (tag, replay window, authorization: what a receiver adds), for
// a local-map ack (29 bytes, argument -1) and local maps of 10, 50, 170 and 512 segments
// (512 is DecodeLimits::max_segments, ~4.2 MB) with 200 scan poses each. For
// scale, the decode of the same local map (runtime/convert, without the
// covariance checks of from_message) is measured too. bytes_per_second is of
// the LCM payload.
#include <cstdint>
#include <memory>
#include <vector>

#include <benchmark/benchmark.h>

#include "runtime/auth.hpp"
#include "runtime/convert.hpp"

namespace {

namespace auth = lmf::runtime::auth;

std::vector<std::uint8_t> local_map_bytes(int segments) {
  lmf::local_map_t map{};
  map.utime = 1'700'000'000'000'000;
  map.robot_id = 1;
  map.seq = 7;
  map.first_scan_utime = map.utime - 20'000'000;
  map.num_scans = 200;
  map.robot = lmf::pose2_t{1.0, 2.0, 0.3};
  map.num_segments = segments;
  for (int i = 0; i < segments; ++i) {
    map.segments.push_back(lmf::segment_t{lmf::pose2_t{0.1 * i, -0.2 * i, 0.01 * i}, 1.5f});
  }
  const int n = 3 + 2 * segments;  // robot pose + 2 dof per segment (DecodeLimits: n = 1027 at 512)
  map.num_covariance = n * (n + 1) / 2;
  map.covariance.assign(static_cast<std::size_t>(map.num_covariance), 1e-3);
  map.num_scan_poses = 200;
  for (int i = 0; i < map.num_scan_poses; ++i) {
    map.scan_utimes.push_back(map.first_scan_utime + 100'000 * i);
    map.scan_poses.push_back(lmf::pose2_t{0.01 * i, 0.0, 0.0});
  }
  return lmf::runtime::encode_message(map);
}

std::vector<std::uint8_t> payload_for(int segments) {
  if (segments < 0) {
    lmf::local_map_ack_t ack{};
    ack.robot_id = 1;
    ack.seq = 7;
    return lmf::runtime::encode_message(ack);
  }
  return local_map_bytes(segments);
}

const auth::Key kRobotKey = auth::random_key();
const auth::Key kServerKey = auth::random_key();

void BM_Sign(benchmark::State& state) {
  const auto payload = payload_for(static_cast<int>(state.range(0)));
  auth::Signer signer(state.range(0) < 0 ? "server" : "robot1", state.range(0) < 0 ? kServerKey : kRobotKey, 1);
  std::vector<std::uint8_t> out;
  for (auto _ : state) {
    signer.sign("LMF_LOCAL_MAP", payload, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(payload.size()));
  state.counters["payload_bytes"] = static_cast<double>(payload.size());
}

void BM_SignVerify(benchmark::State& state) {
  const auto payload = payload_for(static_cast<int>(state.range(0)));
  const bool ack = state.range(0) < 0;
  auth::Signer signer(ack ? "server" : "robot1", ack ? kServerKey : kRobotKey, 1);
  auto keys = std::make_shared<auth::KeyRing>();
  keys->add("server", kServerKey);
  keys->add("robot1", kRobotKey);
  auth::Verifier verifier(keys);
  std::vector<std::uint8_t> out;
  for (auto _ : state) {
    signer.sign("LMF_LOCAL_MAP", payload, out);
    const auto verified = verifier.verify("LMF_LOCAL_MAP", out);
    if (!verified.ok()) state.SkipWithError(verified.rejection().describe().c_str());
    benchmark::DoNotOptimize(verified.value().data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(payload.size()));
  state.counters["payload_bytes"] = static_cast<double>(payload.size());
}

void BM_DecodeOnly(benchmark::State& state) {
  const auto payload = payload_for(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    auto msg = lmf::runtime::decode_message<lmf::local_map_t>(payload.data(), payload.size());
    benchmark::DoNotOptimize(msg.ok());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(payload.size()));
}

BENCHMARK(BM_Sign)->Arg(-1)->Arg(10)->Arg(50)->Arg(170)->Arg(512)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_SignVerify)->Arg(-1)->Arg(10)->Arg(50)->Arg(170)->Arg(512)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DecodeOnly)->Arg(10)->Arg(50)->Arg(170)->Arg(512)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
