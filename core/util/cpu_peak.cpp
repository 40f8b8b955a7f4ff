#include "core/util/cpu_peak.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <fstream>
#include <map>

#include <immintrin.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace residue {
namespace {

// 16 independent accumulators keep both FMA ports busy through the 4-cycle latency.
constexpr int kAcc = 16;
constexpr int64_t kInner = 1 << 14;

__attribute__((target("avx512f"))) float fma_loop_avx512(int64_t iterations) {
  __m512 acc[kAcc];
  for (int i = 0; i < kAcc; ++i) acc[i] = _mm512_set1_ps(static_cast<float>(i) * 1e-3f);
  const __m512 a = _mm512_set1_ps(0.999999f), b = _mm512_set1_ps(1e-7f);
  for (int64_t it = 0; it < iterations; ++it)
    for (int i = 0; i < kAcc; ++i) acc[i] = _mm512_fmadd_ps(acc[i], a, b);
  __m512 sum = acc[0];
  for (int i = 1; i < kAcc; ++i) sum = _mm512_add_ps(sum, acc[i]);
  float out[16];
  _mm512_storeu_ps(out, sum);  // (not _mm512_reduce_add_ps: GCC 12 warns inside it)
  return out[0];
}

__attribute__((target("avx2,fma"))) float fma_loop_avx2(int64_t iterations) {
  __m256 acc[kAcc];
  for (int i = 0; i < kAcc; ++i) acc[i] = _mm256_set1_ps(static_cast<float>(i) * 1e-3f);
  const __m256 a = _mm256_set1_ps(0.999999f), b = _mm256_set1_ps(1e-7f);
  for (int64_t it = 0; it < iterations; ++it)
    for (int i = 0; i < kAcc; ++i) acc[i] = _mm256_fmadd_ps(acc[i], a, b);
  float out[8];
  __m256 sum = acc[0];
  for (int i = 1; i < kAcc; ++i) sum = _mm256_add_ps(sum, acc[i]);
  _mm256_storeu_ps(out, sum);
  return out[0];
}

float fma_loop_scalar(int64_t iterations) {
  float acc[kAcc];
  for (int i = 0; i < kAcc; ++i) acc[i] = static_cast<float>(i) * 1e-3f;
  for (int64_t it = 0; it < iterations; ++it)
    for (int i = 0; i < kAcc; ++i) acc[i] = acc[i] * 0.999999f + 1e-7f;
  float s = 0;
  for (float v : acc) s += v;
  return s;
}

}  // namespace

CpuPeak measure_fp32_peak(int threads, double seconds) {
  CpuPeak peak;
  peak.threads = threads;
  int lanes = 1;
  float (*loop)(int64_t) = fma_loop_scalar;
  if (__builtin_cpu_supports("avx512f")) {
    loop = fma_loop_avx512;
    lanes = 16;
    peak.isa = "avx512f";
  } else if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
    loop = fma_loop_avx2;
    lanes = 8;
    peak.isa = "avx2+fma";
  } else {
    peak.isa = "scalar";
  }
  tbb::task_arena arena(threads);
  std::atomic<float> sink{0};
  for (int attempt = 0; attempt < 3; ++attempt) {
    std::atomic<int64_t> total_iterations{0};
    const auto start = std::chrono::steady_clock::now();
    arena.execute([&] {
      tbb::parallel_for(0, threads, [&](int) {
        int64_t done = 0;
        float s = 0;
        while (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() < seconds) {
          s += loop(kInner);
          done += kInner;
        }
        total_iterations += done;
        sink = sink + s;
      }, tbb::static_partitioner());
    });
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double flops = static_cast<double>(total_iterations.load()) * kAcc * lanes * 2.0;
    peak.gflops = std::max(peak.gflops, flops / elapsed / 1e9);
  }
  return peak;
}

std::string cpu_description() {
  std::ifstream in("/proc/cpuinfo");
  std::map<std::string, std::string> first;  // the first processor's fields
  for (std::string line; std::getline(in, line) && !line.empty();) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string key = line.substr(0, colon);
    key.erase(key.find_last_not_of(" \t") + 1);
    const auto v = line.find_first_not_of(' ', colon + 1);
    first.emplace(key, v == std::string::npos ? "" : line.substr(v));
  }
  if (!first.count("model name")) return "unknown CPU";
  std::string out = first["model name"];
  if (first.count("cpu family") && first.count("model"))
    out += " (family " + first["cpu family"] + " model " + first["model"] + ")";
  return out;
}

}  // namespace residue
