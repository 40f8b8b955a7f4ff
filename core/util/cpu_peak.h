// This machine's measured fp32 ceiling: an FMA loop on every allowed thread, so benchmark figures can be
// stated as a share of what the CPU can do rather than of a datasheet number.
#pragma once

#include <string>

namespace residue {

struct CpuPeak {
  double gflops = 0;      // fp32 multiply-add rate, all threads, GFLOP/s
  std::string isa;        // "avx512f", "avx2+fma" or "scalar"
  int threads = 0;
};

// The CPU as benchmark figures name it: "/proc/cpuinfo's model name (family F model M)", e.g. "AMD EPYC (family 26
// model 2)": machines of one name differ (Zen 4 and Zen 5 are both "AMD EPYC"), the family and model tell them apart.
// "unknown CPU" where /proc/cpuinfo cannot be read.
std::string cpu_description();

// Runs for about `seconds` per measurement and reports the best of three.
CpuPeak measure_fp32_peak(int threads, double seconds = 0.2);

}  // namespace residue
