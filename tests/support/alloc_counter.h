// Heap-allocation counting for tests of real-time paths ("the 1 kHz loop never allocates").
// A binary linked with rheo_test_alloc has the global operator new/delete replaced by versions
// that count, per thread, every allocation made through them.
#pragma once

namespace rheo::testing {

/// Allocations made by the calling thread since it started. Other threads (an emulator, a
/// logger) do not disturb the count.
long ThreadAllocations();

/// Counts the calling thread's allocations made while it is alive.
class AllocationCounter {
 public:
  AllocationCounter() : start_(ThreadAllocations()) {}
  long count() const { return ThreadAllocations() - start_; }

 private:
  long start_;
};

}  // namespace rheo::testing
