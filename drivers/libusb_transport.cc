#include "drivers/libusb_transport.h"

#include <libusb.h>

#include <cstdio>
#include <string>
#include <vector>

namespace rheo::drivers {
namespace {

std::string Hex4(uint16_t v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04x", v);
  return buf;
}

}  // namespace

Result<std::unique_ptr<LibusbTransport>> LibusbTransport::Open(uint16_t vendor, uint16_t product,
                                                               uint8_t endpoint_out,
                                                               uint8_t endpoint_in, int interface) {
  std::unique_ptr<LibusbTransport> t(new LibusbTransport());
  const std::string id = Hex4(vendor) + ":" + Hex4(product);
  if (int r = libusb_init(&t->context_); r != 0) {
    t->context_ = nullptr;
    return Error{ErrorCode::kUnavailable,
                 std::string("USB: libusb_init failed: ") + libusb_error_name(r)};
  }
  t->handle_ = libusb_open_device_with_vid_pid(t->context_, vendor, product);
  if (t->handle_ == nullptr) {
    return Error{ErrorCode::kUnavailable,
                 "USB device " + id + " not found (plugged in? permission via a udev rule?)"};
  }
  libusb_set_auto_detach_kernel_driver(t->handle_, 1);
  if (int r = libusb_claim_interface(t->handle_, interface); r != 0) {
    libusb_close(t->handle_);
    t->handle_ = nullptr;
    return Error{ErrorCode::kUnavailable, "USB device " + id + ": cannot claim interface " +
                                              std::to_string(interface) + ": " +
                                              libusb_error_name(r)};
  }
  t->out_ = endpoint_out;
  t->in_ = endpoint_in;
  t->interface_ = interface;
  return t;
}

LibusbTransport::~LibusbTransport() {
  if (handle_ != nullptr) {
    libusb_release_interface(handle_, interface_);
    libusb_close(handle_);
  }
  if (context_ != nullptr) libusb_exit(context_);
}

Result<size_t> LibusbTransport::Transfer(std::span<const uint8_t> out, std::span<uint8_t> in,
                                         int timeout_us) {
  const unsigned timeout_ms = static_cast<unsigned>((timeout_us + 999) / 1000);
  int sent = 0;
  // libusb takes a non-const buffer for both directions; OUT transfers do not write to it.
  int r = libusb_bulk_transfer(handle_, out_, const_cast<uint8_t*>(out.data()),
                               static_cast<int>(out.size()), &sent, timeout_ms);
  if (r != 0 || sent != static_cast<int>(out.size())) {
    return Error{ErrorCode::kUnavailable,
                 std::string("USB bulk OUT failed: ") + libusb_error_name(r)};
  }
  int got = 0;
  r = libusb_bulk_transfer(handle_, in_, in.data(), static_cast<int>(in.size()), &got, timeout_ms);
  if (r != 0) {
    return Error{ErrorCode::kUnavailable,
                 std::string("USB bulk IN failed: ") + libusb_error_name(r)};
  }
  return static_cast<size_t>(got);
}

}  // namespace rheo::drivers
