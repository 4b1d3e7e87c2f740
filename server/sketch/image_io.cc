// PNG (libpng simplified API) and JPEG (libjpeg-turbo) decoding into grey, with size limits
// checked from the header before the pixel buffer exists.
// clang-format off
#include <cstddef>
#include <cstdio>  // jpeglib.h needs size_t and FILE first
#include <jpeglib.h>
// clang-format on
#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <memory>

#include "sketch/raster.h"

namespace rheo::sketch::internal {
namespace {

std::string SizeText(int64_t w, int64_t h) {
  return std::to_string(w) + " x " + std::to_string(h) + " = " + std::to_string(w * h) + " pixels";
}

Status CheckInput(std::span<const uint8_t> bytes, const ContourOptions& o, const char* what) {
  if (static_cast<int64_t>(bytes.size()) > o.max_input_bytes) {
    return ResourceExhausted(std::string("the ") + what + " file is " +
                             std::to_string(bytes.size()) + " bytes, over the limit of " +
                             std::to_string(o.max_input_bytes) + " (max_input_bytes)");
  }
  return Status::Ok();
}

Status CheckSize(int64_t w, int64_t h, const ContourOptions& o, const char* what) {
  if (w <= 0 || h <= 0) return InvalidArgument(std::string("the ") + what + " has no pixels");
  if (w * h > o.max_pixels) {
    return ResourceExhausted(std::string("the ") + what + " is " + SizeText(w, h) +
                             ", over the limit of " + std::to_string(o.max_pixels) +
                             " pixels (max_pixels)");
  }
  return Status::Ok();
}

struct JpegErr {
  jpeg_error_mgr pub;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

void JpegErrorExit(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<JpegErr*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->jump, 1);
}
void JpegSilence(j_common_ptr, int) {}

constexpr int kMaxJpegScans = 500;  // progressive files with more scans are hostile

void JpegProgress(j_common_ptr cinfo) {
  if (cinfo->is_decompressor) {
    auto* d = reinterpret_cast<j_decompress_ptr>(cinfo);
    if (d->input_scan_number > kMaxJpegScans) {
      auto* err = reinterpret_cast<JpegErr*>(cinfo->err);
      std::snprintf(err->message, sizeof err->message, "more than %d progressive scans",
                    kMaxJpegScans);
      std::longjmp(err->jump, 2);
    }
  }
}

// Everything the JPEG decoder touches lives here, on the heap, so longjmp leaves no C++ state
// half-updated in the frame that called setjmp.
struct JpegJob {
  jpeg_decompress_struct cinfo;
  JpegErr err;
  jpeg_progress_mgr progress;
  std::vector<uint8_t> pixels;
  int width = 0, height = 0;
  bool created = false;
};

// Returns 0 ok, 1 decode error (message in job->err), 3 over the size limit.
int RunJpeg(JpegJob* job, const uint8_t* data, size_t size, int64_t max_pixels) {
  job->cinfo.err = jpeg_std_error(&job->err.pub);
  job->err.pub.error_exit = JpegErrorExit;
  job->err.pub.emit_message = JpegSilence;
  job->err.message[0] = 0;
  if (setjmp(job->err.jump)) return 1;
  jpeg_create_decompress(&job->cinfo);
  job->created = true;
  job->progress.progress_monitor = JpegProgress;
  job->cinfo.progress = &job->progress;
  job->cinfo.mem->max_memory_to_use = 512L * 1024 * 1024;
  jpeg_mem_src(&job->cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&job->cinfo, TRUE);
  job->width = static_cast<int>(job->cinfo.image_width);
  job->height = static_cast<int>(job->cinfo.image_height);
  if (int64_t(job->width) * job->height > max_pixels || job->width <= 0 || job->height <= 0) {
    return 3;
  }
  job->cinfo.out_color_space = JCS_GRAYSCALE;
  jpeg_start_decompress(&job->cinfo);
  if (job->cinfo.output_components != 1) {
    std::snprintf(job->err.message, sizeof job->err.message, "cannot convert to grey");
    return 1;
  }
  job->pixels.assign(size_t(job->width) * job->height, 255);
  while (job->cinfo.output_scanline < job->cinfo.output_height) {
    JSAMPROW row = job->pixels.data() + size_t(job->cinfo.output_scanline) * job->width;
    if (jpeg_read_scanlines(&job->cinfo, &row, 1) != 1) {
      std::snprintf(job->err.message, sizeof job->err.message, "truncated at row %u",
                    job->cinfo.output_scanline);
      return 1;
    }
  }
  jpeg_finish_decompress(&job->cinfo);
  return 0;
}

}  // namespace

bool LooksLikePng(std::span<const uint8_t> b) {
  static const uint8_t kSig[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  return b.size() >= 8 && std::memcmp(b.data(), kSig, 8) == 0;
}

bool LooksLikeJpeg(std::span<const uint8_t> b) {
  return b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF;
}

Result<GrayImage> DecodePng(std::span<const uint8_t> bytes, const ContourOptions& o) {
  if (Status s = CheckInput(bytes, o, "PNG"); !s) return s.error();
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, bytes.data(), bytes.size())) {
    std::string m = image.message;
    png_image_free(&image);
    return InvalidArgument("corrupt PNG: " + m);
  }
  if (Status s = CheckSize(image.width, image.height, o, "PNG picture"); !s) {
    png_image_free(&image);
    return s.error();
  }
  image.format = PNG_FORMAT_GRAY;
  GrayImage out;
  out.width = static_cast<int>(image.width);
  out.height = static_cast<int>(image.height);
  out.pixels.assign(size_t(out.width) * out.height, 255);
  png_color white{255, 255, 255};
  if (!png_image_finish_read(&image, &white, out.pixels.data(), out.width, nullptr)) {
    std::string m = image.message;
    png_image_free(&image);
    return InvalidArgument("corrupt PNG: " + m);
  }
  png_image_free(&image);
  return out;
}

Result<GrayImage> DecodeJpeg(std::span<const uint8_t> bytes, const ContourOptions& o) {
  if (Status s = CheckInput(bytes, o, "JPEG"); !s) return s.error();
  auto job = std::make_unique<JpegJob>();
  const int rc = RunJpeg(job.get(), bytes.data(), bytes.size(), o.max_pixels);
  if (job->created) jpeg_destroy_decompress(&job->cinfo);
  if (rc == 3) {
    if (Status s = CheckSize(job->width, job->height, o, "JPEG picture"); !s) return s.error();
  }
  if (rc != 0) return InvalidArgument(std::string("corrupt JPEG: ") + job->err.message);
  GrayImage out;
  out.width = job->width;
  out.height = job->height;
  out.pixels = std::move(job->pixels);
  return out;
}

}  // namespace rheo::sketch::internal
