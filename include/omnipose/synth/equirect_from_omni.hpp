#pragma once
/// \file equirect_from_omni.hpp
/// A scene texture made from a real omni image (the texture convention of scene.hpp).

#include <opencv2/core.hpp>

#include "omnipose/calibration.hpp"

namespace omnipose::synth {

/// An equirectangular texture made from a real omni image: what a camera under a mirror saw,
/// as a photo the renderer can paint on a sphere or a room.
struct EquirectFromOmni {
  cv::Mat texture;        ///< CV_8UC1, width x width / 2, the convention of scene.hpp
  cv::Mat seen;           ///< CV_8UC1, same size: 255 where the ring saw the bearing, else 0
  double elevation_min = 0.0;  ///< lowest and highest elevation of the ring, radians
                               ///< (Calibration::ringElevations)
  double elevation_max = 0.0;
  double fill = 0.0;      ///< grey level of every unseen texel: the mean of the seen ones
};

/// Resamples `omni` (8-bit grey or BGR, the frame size of `calibration`) into an
/// equirectangular texture of `width` x width/2 texels: texel (x, y) looks along the
/// bearing of the convention of scene.hpp, taken as a camera-frame bearing at the identity pose,
/// and gets the omni image bilinearly at calibration.pixelOfBearing of it, where its
/// elevation is one the ring sees, that pixel lies at least one pixel inside the used ring
/// (radius_inner + 1 .. radius_outer - 1, so no sample reaches beyond it) and, with a mask,
/// on a used pixel.
/// Every other texel (above or below the ring's elevations) gets the seen texels' mean, a
/// flat surface. Rendering the texture through `calibration` at the identity pose gives
/// back the ring's image (to the bilinear resampling). Throws std::invalid_argument when
/// the image size differs from the calibration's, `width` is not an even number in
/// [16, 16384], or the ring sees no texel.
EquirectFromOmni equirectFromOmni(const cv::Mat& omni, const Calibration& calibration, int width);

}  // namespace omnipose::synth
