#pragma once
/// \file window_registration.hpp
/// Sliding-window iFMI registration (improved Fourier-Mellin, Buelow & Birk) of two
/// panoramas: for every L x L window, the translation (du, dv), the in-window rotation and
/// scale, and a confidence. Windows are centred at columns u_k = k * step + L/2 - 0.5
/// (window k covers columns k*step .. k*step+L-1, wrapping around u),
/// k = 0 .. ceil(W/step) - 1, and span the full panorama height (L = H in the paper's
/// setting; with L < H the window is vertically centred).
///
/// Conventions (DESIGN.md section 2/3): content at (u, v) of the current window appears at
/// (u + du, v + dv) in the previous (reference) window, i.e. (du, dv) is what
/// cv::phaseCorrelate(current, previous) returns. The map from current-window coordinates
/// (about the window centre, u right, v down) to reference-window coordinates is
/// s * [[1, phi], [-phi, 1]] (+ (du, dv)): on screen the current content appears in the
/// reference rotated counter-clockwise by phi and scaled by s.
///
/// Realtime: the constructor allocates everything (FFTW plans, aligned buffers, the
/// reference spectra, the worker threads); measure()/advance() allocate nothing and never
/// throw. Windows are registered in parallel on a pool of `threads` workers (the
/// calling thread is one of them), each with its own FFTW plans and buffers; every window's
/// result is computed by the same code on the same data whichever worker runs it, so the
/// output is bit-identical for any thread count. Not thread-safe: one caller at a time
/// (construction and destruction take a process-wide lock around the FFTW planner).
///
/// Accuracy on real texture (tests/registration, paper setting, every window): shifts
/// 0..3 px within 0.03 px; rotations 0..3 deg within 0.09 deg and scales 0.97..1.03 within
/// 0.2 % on rich texture (within 0.22 deg / 0.52 % on a blurry indoor photo). Cost: about
/// 0.2 ms of CPU per window with de-rotation, 0.08 ms translation-only, on the development
/// VM (tests/bench/registration_bench.cpp); FFTW is about half of it.

#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "omnipose/window_motion.hpp"

namespace omnipose {

class WindowRegistration {
 public:
  struct Options {
    int window = 110;            ///< L, pixels (square window, 16 <= L <= H, <= kMaxWindow)
    int step = 20;               ///< d, pixels between window starts (1..kMaxStep); W % step
                                 ///< need not be 0
    bool estimate_rotation_scale = true;  ///< run the log-polar stage (else rotation 0, scale 1)
    /// Measure each window's (du, dv) covariance (WindowMotion::var_du, var_dv, cov_du_dv;
    /// else they stay 0): about 4 % more instructions per frame, in the whitening. The
    /// pipeline turns it on when the fit uses it (MotionFit::Options::window_covariance).
    bool shift_covariance = false;
    /// Weigh each window's frequencies by their signal-to-noise ratio instead of whitening
    /// every one to full weight (the paper's phase correlation): the panorama's noise sigma
    /// is measured on every frame kept as the next reference (Donoho's median of the 2 x 2
    /// diagonal Haar details, over the windows' rows and the usable pixels), and a
    /// frequency of power |F|^2 counts |F|^2 / (|F|^2 + sigma^2 sum(taper^2)) as much in
    /// each of the two windows. Indoor scenes (plain walls, blinds) gain; dense outdoor
    /// texture (grass, whose fine detail the median reads as noise) loses
    /// (docs/results/ANALYSIS.md). The pose covariance still describes the errors. Off by
    /// default. About 1 % more instructions per frame.
    bool noise_weighting = false;
    /// Re-sample a window that is de-rotated or de-scaled before its shift is measured with
    /// Keys cubic convolution (a = -0.75) instead of bilinear interpolation. Phase correlation
    /// reads the sampler's non-linear phase as a shift: given each window's exact scale and
    /// rotation, bilinear leaves an RMS du of 0.0076 px (park) / 0.0117 (indoor), cubic 0.0048 /
    /// 0.0089, and on exact warps of the drift benchmark's straights the expansion is then read
    /// right. But cubic also applies a misread scale or rotation in full, where bilinear's
    /// smoothing damps it: on rendered sequences the straights' yaw is better in six rooms of the
    /// drift pool and worse in three, and a blurred auto-exposure sequence's yaw doubles
    /// (docs/results/ANALYSIS.md, "The de-scaling's sampler"). Off by default. +43 M
    /// instructions a frame (callgrind, the drift pool's park).
    bool cubic_sampling = false;
    double max_rotation_rad = 0.35;  ///< |phi| searched around 0 (no 180-degree ambiguity), in (0, pi/4)
    double max_log_scale = 0.2;      ///< |ln s| searched around 0, in (0, 0.5]
    double min_confidence = 0.02;    ///< below this a window is marked invalid, and a
                                     ///< rotation/scale peak is not used (rs_confidence 0)
    double min_usable_fraction = 0.5;  ///< with a mask (setValidity): windows whose
                                       ///< taper-weighted usable fraction is below this
                                       ///< are not measured (WindowMotion::masked)

