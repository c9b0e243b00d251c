#pragma once
/// \file unwrapper.hpp
/// Omni donut -> W x H cylindrical panorama through a bilinear lookup table built once
/// from the calibration (DESIGN.md section 6), with several samples per pixel where the omni
/// image is at least twice as dense as the panorama (samplesAlong()). Frames that already
/// are panoramas (`input: panorama`) pass through the same entry point and are only converted.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/error.hpp"

namespace omnipose {

/// What the frames given to the pipeline are.
enum class InputKind { kOmni, kPanorama };

/// The size of the frames the pipeline takes: the omni image (omni.image_width x
/// image_height) or, for `input: panorama`, the panorama (panorama.width x height).
cv::Size inputFrameSize(const Calibration& calibration, InputKind input);

class Unwrapper {
 public:
  struct Options {
    InputKind input = InputKind::kOmni;
    /// A frame whose mean grey level is below this is rejected as black (lens cap,
    /// exposure failure). Grey levels 0..255.
    double min_mean_intensity = 2.0;
    /// Every problem, one message per bad field, each starting with the field's name;
    /// empty when valid.
    std::vector<std::string> validate() const;
  };

  /// Builds the lookup table (allocates). Throws std::invalid_argument listing every problem
  /// of the options and the calibration.
  Unwrapper(const Calibration& calibration, const Options& options);

  /// Expected frame size: the omni image size or the panorama size, by input kind.
  cv::Size inputSize() const;
  /// Panorama size W x H.
  cv::Size panoramaSize() const;

  /// Unwraps `frame` (CV_8UC1, CV_8UC3 BGR or CV_8UC4 BGRA, inputSize()) into `panorama`
  /// (CV_32FC1, W x H, grey levels 0..255). `panorama` must already have that size and
  /// type (allocate it once with makePanorama()); it is then written in place without
  /// allocation. Errors (kBadFrame): wrong size or type, all-black frame.
  Expected<void> unwrap(const cv::Mat& frame, cv::Mat& panorama);

  /// unwrap() in two steps, so that the rows can be shared between threads (the pipeline
  /// runs them on its worker pool); the result is the same.
  /// toGrey() checks `frame` (the errors of unwrap()) and converts it to 8-bit grey. It
  /// returns the image that unwrapRows() reads: `frame` itself or a buffer of this
  /// unwrapper, valid until the next toGrey() or unwrap(). No allocation.
  Expected<const cv::Mat*> toGrey(const cv::Mat& frame);
  /// Writes panorama rows [first, last) from `grey` (the pointer toGrey() returned).
  /// `panorama`: CV_32FC1, panoramaSize() (not checked here: unwrap() checks it). Safe to
  /// call concurrently on disjoint row ranges.
  void unwrapRows(const cv::Mat& grey, cv::Mat& panorama, int first, int last) const;

  /// A panorama buffer of the right size and type.
  cv::Mat makePanorama() const;

  /// Which panorama pixels carry the scene (CV_32FC1, W x H, 1 = usable, 0 = not): 0 where
  /// the pixel's bilinear footprint touches a masked omni pixel (calibration omni.mask),
  /// leaves the frame, or has no bearing in the lens model. All 1 for panorama input.
  /// Built once by the constructor; static for the life of the unwrapper.
  const cv::Mat& validity() const { return validity_; }
  /// Mean of validity(): the fraction of the panorama that is usable, in [0, 1].
  double usableFraction() const;

  /// Most samples per panorama pixel along each axis.
  static constexpr int kMaxSamplesPerAxis = 4;
  /// Samples per panorama pixel along an axis on which neighbouring panorama pixels are
  /// `density` omni pixels apart: floor(density) in [1, kMaxSamplesPerAxis]. Where the omni
  /// image is at least twice as dense as the panorama (a phone's full-resolution frame
  /// under a mirror) a pixel is the mean of a regular grid of bilinear samples over its
  /// footprint, a box filter: one sample there would alias the fine texture the panorama
  /// cannot hold into shifts that depend on where the texture falls.
  static int samplesAlong(double density);

 private:
  void buildTable(const Calibration& calibration);

  Calibration calibration_;
  Options options_;
  /// The lookup table. Row v of the panorama takes row_samples_u_[v] x row_samples_v_[v]
  /// samples per pixel (samplesAlong() of the row's largest spacing); its entries start at
  /// row_start_[v], sample k of pixel u at row_start_[v] + k * W + u. Per entry: index of the
  /// top-left source pixel (kOutside: a sample of the pixel leaves the image or the lens
  /// model; every sample of that pixel is kOutside and the pixel is black) and the position
  /// within the 2 x 2 bilinear footprint, in [0, 1).
  static constexpr int kOutside = -1;
  std::vector<std::size_t> row_start_;
  std::vector<int> row_samples_u_, row_samples_v_;
  std::vector<int> offset_;
  std::vector<float> frac_x_, frac_y_;
  cv::Mat grey_;  ///< colour frames are converted here (allocated once)
  cv::Mat validity_;
};

}  // namespace omnipose
