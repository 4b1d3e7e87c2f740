// Lock-free latency histogram: one writer adds samples, any thread reads percentiles.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace rheo::rt {

/// Fixed bins of 1 microsecond from 0 to kBins-1 us, plus an overflow bin; the exact maximum is
/// kept too. Add() is wait-free and never allocates.
class Histogram {
 public:
  static constexpr int kBins = 20000;  // 20 ms range at 1 us resolution

  void Add(int64_t ns) {
    if (ns < 0) ns = 0;
    int64_t us = ns / 1000;
    int bin = us >= kBins ? kBins : static_cast<int>(us);
    bins_[bin].fetch_add(1, std::memory_order_relaxed);
    count_.fetch_add(1, std::memory_order_relaxed);
    sum_ns_.fetch_add(ns, std::memory_order_relaxed);
    int64_t m = max_ns_.load(std::memory_order_relaxed);
    while (ns > m && !max_ns_.compare_exchange_weak(m, ns, std::memory_order_relaxed)) {
    }
  }

  uint64_t count() const { return count_.load(std::memory_order_relaxed); }
  int64_t max_ns() const { return max_ns_.load(std::memory_order_relaxed); }
  double mean_ns() const {
    uint64_t c = count();
    return c ? static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) / c : 0.0;
  }

  /// Value below which fraction q (0..1) of samples lie, in ns, at bin-centre resolution (the
  /// top quantile reports the exact maximum). Reads race benignly with Add().
  int64_t Quantile(double q) const;

  void Reset();

 private:
  std::array<std::atomic<uint64_t>, kBins + 1> bins_{};
  std::atomic<uint64_t> count_{0};
  std::atomic<int64_t> sum_ns_{0};
  std::atomic<int64_t> max_ns_{0};
};

}  // namespace rheo::rt
