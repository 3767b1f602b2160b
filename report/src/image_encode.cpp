#include "image_encode.hpp"

#include <jpeglib.h>
#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

namespace maglead::plot {

std::string encode_png(const BgrImage& img) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(img.width_px);
  image.height = static_cast<png_uint_32>(img.height_px);
  image.format = PNG_FORMAT_BGR;
  // 8-bit samples: the stride in components is the stride in bytes.
  const auto stride = static_cast<png_int_32>(img.row_stride_bytes);
  png_alloc_size_t size = 0;
  if (png_image_write_to_memory(&image, nullptr, &size, 0, img.pixels, stride, nullptr) != 0) {
    std::string out(size, '\0');
    if (png_image_write_to_memory(&image, out.data(), &size, 0, img.pixels, stride, nullptr) != 0) {
      out.resize(size);
      return out;
    }
  }
  const std::string why = image.message;
  png_image_free(&image);
  throw std::runtime_error("PNG encoding failed: " + why);
}

namespace {

// libjpeg reports an error by calling error_exit, which must not return: it jumps back to
// jpeg_into with the message (C frames in between: no exception may cross them).
struct JpegError {
  jpeg_error_mgr mgr;
  std::jmp_buf back;
  char message[JMSG_LENGTH_MAX];
};

void jpeg_error_exit(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<JpegError*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  std::longjmp(err->back, 1);
}

/// Compresses into a malloc'd buffer; false (and `err.message`) on an error. No C++ object with
/// a destructor lives here, so the long jump skips nothing.
bool jpeg_into(const BgrImage& img, int quality, JpegError& err, unsigned char** buf,
               unsigned long* size) {
  jpeg_compress_struct cinfo{};
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = jpeg_error_exit;
  if (setjmp(err.back) != 0) {
    jpeg_destroy_compress(&cinfo);
    return false;
  }
  jpeg_create_compress(&cinfo);
  jpeg_mem_dest(&cinfo, buf, size);
  cinfo.image_width = static_cast<JDIMENSION>(img.width_px);
  cinfo.image_height = static_cast<JDIMENSION>(img.height_px);
  cinfo.input_components = 3;
  cinfo.in_color_space = JCS_EXT_BGR;
  jpeg_set_defaults(&cinfo);
  jpeg_set_quality(&cinfo, quality, TRUE);
  jpeg_start_compress(&cinfo, TRUE);
  while (cinfo.next_scanline < cinfo.image_height) {
    // libjpeg's row pointer is not const; it only reads the row.
    JSAMPROW row = const_cast<JSAMPROW>(img.pixels + cinfo.next_scanline * img.row_stride_bytes);
    jpeg_write_scanlines(&cinfo, &row, 1);
  }
  jpeg_finish_compress(&cinfo);
  jpeg_destroy_compress(&cinfo);
  return true;
}

}  // namespace

std::string encode_jpeg(const BgrImage& img, int quality) {
  JpegError err{};
  unsigned char* buf = nullptr;
  unsigned long size = 0;
  const bool ok = jpeg_into(img, quality, err, &buf, &size);
  std::string out;
  if (ok) out.assign(reinterpret_cast<const char*>(buf), size);
  std::free(buf);
  if (!ok) throw std::runtime_error(std::string("JPEG encoding failed: ") + err.message);
  return out;
}

}  // namespace maglead::plot
