#pragma once
/// \file test_images.hpp
/// Real-texture panoramas for the registration tests, made from the equirectangular photos
/// in shared/data/equirect (an equirectangular image is periodic in u, like a panorama).
/// Every generator is exact up to float rounding: sub-pixel shifts by the Fourier shift
/// theorem, rotations/scales by warping a 4x supersampled image and box-averaging it down,
/// so the measured errors are the registration's own.

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

namespace omnipose::test {

inline constexpr const char* kIndoor = "indoor_1024x512.jpg";
inline constexpr const char* kPark = "park_theta_v_5376x2688.jpg";

/// Path of a shared equirect photo, or "" when it is not there. Looks only in
/// $OMNIPOSE_EQUIRECT_DIR when that is set; else in tests/data/equirect,
/// ../shared/data/equirect beside the source tree, then /work/shared/data/equirect.
inline std::string equirectPath(const std::string& name) {
  std::vector<std::filesystem::path> dirs;
  if (const char* env = std::getenv("OMNIPOSE_EQUIRECT_DIR")) {
    dirs.emplace_back(env);
  } else {
    dirs.emplace_back(std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests" / "data" / "equirect");
    dirs.emplace_back(std::filesystem::path(OMNIPOSE_SOURCE_DIR) / ".." / "shared" / "data" / "equirect");
    dirs.emplace_back("/work/shared/data/equirect");
  }
  for (const auto& dir : dirs)
    if (std::filesystem::exists(dir / name)) return (dir / name).string();
  return {};
}

/// The photo as grey levels 0..255 (CV_32FC1), box-resized to `width` x width/2 (square
/// pixels, 360 degrees across). Empty when the file is missing.
inline cv::Mat loadEquirect(const std::string& name, int width) {
  const std::string path = equirectPath(name);
  if (path.empty()) return {};
  cv::Mat grey = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (grey.empty()) return {};
  cv::Mat resized, out;
  cv::resize(grey, resized, cv::Size(width, width / 2), 0, 0, cv::INTER_AREA);
  resized.convertTo(out, CV_32F);
  return out;
}

/// Rows [centre - rows/2, centre - rows/2 + rows) of `image` (a copy); empty for an empty image.
inline cv::Mat rowBand(const cv::Mat& image, int centre, int rows) {
  if (image.empty()) return {};
  return image.rowRange(centre - rows / 2, centre - rows / 2 + rows).clone();
}

/// Band of `rows` rows about row `centre` of a periodic-in-u equirect, shifted so that
/// content at (u, v) of the unshifted band appears at (u + du, v + dv): Fourier shift
/// theorem, periodic in u, and mirror-extended in v (continuous, so no ringing reaches
/// the band through the margin).
inline cv::Mat fourierShiftedBand(const cv::Mat& equirect, int centre, int rows, double du,
                                  double dv) {
  const int margin = std::min(64, std::min(centre - rows / 2, equirect.rows - centre - rows + rows / 2));
  const cv::Mat tall = rowBand(equirect, centre, rows + 2 * margin);
  cv::Mat flipped, periodic;
  cv::flip(tall, flipped, 0);
  cv::vconcat(tall, flipped, periodic);
  cv::Mat spectrum;
  cv::dft(periodic, spectrum, cv::DFT_COMPLEX_OUTPUT);
  const int h = spectrum.rows, w = spectrum.cols;
  for (int r = 0; r < h; ++r) {
    const int kv = r <= h / 2 ? r : r - h;
    auto* row = spectrum.ptr<cv::Vec2f>(r);
    for (int c = 0; c < w; ++c) {
      const int ku = c <= w / 2 ? c : c - w;
      // F'(k) = F(k) exp(-i 2 pi (ku du / w + kv dv / h)).
      const double phase = -2.0 * std::numbers::pi * (ku * du / w + kv * dv / h);
      const double re = row[c][0], im = row[c][1];
      const double cs = std::cos(phase), sn = std::sin(phase);
      row[c] = cv::Vec2f(static_cast<float>(re * cs - im * sn), static_cast<float>(re * sn + im * cs));
    }
  }
  // Real part of the inverse (the Nyquist terms become cos(pi d), as for any real shift).
  cv::Mat shifted, planes[2];
  cv::dft(spectrum, shifted, cv::DFT_INVERSE | cv::DFT_SCALE | cv::DFT_COMPLEX_OUTPUT);
  cv::split(shifted, planes);
  return planes[0].rowRange(margin, margin + rows).clone();
}

/// Supersampled source for rotation/scale tests: the photo at `factor` x the panorama width.
struct Supersampled {
  cv::Mat image;  ///< CV_32FC1, factor * W x factor * W / 2
  int factor = 4;
  int band_rows = 0;  ///< panorama height H
  int band_top = 0;   ///< first equirect row (at panorama scale) of the panorama band

  /// The panorama band (W x H) box-averaged from the supersampled image.
  cv::Mat panorama() const {
    return downsample(image.rowRange(band_top * factor, (band_top + band_rows) * factor));
  }
  cv::Mat downsample(const cv::Mat& hi) const {
    cv::Mat lo;
    cv::resize(hi, lo, cv::Size(hi.cols / factor, hi.rows / factor), 0, 0, cv::INTER_AREA);
    return lo;
  }
  /// The L x L block of the current panorama whose top-left panorama pixel is (u0, 0),
  /// where the current content at panorama point x appears in the reference at
  /// c + s R (x - c), R = [[cos phi, sin phi], [-sin phi, cos phi]] (cv::getRotationMatrix2D
  /// about the panorama point c). Made by warping the supersampled image, then box-averaging.
  cv::Mat warpedBlock(int u0, int length, cv::Point2d c, double phi, double s) const {
    // Panorama point x <-> supersampled point X = f x + (f - 1) / 2 (box centres).
    const double f = factor, off = 0.5 * (factor - 1);
    const cv::Point2d C(f * c.x + off, f * (c.y + band_top) + off);
    cv::Mat m = cv::getRotationMatrix2D(C, phi * 180.0 / std::numbers::pi, s);
    // Block pixel X_b = X - O; current(X) = reference(M X), so current_b(X_b) = ref(M (X_b + O)).
    const cv::Point2d origin(f * u0, f * band_top);
    m.at<double>(0, 2) += m.at<double>(0, 0) * origin.x + m.at<double>(0, 1) * origin.y;
    m.at<double>(1, 2) += m.at<double>(1, 0) * origin.x + m.at<double>(1, 1) * origin.y;
    cv::Mat hi;
    cv::warpAffine(image, hi, m, cv::Size(factor * length, factor * length),
                   cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_WRAP);
    return downsample(hi);
  }
};

/// The photo at 4x the panorama width (`width`), the panorama band centred on the horizon.
inline Supersampled loadSupersampled(const std::string& name, int width, int rows) {
  Supersampled s;
  s.image = loadEquirect(name, s.factor * width);
  s.band_rows = rows;
  s.band_top = width / 4 - rows / 2;
  return s;
}

/// Copies the block into columns u0 .. u0 + block.cols - 1 (wrapping) of `panorama`.
inline void pasteWrapped(const cv::Mat& block, int u0, cv::Mat& panorama) {
  for (int j = 0; j < block.cols; ++j)
    block.col(j).copyTo(panorama.col((u0 + j) % panorama.cols));
}

}  // namespace omnipose::test
