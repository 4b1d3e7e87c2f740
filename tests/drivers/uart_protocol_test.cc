#include "drivers/uart_protocol.h"

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "drivers/sh4_board.h"
#include "drivers/transport.h"
#include "drivers/uart_motor_link.h"

namespace rheo::drivers {
namespace {

using namespace uart;

TEST(UartProtocol, HeaderPacksCommandAndBoard) {
  EXPECT_EQ(Header(Command::kCurrent, 3), 0x33);  // (6 << 3) | 3
  EXPECT_EQ(Header(Command::kBoardInfo, 0), 0x08);
  EXPECT_EQ(Header(Command::kGetParameter, 7), 0x5F);
  for (int c = 0; c < 12; ++c) {
    for (int b = 0; b < 8; ++b) {
      uint8_t h = Header(static_cast<Command>(c), b);
      EXPECT_EQ(static_cast<int>(HeaderCommand(h)), c);
      EXPECT_EQ(HeaderBoard(h), b);
    }
  }
}

TEST(UartProtocol, EnumerationRequestIsZerosHeaderZeros) {
  std::array<uint8_t, kBoardInfoRequestSize> req;
  ASSERT_EQ(EncodeBoardInfoRequest(5, req), 67u);
  for (int i = 0; i < 67; ++i) EXPECT_EQ(req[i], i == 40 ? 0x0D : 0) << i;
}

TEST(UartProtocol, BoardInfoReply) {
  const uint8_t bytes[7] = {0x08, 7, 0, 8, 8, 4, 0};
  auto info = DecodeBoardInfoReply(bytes, 0);
  ASSERT_TRUE(info.ok()) << info.error().message;
  EXPECT_EQ(info->model, 7);
  EXPECT_EQ(info->n_motor, 8);
  EXPECT_EQ(info->n_force, 4);
  EXPECT_EQ(CurrentCommandSize(info->n_motor), 17u);
  EXPECT_EQ(CurrentReplySize(info->n_motor, info->n_force), 41u);
  std::array<uint8_t, 7> again;
  EncodeBoardInfoReply(*info, again);
  EXPECT_TRUE(std::equal(again.begin(), again.end(), bytes));
  EXPECT_FALSE(DecodeBoardInfoReply(bytes, 1).ok());  // header says board 0
  const uint8_t nine[7] = {0x08, 7, 0, 9, 8, 4, 0};
  EXPECT_NE(DecodeBoardInfoReply(nine, 0).error().message.find("9 motors"), std::string::npos);
  EXPECT_FALSE(DecodeBoardInfoReply(std::span(bytes, 6), 0).ok());
}

TEST(UartProtocol, CurrentCommandIsLittleEndianAndClamped) {
  const int16_t values[8] = {0x0123, -1, 4095, 5000, -5000, 0, 1, -4095};
  std::array<uint8_t, 17> out;
  ASSERT_EQ(EncodeCurrentCommand(2, values, out), 17u);
  const uint8_t expected[17] = {0x32, 0x23, 0x01, 0xFF, 0xFF, 0xFF, 0x0F, 0xFF, 0x0F,
                                0x01, 0xF0, 0x00, 0x00, 0x01, 0x00, 0x01, 0xF0};
  for (int i = 0; i < 17; ++i) EXPECT_EQ(out[i], expected[i]) << "byte " << i;
  std::array<int16_t, 8> back;
  ASSERT_TRUE(DecodeCurrentCommand(out, 8, back).ok());
  EXPECT_EQ(back[3], 4095);
  EXPECT_EQ(back[4], -4095);
  EXPECT_EQ(back[1], -1);
}

TEST(UartProtocol, CurrentReplyRoundTrip) {
  BoardInfo info{1, 7, 0, 8, 8, 4, 0};
  SensorReply r;
  for (int i = 0; i < 8; ++i) {
    r.position[i] = static_cast<int16_t>(i * 1000 - 32000);
    r.velocity[i] = static_cast<int16_t>(-i);
  }
  for (int i = 0; i < 4; ++i) r.force[i] = static_cast<int16_t>(100 + i);
  std::array<uint8_t, kMaxFrameSize> out;
  ASSERT_EQ(EncodeCurrentReply(1, info, r, out), 41u);
  EXPECT_EQ(out[0], 0x31);
  EXPECT_EQ(out[1], static_cast<uint8_t>(static_cast<uint16_t>(-32000) & 0xFF));
  SensorReply back;
  ASSERT_TRUE(DecodeCurrentReply(std::span(out.data(), 41), info, &back).ok());
  EXPECT_EQ(back.position, r.position);
  EXPECT_EQ(back.velocity, r.velocity);
  EXPECT_EQ(back.force, r.force);
  EXPECT_FALSE(DecodeCurrentReply(std::span(out.data(), 40), info, &back).ok());
  out[0] = 0x30;  // board 0's header
  EXPECT_FALSE(DecodeCurrentReply(std::span(out.data(), 41), info, &back).ok());
}

// A random walk far past +-32767: the unwrapped count equals the true count.
TEST(UartProtocol, CounterUnwrapsAcrossTheSixteenBitBoundary) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> step(-3000, 3500);
  CounterUnwrapper u;
  int64_t truth = 32000;
  EXPECT_EQ(u.Update(static_cast<uint16_t>(truth)), truth);
  int64_t lowest = truth, highest = truth;
  for (int k = 0; k < 20000; ++k) {
    truth += step(rng);
    lowest = std::min(lowest, truth);
    highest = std::max(highest, truth);
    ASSERT_EQ(u.Update(static_cast<uint16_t>(truth & 0xFFFF)), truth) << "step " << k;
  }
  EXPECT_GT(highest, 100000);  // the walk really crossed the boundary many times
}

TEST(Sh4Board, PacketLayout) {
  const int16_t da[8] = {1, -2, 300, 0, 0, 0, 0, 0x7FFF};
  std::array<uint8_t, sh4::kPacketSize> out;
  sh4::EncodeCommand(da, out);
  EXPECT_EQ(out[0], 0x01);
  EXPECT_EQ(out[1], 0x0E);
  EXPECT_EQ(out[2], 1);
  EXPECT_EQ(out[4], 0xFE);
  EXPECT_EQ(out[5], 0xFF);
  EXPECT_EQ(out[6], 300 & 0xFF);
  EXPECT_EQ(out[7], 300 >> 8);
  EXPECT_EQ(out[17], 0x7F);
  EXPECT_EQ(out[18], 0);
  std::array<uint8_t, sh4::kPacketSize> in{};
  in[16] = 0x34;
  in[17] = 0x12;
  in[32] = 7;
  in[48] = 0x53;  // switch 5, inputs 0b0011
  sh4::Sensors s;
  ASSERT_TRUE(sh4::DecodeSensors(in, &s).ok());
  EXPECT_EQ(s.counters[0], 0x1234);
  EXPECT_EQ(s.adc[0], 7);
  EXPECT_EQ(s.digital, 0x53);
  EXPECT_FALSE(sh4::DecodeSensors(std::span(in.data(), 40), &s).ok());
}

// Stands in for the USB board (none exists here): counters that wrap and count down.
class FakeSh4 final : public BulkTransport {
 public:
  std::array<int64_t, 8> lengthening{};  // true counts (string lengthening is positive)
  std::array<int16_t, 8> last_da{};
  uint16_t digital = 0;
  Result<size_t> Transfer(std::span<const uint8_t> out, std::span<uint8_t> in, int) override {
    if (out.size() != sh4::kPacketSize || out[0] != 0x01 || out[1] != 0x0E) {
      return Error{ErrorCode::kInternal, "bad OUT packet"};
    }
    for (int i = 0; i < 8; ++i) {
      last_da[i] = static_cast<int16_t>(out[2 + 2 * i] | (out[3 + 2 * i] << 8));
    }
    std::fill(in.begin(), in.end(), 0);
    for (int i = 0; i < 8; ++i) {
      const auto raw = static_cast<uint16_t>(-lengthening[i] & 0xFFFF);
      in[16 + 2 * i] = raw & 0xFF;
      in[17 + 2 * i] = raw >> 8;
    }
    in[48] = digital & 0xFF;
    in[49] = digital >> 8;
    return in.size();
  }
};

TEST(Sh4Board, LinkUnwrapsInvertsAndMasksButtons) {
  auto fake = std::make_unique<FakeSh4>();
  FakeSh4* board = fake.get();
  Sh4MotorLink link(std::move(fake), /*button_mask=*/0x0F);
  ASSERT_TRUE(link.Open(8).ok());
  EXPECT_FALSE(link.Open(7).ok());
  std::array<int16_t, 8> cmd{10, 20, 30, 40, 50, 60, 70, 80};
  std::array<int64_t, 8> counts{};
  uint32_t buttons = 0;
  board->digital = 0x35;  // switch 3, buttons 0 and 2
  for (int k = 0; k < 100; ++k) {
    for (int i = 0; i < 8; ++i) board->lengthening[i] += (i + 1) * 1500 * (i % 2 ? -1 : 1);
    ASSERT_TRUE(link.Exchange(cmd, counts, &buttons).ok());
  }
  for (int i = 0; i < 8; ++i) EXPECT_EQ(counts[i], board->lengthening[i]) << i;
  EXPECT_EQ(board->last_da, cmd);
  EXPECT_EQ(buttons, 0x5u);
  EXPECT_EQ(link.rotary_switch(), 3);
}

// A board that answers late answers every try it was sent. The first try's reply arrives only
// after the second try was written, so two replies come; the second must not stay on the line,
// where the first current exchange read it ("current reply header 8 is not board 0's").
class LateBoard : public ByteTransport {
 public:
  Status Write(std::span<const uint8_t> data, int) override {
    if (data.size() == kBoardInfoRequestSize) ++unanswered_;
    return Status::Ok();
  }
  Status ReadExact(std::span<uint8_t> data, int) override {
    if (reads_++ == 0 || unanswered_ == 0)
      return Error{ErrorCode::kDeadlineExceeded, "no reply within the window"};
    --unanswered_;
    BoardInfo info;
    info.model = 7;
    info.n_motor = 8;
    info.n_force = 4;
    EXPECT_EQ(data.size(), kBoardInfoReplySize);
    EncodeBoardInfoReply(info, data);
    return Status::Ok();
  }
  void DiscardInput() override {}  // nothing has arrived when it is called
  int unanswered() const { return unanswered_; }