    /// Every problem, one message per bad field, each starting with the field's name
    /// ("window: 8 is outside [16, 512] pixels"); empty when valid.
    std::vector<std::string> validate() const;
  };

  /// Largest window side, pixels.
  static constexpr int kMaxWindow = 512;
  /// Most worker threads a registration or a pipeline runs (PipelineOptions::threads).
  static constexpr int kMaxThreads = 256;
  /// Largest step between windows, pixels.
  static constexpr int kMaxStep = 4096;
  /// Most window samples of one frame (windows x L^2): 16 Mi, 25 times the paper's setting
  /// (55 windows of 110 x 110); bounds the memory of the reference spectra.
  static constexpr long long kMaxWindowSamples = 16LL << 20;
  /// measure()'s `expected_dv`: a window with an expected vertical shift searches its
  /// translation peak only within this many pixels of it, pixels.
  static constexpr double kExpectedDvReachPx = 8.0;

  /// Every problem of `options` on a panorama of `panorama` pixels (width x height): those
  /// of Options::validate() plus the window against the panorama (taller or wider than it,
  /// more window samples than kMaxWindowSamples, a panorama under 16 pixels). Messages start
  /// with the field's name (or "panorama"). Empty when they fit.
  static std::vector<std::string> validate(cv::Size panorama, const Options& options);

  /// Registration of panoramas of `panorama` pixels (W x H: the calibration's panorama) on
  /// `threads` workers, the calling thread included (0 = all online cores; the result is the
  /// same for any count). Throws std::invalid_argument listing every problem of
  /// validate(panorama, options), and a thread count outside [0, kMaxThreads].
  WindowRegistration(cv::Size panorama, const Options& options, int threads = 1);
  ~WindowRegistration();
  WindowRegistration(const WindowRegistration&) = delete;
  WindowRegistration& operator=(const WindowRegistration&) = delete;

  const Options& options() const;
  /// Panorama size (W x H) this registration was built for.
  cv::Size panoramaSize() const;
  /// Number of workers (the calling thread included).
  int threads() const;
  /// Number of windows per panorama.
  int windowCount() const;
  /// The smallest |in-window rotation| (radians) or |ln scale| by which measure() re-samples a
  /// window before measuring its shift: below it, its corners move by at most 0.1 px and the
  /// window is registered as it is.
  double minDewarp() const;
  /// The panorama noise sigma (grey levels) measured on the last frame set as the
  /// reference or measured with keep_as_next (Options::noise_weighting); NaN without noise
  /// weighting, before any frame, or when too few pixels were usable.
  double noiseSigma() const;
  /// Centre column of window k, pixels.
  double windowCenter(int k) const;
  /// First panorama row of every window ((H - L) / 2: the windows are centred vertically).
  int windowTop() const;

  /// Makes `panorama` (CV_32FC1, W x H) the reference. Transforms its windows
  /// once. A panorama of the wrong size or type is ignored (the reference is unchanged).
  void setReference(const cv::Mat& panorama);
  /// Whether a reference is set.
  bool hasReference() const;

  /// The most samples of a blur path setMotionBlur() reads per window.
  static constexpr int kMaxBlurSamples = 64;
  /// setMotionBlur() leaves a window alone whose blur is shorter than this, pixels (its
  /// kernel's phase is then its centroid's), or longer than kMaxBlurExtentPx.
  static constexpr double kMinBlurExtentPx = 0.5;
  static constexpr double kMaxBlurExtentPx = 32.0;
  /// The motion blur of the frame whose windows are transformed next (measure()'s
  /// `current`, setReference()'s panorama; not setKeyframe()'s): `paths` holds, for each of
  /// the windowCount() windows in turn, `samples` (1..kMaxBlurSamples) shifts in pixels, in
  /// du's sense (WindowMotion), of the sharp frames the blurred one averages (equally spaced
  /// over the exposure). Each window's translation band is then freed of its blur kernel's
  /// phase about the kernel's mean, so the window's du reads the mean of its shifts
  /// whatever the kernel's shape (a long, asymmetric blur otherwise moves the correlation
  /// peak off that mean). Only horizontal blur: vertical shifts are not given. Applies to
  /// every frame until set again; empty `paths`, or fewer than windowCount() * samples
  /// values, clears it. Allocation-free; about windows x 65 x samples complex products.
  void setMotionBlur(std::span<const float> paths, int samples);

