// The allocation counter itself: it must see allocations, so that a test reading 0 means it.
#include "alloc_counter.h"

#include <gtest/gtest.h>

#include <memory>
#include <thread>
#include <vector>

namespace rheo::testing {
namespace {

// Keeps the compiler from eliding a new/delete pair it can see both ends of.
template <typename T>
void Escape(T* p) {
  asm volatile("" : : "g"(p) : "memory");
}

TEST(AllocationCounter, SeesEveryFormOfNew) {
  AllocationCounter c;
  auto* v = new std::vector<int>(100);
  Escape(v);
  Escape(v->data());
  delete v;
  EXPECT_EQ(c.count(), 2);
  auto* a = new int[7];
  Escape(a);
  delete[] a;
  struct alignas(64) Wide {
    double x[8];
  };
  auto* w = new Wide;
  Escape(w);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(w) % 64, 0u);
  delete w;
  auto* n = new (std::nothrow) int(3);
  Escape(n);
  delete n;
  EXPECT_EQ(c.count(), 5);
}

TEST(AllocationCounter, OtherThreadsDoNotCount) {
  AllocationCounter c;
  std::thread t([] {
    for (int i = 0; i < 100; ++i) {
      auto p = std::make_unique<int>(i);
      Escape(p.get());
    }
  });
  t.join();
  // std::thread allocates its state on this thread; the 100 in the other thread do not count.
  EXPECT_LT(c.count(), 10);
}

}  // namespace
}  // namespace rheo::testing
