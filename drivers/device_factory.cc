#include "drivers/device_factory.h"

#include <fstream>
#include <sstream>

#include "drivers/libusb_transport.h"
#include "drivers/sh4_board.h"
#include "drivers/termios_transport.h"
#include "drivers/uart_motor_link.h"

namespace rheo::drivers {

Result<SpidarConfig> LoadSpidarConfigFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return NotFound("SPIDAR-G config " + path + ": cannot open");
  std::stringstream text;
  text << in.rdbuf();
  return ParseSpidarConfig(text.str(), path);
}

Result<std::unique_ptr<SpidarG>> OpenSpidarG(const SpidarConfig& config, const std::string& port,
                                             const SpidarOpenOptions& options) {
  std::unique_ptr<MotorLink> link;
  UartMotorLink* uart = nullptr;
  if (config.board.type == BoardType::kUart) {
    auto transport = TermiosTransport::Open(port);
    if (!transport.ok()) return transport.error();
    auto u = std::make_unique<UartMotorLink>(std::move(transport).value(), config.board.board_ids,
                                             options.reply_timeout_us);
    uart = u.get();
    link = std::move(u);
  } else {
    auto transport =
        LibusbTransport::Open(sh4::kVendorId, sh4::kProductId, sh4::kEndpointOut, sh4::kEndpointIn);
    if (!transport.ok()) return transport.error();
    link = std::make_unique<Sh4MotorLink>(std::move(transport).value(), config.board.button_mask,
                                          options.reply_timeout_us);
  }
  auto device = std::make_unique<SpidarG>(config, std::move(link));
  if (Status s = device->Open(); !s.ok()) return s.error();
  if (uart && options.reopen) {
    // A reopened line must carry the boards found now: another board (or another device on a
    // reused port name) would get commands meant for these motors.
    const std::vector<uart::BoardInfo> boards = uart->boards();
    auto reopen = [port, boards,
                   ids = config.board.board_ids]() -> Result<std::unique_ptr<ByteTransport>> {
      auto t = TermiosTransport::Open(port);
      if (!t.ok()) return t.error();
      auto found = IdentifyUartBoards(**t, ids, kSpidarStrings);
      if (!found.ok()) return found.error();
      for (size_t i = 0; i < boards.size(); ++i) {
        const uart::BoardInfo &a = boards[i], &b = (*found)[i];
        if (a.model != b.model || a.n_motor != b.n_motor || a.n_force != b.n_force)
          return Error{ErrorCode::kFailedPrecondition,
                       port + ": board " + std::to_string(b.board_id) + " now answers as model " +
                           std::to_string(b.model) + " with " + std::to_string(b.n_motor) +
                           " motors and " + std::to_string(b.n_force) +
                           " force inputs, not the model " + std::to_string(a.model) + " with " +
                           std::to_string(a.n_motor) + " and " + std::to_string(a.n_force) +
                           " it was opened with"};
      }
      return std::unique_ptr<ByteTransport>(std::move(t).value());
    };
    uart->SetLineSource(std::make_unique<LineReopener>(std::move(reopen), options.reopen_options));
  }
  return device;
}

}  // namespace rheo::drivers