  /// Sets the static map of usable panorama pixels (CV_32FC1, W x H, 1 = usable, 0 = masked
  /// or outside the lens, e.g. Unwrapper::validity()). Start-up only: allocates one weight
  /// table per window when anything is masked, and drops the reference. Masked pixels are
  /// left out of each window's mean and faded out of its taper (eroded by 3 px, feathered
  /// over 2 px), so a static mask border never reaches a spectrum as an edge that would
  /// pull the shift towards zero; windows whose taper-weighted usable fraction is below
  /// Options::min_usable_fraction are not measured (WindowMotion::masked). An all-ones map
  /// restores the plain taper. Throws std::invalid_argument on a map of the wrong size/type.
  void setValidity(const cv::Mat& validity);
  /// Windows that setValidity() excluded.
  int maskedWindowCount() const;

  /// Registers every window of `current` (CV_32FC1, W x H) against the reference and
  /// writes windowCount() motions to `out` (out.size() must be >= windowCount()). The
  /// current windows' spectra are kept as the candidate next reference unless
  /// `keep_as_next` is false (used to re-register a warped copy of the same frame).
  /// Requires hasReference(); returns false (and writes nothing) otherwise or when the
  /// image has the wrong size/type.
  ///
  /// `known_rotation_scale` (one entry per window): skip the log-polar search and
  /// de-rotate/de-scale each window by the given rotation and scale (entries with
  /// rs_confidence 0 are not de-warped); they are copied to `out`. With keep_as_next the
  /// log-polar spectra are still computed for the next reference. The pipeline's first
  /// pass uses it with all rs_confidence 0 (a fast shift-only estimate that the
  /// refinement pass then measures again in full).
  ///
  /// `expected_dv` (empty, or one entry per window, pixels): window k with a finite entry
  /// searches its translation peak only within kExpectedDvReachPx of dv = expected_dv[k]
  /// (every du still), so the inverse transform's row pass computes 17 of its 108 rows at
  /// the paper setting; a peak on the border of that band may be a cut-off one and leaves
  /// the window invalid.
  /// NaN entries search every shift. The pipeline's refinement pass uses it with the dv
  /// its first fit predicts.
  ///
  /// `against`: kPreviousFrame (the reference), or a keyframe slot (storeKeyframe()) to
  /// register against instead; false (nothing written) for an empty or unknown slot.
  ///
  /// `dewarp` (empty, or one entry per window): window k is de-rotated/de-scaled by
  /// dewarp[k].rotation (radians) and dewarp[k].scale before its shift is measured, instead of
  /// by the rotation and scale it measured (or was given in `known_rotation_scale`); `out`
  /// still reports those. An entry whose rotation is not finite, or whose scale is not a finite
  /// positive number, leaves its window to its own. The pipeline's refinement pass gives the rotation
  /// and scale its last fit predicts (PipelineOptions::dewarp_by_fit): smooth around the ring,
  /// where a window's own are noisy.
  bool measure(const cv::Mat& current, std::span<WindowMotion> out, bool keep_as_next = true,
               std::span<const WindowMotion> known_rotation_scale = {},
               std::span<const double> expected_dv = {}, int against = kPreviousFrame,
               std::span<const WindowMotion> dewarp = {});
  /// Makes the last frame measured with keep_as_next the reference (a pointer swap, no
  /// recomputation). A no-op when no frame was measured with keep_as_next since the last
  /// setReference()/advance().
  void advance();

  /// measure()'s `against` for the reference (the previous frame).
  static constexpr int kPreviousFrame = -1;
  /// The most keyframe slots reserveKeyframes() takes (keyframes.slots of daemon.yaml).
  static constexpr int kMaxKeyframeSlots = 16;
  /// Start-up only: allocates `slots` keyframe slots (spectra of a whole panorama each,
  /// as much memory as the reference). Drops any stored keyframe. Throws
  /// std::invalid_argument outside [0, kMaxKeyframeSlots].
  void reserveKeyframes(int slots);
  /// Keyframe slots reserved.
  int keyframeSlots() const;
  /// Makes the reference keyframe `slot` (replacing what the slot held). No copy is made:
  /// the spectra move into the slot when the reference is replaced (advance(),
  /// setReference()). False, and nothing stored, without a reference or for an unknown slot.
  bool storeKeyframe(int slot);
  /// Makes `panorama` (CV_32FC1, W x H: a view kept from earlier, a place to recognise)
  /// keyframe `slot`, transforming its windows as setReference() does, without touching
  /// the reference (its noise, measured on the reference, whitens it). Allocates nothing.
  /// False, and nothing stored, for an unknown slot or a panorama of the wrong size/type.
  bool setKeyframe(int slot, const cv::Mat& panorama);
  /// Whether keyframe slot `slot` holds spectra (storeKeyframe() since the last
  /// reserveKeyframes()/setValidity()).
  bool hasKeyframe(int slot) const;

 private:
  struct Impl;
  /// The library's pipeline builds its registration on the worker pool it shares among its
  /// stages (src/registration/shared_pool_registration.hpp, private).
  friend class SharedPoolRegistration;
  explicit WindowRegistration(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace omnipose
