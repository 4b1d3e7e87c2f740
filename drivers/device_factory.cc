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
  if (config.board.type == BoardType::kUart) {
    auto transport = TermiosTransport::Open(port);
    if (!transport.ok()) return transport.error();
    link = std::make_unique<UartMotorLink>(std::move(transport).value(), config.board.board_ids,
                                           options.reply_timeout_us);
  } else {
    auto transport =
        LibusbTransport::Open(sh4::kVendorId, sh4::kProductId, sh4::kEndpointOut, sh4::kEndpointIn);
    if (!transport.ok()) return transport.error();
    link = std::make_unique<Sh4MotorLink>(std::move(transport).value(), config.board.button_mask,
                                          options.reply_timeout_us);
  }
  auto device = std::make_unique<SpidarG>(config, std::move(link));
  if (Status s = device->Open(); !s.ok()) return s.error();
  return device;
}

}  // namespace rheo::drivers
