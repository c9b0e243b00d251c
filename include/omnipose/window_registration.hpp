#pragma once
/// \file window_registration.hpp
/// Sliding-window iFMI registration (improved Fourier-Mellin, Buelow & Birk) of two
/// panoramas: for every L x L window, the translation (du, dv), the in-window rotation and
/// scale, and a confidence. Windows are centred at columns u_k = k * step + L/2 - 0.5
/// (window k covers columns k*step .. k*step+L-1, wrapping around u), k = 0 .. W/step - 1,
/// and span the full panorama height (L = H in the paper's setting; with L < H the window
/// is vertically centred).
///
/// Conventions (DESIGN.md section 2/3): content at (u, v) of the current window appears at
/// (u + du, v + dv) in the previous (reference) window, i.e. (du, dv) is what
/// cv::phaseCorrelate(current, previous) returns. The map from current-window coordinates
/// (about the window centre, u right, v down) to reference-window coordinates is
/// s * [[1, phi], [-phi, 1]] (+ (du, dv)): on screen the current content appears in the
/// reference rotated counter-clockwise by phi and scaled by s.
///
/// Realtime: the constructor allocates everything (FFTW plans, aligned buffers, the
/// reference spectra); measure()/advance() allocate nothing and never throw. Not
/// thread-safe: one instance per processing thread.

#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string>

namespace omnipose {

/// Motion of one window between the reference and the current panorama.
struct WindowMotion {
  double center_u = 0.0;    ///< window centre column in the panorama, pixels
  double du = 0.0;          ///< shift along u, pixels (see file comment for the sign)
  double dv = 0.0;          ///< shift along v, pixels
  double rotation = 0.0;    ///< in-window rotation phi, radians (counter-clockwise on screen)
  double scale = 1.0;       ///< in-window scale s
  double confidence = 0.0;  ///< translation peak quality in [0, 1]; 0 = no usable peak
  double rs_confidence = 0.0;  ///< rotation/scale peak quality in [0, 1]
  bool valid = false;       ///< false: window has no texture / no peak; ignore it
};

class WindowRegistration {
 public:
  struct Options {
    int panorama_width = 1100;   ///< W, pixels
    int panorama_height = 110;   ///< H, pixels
    int window = 110;            ///< L, pixels (square window, L <= H)
    int step = 20;               ///< d, pixels between window starts; W % step need not be 0
    bool estimate_rotation_scale = true;  ///< run the log-polar stage (else rotation 0, scale 1)
    double max_rotation_rad = 0.35;  ///< |phi| searched around 0 (no 180-degree ambiguity)
    double max_log_scale = 0.2;      ///< |ln s| searched around 0
    double min_confidence = 0.02;    ///< below this a window is marked invalid

    /// Empty string when valid, else a message naming the bad field.
    std::string validate() const;
  };

  /// Throws std::invalid_argument (naming the field) when options are invalid.
  explicit WindowRegistration(const Options& options);
  ~WindowRegistration();
  WindowRegistration(const WindowRegistration&) = delete;
  WindowRegistration& operator=(const WindowRegistration&) = delete;

  const Options& options() const;
  /// Number of windows per panorama.
  int windowCount() const;
  /// Centre column of window k, pixels.
  double windowCenter(int k) const;

  /// Makes `panorama` (CV_32FC1, W x H) the reference. Transforms its windows once.
  void setReference(const cv::Mat& panorama);
  /// Whether a reference is set.
  bool hasReference() const;

  /// Registers every window of `current` (CV_32FC1, W x H) against the reference and
  /// writes windowCount() motions to `out` (out.size() must be >= windowCount()). The
  /// current windows' spectra are kept as the candidate next reference unless
  /// `keep_as_next` is false (used to re-register a warped copy of the same frame).
  /// Requires hasReference(); returns false (and writes nothing) otherwise or when the
  /// image has the wrong size/type.
  bool measure(const cv::Mat& current, std::span<WindowMotion> out, bool keep_as_next = true);
  /// Makes the last frame measured with keep_as_next the reference (no recomputation).
  void advance();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace omnipose
