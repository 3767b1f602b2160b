#pragma once
// A figure's pixels as the bytes of a PNG or JPEG file. libpng and libjpeg-turbo, not OpenCV's
// imgcodecs: imgcodecs brings GDAL, poppler, HDF5 and some 120 more shared libraries into every
// maglead process (0.17 s to start one), for two encoders.
#include <cstddef>
#include <string>

namespace maglead::plot {

/// 8-bit BGR pixels, rows `row_stride_bytes` apart (OpenCV's CV_8UC3 layout).
struct BgrImage {
  const unsigned char* pixels = nullptr;
  int width_px = 0;
  int height_px = 0;
  std::size_t row_stride_bytes = 0;
};

/// PNG (lossless). Throws std::runtime_error with libpng's message.
std::string encode_png(const BgrImage& img);

/// JPEG at quality `quality` (1..100). Throws std::runtime_error with libjpeg's message.
std::string encode_jpeg(const BgrImage& img, int quality);

}  // namespace maglead::plot