 private:
  int reads_ = 0;
  int unanswered_ = 0;
};

TEST(UartMotorLink, ALateBoardsSecondReplyIsDroppedNotReadAsTheNextOne) {
  LateBoard line;
  auto boards = IdentifyUartBoards(line, {0}, 8);
  ASSERT_TRUE(boards.ok()) << boards.error().message;
  ASSERT_EQ(boards->size(), 1u);
  EXPECT_EQ((*boards)[0].n_motor, 8);
  EXPECT_EQ(line.unanswered(), 0) << "a board-info reply is left on the line";
}

// A board (or an emulated one on a busy machine) whose reply takes `delay_us`: it arrives within
// a try only if that try waits long enough. Records every window it was given.
class SlowBoard : public ByteTransport {
 public:
  explicit SlowBoard(int delay_us) : delay_us_(delay_us) {}
  Status Write(std::span<const uint8_t>, int) override { return Status::Ok(); }
  Status ReadExact(std::span<uint8_t> data, int timeout_us) override {
    windows_us.push_back(timeout_us);
    if (delay_us_ < 0 || timeout_us < delay_us_)
      return Error{ErrorCode::kDeadlineExceeded, "0 of 7 bytes within the window"};
    BoardInfo info;
    info.n_motor = 8;
    EncodeBoardInfoReply(info, data);
    return Status::Ok();
  }
  void DiscardInput() override {}
  std::vector<int> windows_us;

