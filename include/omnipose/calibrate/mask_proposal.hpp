#pragma once
/// \file mask_proposal.hpp
/// `omnipose-calibrate --propose-mask`: finds what the camera sees of the robot itself (mast,
/// body, cables, lens bezel) as the textured pixels that stay still while the rest of the
/// ring moves, over a short sequence in which the robot turns or drives.

#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

namespace omnipose::calibrate {

struct MaskProposalOptions {
  /// Side of the square patch about each pixel over which change and texture are pooled.
  int pool_px = 9;
  /// A patch is decidable when its texture variance is this many times the noise variance.
  double min_texture_snr = 2.0;
  /// A decidable patch is still when its mean squared frame-to-frame change is below
  /// static_noise x the noise's (2 s^2) plus static_fraction x its texture variance (about
  /// a third of a pixel of motion for smooth texture).
  double static_noise = 1.5;
  double static_fraction = 0.1;
  /// Masked regions are closed (pool_px) and then grown by this much (pixels).
  int grow_px = 3;
  /// The scene must have moved: at least this fraction of the textured pixels must not be
  /// static, else the frames are refused (nothing could be told apart).
  double min_moving_fraction = 0.3;
};

struct MaskProposal {
  cv::Mat mask;                 ///< CV_8UC1, frame size: 0 = never use, 255 = use
  double masked_fraction = 0;   ///< of the frame
  double moving_fraction = 0;   ///< of the textured pixels, those that moved
  std::vector<std::string> notes;
};

/// Proposes the mask from at least 3 frames of one size (grey or colour, 8 bit). Throws
/// std::runtime_error naming the problem: too few frames, sizes differ, no texture, or a
/// scene that did not move (then nothing can be told apart: record a short turn).
MaskProposal proposeMask(std::span<const cv::Mat> frames, const MaskProposalOptions& options = {});

/// The mean frame with the masked pixels tinted red (CV_8UC3), for a look by eye.
cv::Mat renderMaskPreview(std::span<const cv::Mat> frames, const cv::Mat& mask);

}  // namespace omnipose::calibrate
