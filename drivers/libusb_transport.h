// BulkTransport over libusb (the SH4 board). The device ids and endpoints come from
// sh4_board.h, where the unverified protocol is kept.
#pragma once

#include <cstdint>
#include <memory>

#include "drivers/transport.h"

struct libusb_context;
struct libusb_device_handle;

namespace rheo::drivers {

class LibusbTransport final : public BulkTransport {
 public:
  /// Opens the first device with vendor:product, claims `interface`, uses the two endpoints.
  static Result<std::unique_ptr<LibusbTransport>> Open(uint16_t vendor, uint16_t product,
                                                       uint8_t endpoint_out, uint8_t endpoint_in,
                                                       int interface = 0);
  ~LibusbTransport() override;
  Result<size_t> Transfer(std::span<const uint8_t> out, std::span<uint8_t> in,
                          int timeout_us) override;

 private:
  LibusbTransport() = default;
  libusb_context* context_ = nullptr;
  libusb_device_handle* handle_ = nullptr;
  uint8_t out_ = 0, in_ = 0;
  int interface_ = 0;
};

}  // namespace rheo::drivers
