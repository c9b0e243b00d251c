#pragma once
/// \file equirect.hpp (private)
/// The equirectangular texture as a mip pyramid with trilinear lookup by direction.
/// Convention (synth.hpp): x = W * (0.5 - lon / (2 pi)) - 0.5, y = H * (0.5 - lat / pi) - 0.5.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

namespace omnipose::synth::detail {

/// Mip levels of a CV_32FC1 equirect texture, level 0 = the texture itself. Level k+1
/// is level k filtered by the binomial [1 3 3 1] / 8 in each direction and decimated by 2:
/// texel i of level k+1 is centred between texels 2i and 2i+1 of level k, exactly where
/// the fractional coordinates of sampleEquirect() put it, so no level shifts content.
/// Columns wrap around (longitude is periodic), rows are clamped at the poles. Building
/// stops when a dimension becomes odd or smaller than 4.
std::vector<cv::Mat> buildPyramid(const cv::Mat& texture);

/// Texel spacing of level 0 in latitude, radians (pi / rows).
double texelAngle(const std::vector<cv::Mat>& pyramid);

/// Texture value seen along direction d (any length > 0), bilinear within a level and
/// linear between levels floor(lod) and floor(lod) + 1 (lod in levels, clamped to the
/// pyramid). Grey levels.
float sampleEquirect(const std::vector<cv::Mat>& pyramid, const Eigen::Vector3d& d, double lod);

}  // namespace omnipose::synth::detail
