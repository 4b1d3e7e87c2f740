#include "rt/histogram.h"

#include <algorithm>
#include <cmath>

namespace rheo::rt {

int64_t Histogram::Quantile(double q) const {
  uint64_t total = 0;
  for (const auto& b : bins_) total += b.load(std::memory_order_relaxed);
  if (total == 0) return 0;
  q = std::clamp(q, 0.0, 1.0);
  uint64_t rank = static_cast<uint64_t>(std::ceil(q * static_cast<double>(total)));
  if (rank == 0) rank = 1;
  uint64_t seen = 0;
  for (int i = 0; i <= kBins; ++i) {
    seen += bins_[i].load(std::memory_order_relaxed);
    if (seen >= rank) {
      if (i == kBins || seen == total) return max_ns();
      return std::min<int64_t>(static_cast<int64_t>(i) * 1000 + 500, max_ns());
    }
  }
  return max_ns();
}

void Histogram::Reset() {
  for (auto& b : bins_) b.store(0, std::memory_order_relaxed);
  count_.store(0, std::memory_order_relaxed);
  sum_ns_.store(0, std::memory_order_relaxed);
  max_ns_.store(0, std::memory_order_relaxed);
}

}  // namespace rheo::rt