 private:
  int delay_us_;  // < 0: never answers
};

TEST(UartMotorLink, ABoardAnsweringAfter70MsIsFoundByALongerTry) {
  SlowBoard line(70'000);  // three 20 ms tries in a row missed it
  auto boards = IdentifyUartBoards(line, {0}, 8);
  ASSERT_TRUE(boards.ok()) << boards.error().message;
  EXPECT_EQ((*boards)[0].n_motor, 8);
  ASSERT_GE(line.windows_us.size(), 3u);
  EXPECT_EQ(line.windows_us[0], 20'000);
  EXPECT_EQ(line.windows_us[1], 40'000);
  EXPECT_EQ(line.windows_us[2], 80'000);
}

TEST(UartMotorLink, AnAbsentBoardIsDeclaredAbsentAfter300Ms) {
  SlowBoard line(-1);
  auto boards = IdentifyUartBoards(line, {0}, 8);
  ASSERT_FALSE(boards.ok());
  EXPECT_EQ(boards.error().code, ErrorCode::kUnavailable);
  EXPECT_NE(boards.error().message.find("board 0 did not answer board-info in 4 tries"),
            std::string::npos)
      << boards.error().message;
  int total = 0;
  for (int w : line.windows_us) total += w;
  EXPECT_EQ(total, 300'000);
}

}  // namespace
}  // namespace rheo::drivers
