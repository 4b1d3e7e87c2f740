// The writer's steady state allocates nothing per message: once its chunk and compression
// buffers have grown, a Write that stays inside the chunk makes no heap allocation, and closing a
// chunk only grows the summary's lists now and then (amortised doubling).
#include <gtest/gtest.h>

#include "alloc_counter.h"
#include "record/mcap.h"

namespace rheo::record {
namespace {

using rheo::testing::AllocationCounter;

/// Counts bytes and drops them, so the sink itself never allocates.
class NullSink final : public ByteSink {
 public:
  Status Write(std::span<const uint8_t> b) override {
    bytes_ += b.size();
    return Status::Ok();
  }
  Status Flush() override { return Status::Ok(); }

 private:
  uint64_t bytes_ = 0;
};

class SteadyState : public ::testing::TestWithParam<Compression> {};

TEST_P(SteadyState, WritesAllocateOnlyWhenTheSummaryListsGrow) {
  NullSink sink;
  McapWriter w;
  WriterOptions options;
  options.compression = GetParam();
  options.chunk_size = 256 * 1024;
  ASSERT_TRUE(w.Open(sink, "", "alloc test", options).ok());
  auto pose = w.AddChannel(0, "/tool/sample", "json");
  auto frame = w.AddChannel(0, "/studio/frame", "json");
  ASSERT_TRUE(pose.ok() && frame.ok());
  std::vector<uint8_t> small(200), large(100 * 1024);
  for (size_t i = 0; i < large.size(); ++i) large[i] = uint8_t((i * 7) ^ (i >> 5));

  long in_chunk = 0, at_close = 0;
  uint32_t closes = 0;
  auto second = [&](int s, bool count) {
    for (int i = 0; i < 1000; ++i) {
      const uint64_t t = uint64_t(s) * 1'000'000'000 + uint64_t(i) * 1'000'000;
      for (int k = 0; k < 2; ++k) {
        if (k == 1 && (i * 60) / 1000 == ((i + 1) * 60) / 1000) continue;  // frames at 60 Hz
        const uint32_t chunks = w.chunk_count();
        AllocationCounter guard;
        const Status st = k == 0 ? w.Write(*pose, i, t, t, small) : w.Write(*frame, i, t, t, large);
        const long n = guard.count();
        ASSERT_TRUE(st.ok());
        if (!count) continue;
        if (w.chunk_count() == chunks) {
          in_chunk += n;
        } else {
          at_close += n;
          ++closes;
        }
      }
    }
  };
  {
    AllocationCounter probe;  // the counter sees this binary's allocations
    std::vector<int>* volatile v = new std::vector<int>(100);
    delete v;
    ASSERT_EQ(probe.count(), 2);
  }
  second(0, false);  // buffers grow to their working size
  for (int s = 1; s <= 10; ++s) second(s, true);
  EXPECT_EQ(in_chunk, 0);
  EXPECT_GT(closes, 20u);
  EXPECT_LE(at_close, 16) << "over " << closes << " chunk closes";
  RecordProperty("allocations_at_chunk_close", static_cast<int>(at_close));
  RecordProperty("chunk_closes", static_cast<int>(closes));
  ASSERT_TRUE(w.Close().ok());
}

INSTANTIATE_TEST_SUITE_P(Compressions, SteadyState,
                         ::testing::Values(Compression::kNone, Compression::kZstd,
                                           Compression::kLz4),
                         [](const auto& info) {
                           const std::string_view n = CompressionName(info.param);
                           return n.empty() ? std::string("none") : std::string(n);
                         });

}  // namespace
}  // namespace rheo::record
