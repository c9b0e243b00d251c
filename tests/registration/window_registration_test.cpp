/// Tests of the sliding-window iFMI registration on real texture (shared/data/equirect).
///
/// Accuracy achieved at the paper's setting (W = 1100, H = L = 110, d = 20), every window,
/// exact generators (test_images.hpp); see each test for the asserted bound:
///   sub-pixel shift 0..3 px (0.1 steps, u and v):  max error 0.027 px (indoor), 0.017 px (park)
///   in-window rotation 0..3 deg:                   max error 0.085 deg (park), 0.22 deg (indoor)
///   in-window scale 0.97..1.03:                    max error 0.20 % (park), 0.52 % (indoor)

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

#include "omnipose/window_registration.hpp"
#include "test_figures.hpp"
#include "test_images.hpp"

namespace omnipose {
namespace {

using test::kIndoor;
using test::kPark;

constexpr double kDeg = std::numbers::pi / 180.0;

WindowRegistration::Options paperOptions() { return {}; }  // L 110, d 20
const cv::Size kPaperPanorama(1100, 110);                  // W 1100, H = L

/// Equirect photo at panorama width 1100 (cached: decoding the park photo takes a while).
const cv::Mat& equirect(const char* name) {
  static cv::Mat indoor = test::loadEquirect(kIndoor, 1100);
  static cv::Mat park = test::loadEquirect(kPark, 1100);
  return std::string(name) == kIndoor ? indoor : park;
}

#define REQUIRE_IMAGE(image, name)                                                      \
  if ((image).empty()) GTEST_SKIP() << "shared test photo " << (name)                   \
                                    << " not found (set OMNIPOSE_EQUIRECT_DIR)"

/// The 1100 x 110 panorama band about the horizon of a photo.
cv::Mat horizonBand(const char* name) {
  const cv::Mat& eq = equirect(name);
  return test::rowBand(eq, eq.rows / 2, 110);
}

/// Runs measure() and returns the motions (asserting success).
std::vector<WindowMotion> measureAll(WindowRegistration& reg, const cv::Mat& current,
                                     bool keep_as_next = true) {
  std::vector<WindowMotion> out(reg.windowCount());
  EXPECT_TRUE(reg.measure(current, out, keep_as_next));
  return out;
}

// ---------------------------------------------------------------------------------------
// Options, geometry, preconditions
// ---------------------------------------------------------------------------------------

TEST(WindowRegistrationOptions, DefaultsArePaperSettingAndValid) {
  const WindowRegistration::Options o;
  EXPECT_EQ(o.window, 110);
  EXPECT_EQ(o.step, 20);
  EXPECT_TRUE(o.validate().empty());
  EXPECT_TRUE(WindowRegistration::validate(kPaperPanorama, o).empty());
}

TEST(WindowRegistrationOptions, ValidateNamesTheBadField) {
  auto check = [](auto mutate, const char* field, cv::Size panorama = kPaperPanorama) {
    WindowRegistration::Options o;
    mutate(o);
    const auto problems = WindowRegistration::validate(panorama, o);
    ASSERT_EQ(problems.size(), 1u) << field;
    EXPECT_EQ(problems[0].rfind(std::string(field) + ": ", 0), 0u) << problems[0];
    EXPECT_THROW(WindowRegistration(panorama, o), std::invalid_argument) << field;
  };
  check([](auto& o) { o.window = 120; }, "window");  // taller than the panorama
  check([](auto& o) { o.window = 8; }, "window");
  check([](auto& o) { o.step = 0; }, "step");
  check([](auto&) {}, "panorama", cv::Size(0, 110));
  check([](auto& o) { o.max_rotation_rad = 0.0; }, "max_rotation_rad");
  check([](auto& o) { o.max_rotation_rad = 1.0; }, "max_rotation_rad");
  check([](auto& o) { o.max_log_scale = -0.1; }, "max_log_scale");
  check([](auto& o) { o.min_confidence = 1.5; }, "min_confidence");
  check([](auto& o) { o.min_confidence = std::nan(""); }, "min_confidence");
  check([](auto& o) { o.step = 1; }, "step", cv::Size(16384, 512));  // too many samples
}

TEST(WindowRegistrationOptions, ValidateListsEveryProblem) {
  WindowRegistration::Options o;
  o.window = 4;
  o.step = -1;
  o.max_log_scale = 0.9;
  const auto problems = o.validate();
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_EQ(problems[0], "window: 4 is outside [16, 512] pixels");
  EXPECT_EQ(problems[1], "step: -1 is outside [1, 4096] pixels");
  EXPECT_EQ(problems[2], "max_log_scale: 0.9 is outside (0, 0.5]");
}

TEST(WindowRegistration, WindowCentresFollowTheHeaderConvention) {
  WindowRegistration reg(kPaperPanorama, paperOptions());
  ASSERT_EQ(reg.windowCount(), 55);
  EXPECT_DOUBLE_EQ(reg.windowCenter(0), 54.5);
  EXPECT_DOUBLE_EQ(reg.windowCenter(1), 74.5);
  EXPECT_DOUBLE_EQ(reg.windowCenter(52), 1094.5);
  EXPECT_DOUBLE_EQ(reg.windowCenter(53), 14.5);  // 1114.5, wrapped into [0, W)
  // W not a multiple of the step: ceil(W / step) windows.
  WindowRegistration odd(cv::Size(1110, 110), paperOptions());
  EXPECT_EQ(odd.windowCount(), 56);
  EXPECT_DOUBLE_EQ(odd.windowCenter(55), std::fmod(55 * 20 + 54.5, 1110.0));
}

TEST(WindowRegistration, MeasureRejectsMissingReferenceAndBadInput) {
  WindowRegistration reg(kPaperPanorama, paperOptions());
  const cv::Mat good(110, 1100, CV_32FC1, cv::Scalar(1.0f));
  std::vector<WindowMotion> out(reg.windowCount());
  out[0].du = 42.0;
  EXPECT_FALSE(reg.hasReference());
  EXPECT_FALSE(reg.measure(good, out));
  reg.setReference(good);
  EXPECT_TRUE(reg.hasReference());
  EXPECT_FALSE(reg.measure(cv::Mat(110, 1100, CV_8UC1, cv::Scalar(1)), out));
  EXPECT_FALSE(reg.measure(cv::Mat(110, 1000, CV_32FC1, cv::Scalar(1.0f)), out));
  std::vector<WindowMotion> short_out(reg.windowCount() - 1);
  EXPECT_FALSE(reg.measure(good, short_out));
  EXPECT_EQ(out[0].du, 42.0) << "a rejected call must not write";
  const std::vector<double> short_expected(reg.windowCount() - 1, 0.0);
  EXPECT_FALSE(reg.measure(good, out, true, {}, short_expected));
  EXPECT_EQ(out[0].du, 42.0) << "a rejected call must not write";
}

TEST(WindowRegistration, AcceptsRoiViewsOfLargerImages) {
  const cv::Mat& eq = equirect(kIndoor);
  REQUIRE_IMAGE(eq, kIndoor);
  const cv::Mat a = test::fourierShiftedBand(eq, eq.rows / 2, 110, 0.0, 0.0);
  const cv::Mat b = test::fourierShiftedBand(eq, eq.rows / 2, 110, 0.4, -0.2);
  cv::Mat big_a(130, 1150, CV_32F, cv::Scalar(0.0f)), big_b = big_a.clone();
  const cv::Rect roi(17, 9, 1100, 110);
  a.copyTo(big_a(roi));
  b.copyTo(big_b(roi));
  WindowRegistration reg(kPaperPanorama, paperOptions());
  reg.setReference(a);
  const auto dense = measureAll(reg, b, false);
  reg.setReference(big_a(roi));
  const auto views = measureAll(reg, big_b(roi), false);
  for (std::size_t k = 0; k < dense.size(); ++k) {
    EXPECT_DOUBLE_EQ(views[k].du, dense[k].du) << k;
    EXPECT_DOUBLE_EQ(views[k].dv, dense[k].dv) << k;
  }
}

// ---------------------------------------------------------------------------------------
// (c) Sign conventions, pinned with cv::warpAffine
// ---------------------------------------------------------------------------------------

TEST(WindowRegistrationSigns, TranslationMatchesPhaseCorrelateOfCurrentThenReference) {
  const cv::Mat current = horizonBand(kPark);
  REQUIRE_IMAGE(current, kPark);
  WindowRegistration reg(kPaperPanorama, paperOptions());
  for (const auto& [du, dv] : {std::pair{3.0, -2.0}, {2.5, -1.5}, {-1.25, 0.75}}) {
    // Content at x in the current panorama appears at x + (du, dv) in the reference.
    const cv::Mat m = (cv::Mat_<double>(2, 3) << 1, 0, du, 0, 1, dv);
    cv::Mat reference;
    cv::warpAffine(current, reference, m, current.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
    reg.setReference(reference);
    const auto out = measureAll(reg, current);
    for (int k = 5; k < 45; ++k) {  // away from the panorama's (non-periodic) ends
      ASSERT_TRUE(out[k].valid) << k;
      EXPECT_NEAR(out[k].du, du, 0.1) << k;
      EXPECT_NEAR(out[k].dv, dv, 0.1) << k;
    }
    if (du != std::round(du)) continue;
    // Same sign as OpenCV's phaseCorrelate(current window, reference window), compared at
    // an integer shift (its 5x5 centroid is biased between pixels, by up to ~0.3 px).
    const cv::Rect roi(400, 0, 110, 110);  // window 20
    cv::Mat hann;
    cv::createHanningWindow(hann, roi.size(), CV_32F);
    const cv::Point2d cv_shift = cv::phaseCorrelate(current(roi), reference(roi), hann);
    const std::string shift = "shift_u" + testing::fixed(du, 0) + "_v" + testing::fixed(dv, 0);
    testing::recordFigure(shift + "_ours_du_px", out[20].du, 3);
    testing::recordFigure(shift + "_ours_dv_px", out[20].dv, 3);
    testing::recordFigure(shift + "_phase_correlate_du_px", cv_shift.x, 3);
    testing::recordFigure(shift + "_phase_correlate_dv_px", cv_shift.y, 3);
    SCOPED_TRACE("shift (" + testing::fixed(du, 1) + ", " + testing::fixed(dv, 1) + "): ours (" +
                 testing::fixed(out[20].du, 3) + ", " + testing::fixed(out[20].dv, 3) +
                 "), cv::phaseCorrelate (" + testing::fixed(cv_shift.x, 3) + ", " +
                 testing::fixed(cv_shift.y, 3) + ")");
    EXPECT_GT(cv_shift.x * du, 0.0);
    EXPECT_GT(cv_shift.y * dv, 0.0);
    EXPECT_NEAR(out[20].du, cv_shift.x, 0.1);
    EXPECT_NEAR(out[20].dv, cv_shift.y, 0.1);
  }
}

TEST(WindowRegistrationSigns, RotationIsCounterClockwiseOnScreenAndScaleIsReferenceOverCurrent) {
  const cv::Mat current = horizonBand(kPark);
  REQUIRE_IMAGE(current, kPark);
  WindowRegistration reg(kPaperPanorama, paperOptions());
  const int k = 20;
  const cv::Point2f centre(static_cast<float>(reg.windowCenter(k)), 54.5f);
  for (const auto& [degrees, scale] : {std::pair{2.0, 1.0}, {-2.0, 1.0}, {0.0, 1.02}, {1.5, 0.98}}) {
    // getRotationMatrix2D maps current -> reference: x_p = c + s [[cos, sin], [-sin, cos]] (x_c - c),
    // i.e. the current content appears in the reference rotated counter-clockwise on screen.
    const cv::Mat m = cv::getRotationMatrix2D(centre, degrees, scale);
    cv::Mat reference;
    cv::warpAffine(current, reference, m, current.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
    reg.setReference(reference);
    const auto out = measureAll(reg, current);
    ASSERT_TRUE(out[k].valid);
    EXPECT_GT(out[k].rs_confidence, 0.2);
    EXPECT_NEAR(out[k].rotation, degrees * kDeg, 0.2 * kDeg) << degrees << " deg, s " << scale;
    EXPECT_NEAR(out[k].scale, scale, 0.004) << degrees << " deg, s " << scale;
    EXPECT_NEAR(out[k].du, 0.0, 0.1);  // rotation about the window centre: no shift
    EXPECT_NEAR(out[k].dv, 0.0, 0.1);
  }
}

// ---------------------------------------------------------------------------------------
// (a) Sub-pixel shifts
TEST(WindowRegistration, AnExpectedDvSearchesOnlyABandOfShiftsAroundIt) {
  const cv::Mat& eq = equirect(kPark);
  REQUIRE_IMAGE(eq, kPark);
  const int centre = eq.rows / 2;
  WindowRegistration reg(kPaperPanorama, paperOptions());
  reg.setReference(test::fourierShiftedBand(eq, centre, 110, 0.0, 0.0));
  // Content of the current panorama appears at (+1.3, +12.4) px in the reference: a shift
  // beyond the band around zero, as a vertical translation gives.
  const cv::Mat current = test::fourierShiftedBand(eq, centre, 110, -1.3, -12.4);
  const int n = reg.windowCount();
  const auto full = measureAll(reg, current, false);
  std::vector<WindowMotion> near(n);
  // Expected 1.7 px below the true shift (inside the band): the same peaks.
  std::vector<double> expected(n, 10.7);
  ASSERT_TRUE(reg.measure(current, near, false, {}, expected));
  int valid = 0;
  for (int k = 0; k < n; ++k) {
    ASSERT_TRUE(full[k].valid) << k;
    EXPECT_NEAR(full[k].dv, 12.4, 0.05) << k;
    EXPECT_TRUE(near[k].valid) << k;
    EXPECT_NEAR(near[k].du, full[k].du, 1e-4) << k;
    EXPECT_NEAR(near[k].dv, full[k].dv, 1e-4) << k;
    EXPECT_GE(near[k].confidence, full[k].confidence - 1e-6) << k;
    valid += near[k].valid;
  }
  EXPECT_EQ(valid, n);
  // NaN: every shift searched, the same result bit for bit.
  std::fill(expected.begin(), expected.end(), std::numeric_limits<double>::quiet_NaN());
  ASSERT_TRUE(reg.measure(current, near, false, {}, expected));
  for (int k = 0; k < n; ++k) {
    EXPECT_EQ(near[k].dv, full[k].dv) << k;
    EXPECT_EQ(near[k].confidence, full[k].confidence) << k;
  }
  // A band that misses the true shift cannot report it.
  std::fill(expected.begin(), expected.end(), 12.4 + 2.5 * WindowRegistration::kExpectedDvReachPx);
  ASSERT_TRUE(reg.measure(current, near, false, {}, expected));
  for (int k = 0; k < n; ++k)
    EXPECT_TRUE(!near[k].valid || std::abs(near[k].dv - 12.4) > WindowRegistration::kExpectedDvReachPx)
        << k << ": dv " << near[k].dv;
}

// ---------------------------------------------------------------------------------------

struct ShiftStats {
  double max_error = 0.0;
  double sum_sq = 0.0;
  int count = 0;
  int invalid = 0;
  double min_confidence = 1.0;
};

/// Shifts 0.0 .. 3.0 px in 0.1 steps along one axis (Fourier shift: exact, no
/// interpolation bias); the error of a window is the larger of its u and v errors.
ShiftStats shiftSweep(const char* name, bool along_u) {
  const cv::Mat& eq = equirect(name);
  const int centre = eq.rows / 2;
  WindowRegistration reg(kPaperPanorama, paperOptions());
  reg.setReference(test::fourierShiftedBand(eq, centre, 110, 0.0, 0.0));
  ShiftStats stats;
  for (int i = 0; i <= 30; ++i) {
    const double d = 0.1 * i, du = along_u ? d : 0.0, dv = along_u ? 0.0 : d;
    // Current = reference moved by -d: its content appears at +d in the reference.
    const auto out = measureAll(reg, test::fourierShiftedBand(eq, centre, 110, -du, -dv), false);
    for (const WindowMotion& w : out) {
      if (!w.valid) {
        ++stats.invalid;
        continue;
      }
      const double e = std::max(std::abs(w.du - du), std::abs(w.dv - dv));
      stats.max_error = std::max(stats.max_error, e);
      stats.sum_sq += e * e;
      ++stats.count;
      stats.min_confidence = std::min(stats.min_confidence, w.confidence);
    }
  }
  return stats;
}

class SubpixelShift : public ::testing::TestWithParam<std::tuple<std::string, bool>> {};

TEST_P(SubpixelShift, EveryWindowWithin0p04Pixel) {
  const auto& [image, along_u] = GetParam();
  const char* name = image.c_str();
  REQUIRE_IMAGE(equirect(name), name);
  const ShiftStats s = shiftSweep(name, along_u);
  testing::recordFigure("max_error_px", s.max_error, 4);
  testing::recordFigure("rms_error_px", std::sqrt(s.sum_sq / s.count), 4);
  RecordProperty("windows", s.count);
  // Achieved: max 0.027 px (indoor, u), 0.020 (indoor, v), 0.017 (park, u), 0.013 (park, v);
  // RMS 0.004 - 0.006 px. Target 0.05 px.
  EXPECT_EQ(s.invalid, 0);
  EXPECT_LT(s.max_error, 0.04);
  EXPECT_LT(std::sqrt(s.sum_sq / s.count), 0.01);
  EXPECT_GT(s.min_confidence, 0.5);
}

INSTANTIATE_TEST_SUITE_P(RealTexture, SubpixelShift,
                         ::testing::Combine(::testing::Values(std::string(kIndoor), std::string(kPark)),
                                            ::testing::Bool()),
                         [](const auto& info) {
                           return std::string(std::get<0>(info.param) == kIndoor ? "Indoor" : "Park") +
                                  (std::get<1>(info.param) ? "AlongU" : "AlongV");
                         });

// ---------------------------------------------------------------------------------------
// (b) In-window rotation and scale
// ---------------------------------------------------------------------------------------

/// Every window of the current panorama made from the reference rotated by `phi` and
/// scaled by `s` about that window's own centre (4x supersampled warp, box-averaged): the
/// current content appears in the reference rotated counter-clockwise by phi, scaled by s,
/// so each window must report (phi, s) and no shift. Windows whose blocks do not overlap
/// (around the circle) share one current panorama. With `given` kKnown the registration is
/// given (phi, s) and only de-rotates, de-scales and measures the shift; with kDewarp it
/// measures them and is given (phi, s) to de-warp by (measure()'s `dewarp`); with kNoDewarp
/// it is given de-warp entries that leave every window to its own.
enum class Given { kNothing, kKnown, kDewarp, kNoDewarp };
std::vector<WindowMotion> similaritySweep(WindowRegistration& reg, const test::Supersampled& ss,
                                          double phi, double s, Given given = Given::kNothing) {
  const int n = reg.windowCount(), length = reg.options().window, step = reg.options().step;
  const int width = reg.panoramaSize().width;
  auto overlap = [&](int a, int b) {
    const int d = ((b - a) * step % width + width) % width;
    return d < length || width - d < length;
  };
  std::vector<std::vector<int>> groups;  // greedy: first group without an overlapping block
  for (int k = 0; k < n; ++k) {
    auto fits = [&](const std::vector<int>& g) {
      return std::none_of(g.begin(), g.end(), [&](int m) { return overlap(m, k); });
    };
    auto it = std::find_if(groups.begin(), groups.end(), fits);
    if (it == groups.end()) groups.push_back({k});
    else it->push_back(k);
  }
  const cv::Mat reference = ss.panorama();
  reg.setReference(reference);
  std::vector<WindowMotion> all(n);
  for (const std::vector<int>& group : groups) {
    cv::Mat current = reference.clone();
    for (int k : group) {
      const cv::Point2d centre(k * step + 0.5 * length - 0.5, 0.5 * length - 0.5);  // unwrapped
      test::pasteWrapped(ss.warpedBlock(k * step, length, centre, phi, s), k * step, current);
    }
    std::vector<WindowMotion> values(given == Given::kNothing ? 0 : n);
    for (WindowMotion& w : values) {
      w.rotation = phi;
      w.scale = given == Given::kNoDewarp ? 0.0 : s;
      w.rs_confidence = 1.0;
    }
    std::vector<WindowMotion> out(n);
    if (given == Given::kKnown) {
      EXPECT_TRUE(reg.measure(current, out, false, values));
    } else {
      EXPECT_TRUE(reg.measure(current, out, false, {}, {}, WindowRegistration::kPreviousFrame,
                              values));
    }
    for (int k : group) all[k] = out[k];
  }
  return all;
}

/// Percentile p in [0, 1] of |values|.
double percentile(std::vector<double> values, double p) {
  for (double& v : values) v = std::abs(v);
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<std::size_t>(p * values.size()))];
}

/// Bounds on the errors over every window of both sweeps (rotations 0.5..3 deg at s = 1,
/// scales 0.97..1.03 at phi = 0); p90 = 90th percentile.
struct SimilarityBounds {
  const char* image;
  double rotation_max_deg, rotation_p90_deg;  ///< |phi_measured - phi|, degrees
  double scale_max, scale_p90;                ///< |s_measured / s - 1|
  double shift_max_px;                        ///< |du|, |dv| (true shift 0), pixels
};

class SimilarityAccuracy : public ::testing::TestWithParam<SimilarityBounds> {};

TEST_P(SimilarityAccuracy, RotationsAndScales) {
  const SimilarityBounds bounds = GetParam();
  const test::Supersampled ss = test::loadSupersampled(bounds.image, 1100, 110);
  REQUIRE_IMAGE(ss.image, bounds.image);
  WindowRegistration reg(kPaperPanorama, paperOptions());
  // Errors of every window in both sweeps (the rotation sweep has s = 1, the scale sweep
  // phi = 0, and both have no shift).
  std::vector<double> rotation_errors, scale_errors, shifts;
  auto collect = [&](const std::vector<WindowMotion>& out, double degrees, double s) {
    for (const WindowMotion& w : out) {
      ASSERT_TRUE(w.valid);
      ASSERT_GT(w.rs_confidence, 0.0);
      rotation_errors.push_back(w.rotation / kDeg - degrees);
      scale_errors.push_back(w.scale / s - 1.0);
      shifts.push_back(std::max(std::abs(w.du), std::abs(w.dv)));
    }
  };
  for (double degrees : {0.5, 1.0, 1.5, 2.0, 2.5, 3.0})
    collect(similaritySweep(reg, ss, degrees * kDeg, 1.0), degrees, 1.0);
  for (double s : {0.97, 0.98, 0.99, 1.01, 1.02, 1.03}) collect(similaritySweep(reg, ss, 0.0, s), 0.0, s);

  const double rot_max = percentile(rotation_errors, 1.0), rot_p90 = percentile(rotation_errors, 0.9);
  const double scale_max = percentile(scale_errors, 1.0), scale_p90 = percentile(scale_errors, 0.9);
  const double shift_max = percentile(shifts, 1.0);
  testing::recordFigure("rotation_error_max_deg", rot_max, 3);
  testing::recordFigure("rotation_error_p90_deg", rot_p90, 3);
  testing::recordFigure("scale_error_max", scale_max, 4);
  testing::recordFigure("scale_error_p90", scale_p90, 4);
  testing::recordFigure("shift_max_px", shift_max, 3);
  EXPECT_LT(rot_max, bounds.rotation_max_deg);
  EXPECT_LT(rot_p90, bounds.rotation_p90_deg);
  EXPECT_LT(scale_max, bounds.scale_max);
  EXPECT_LT(scale_p90, bounds.scale_p90);
  EXPECT_LT(shift_max, bounds.shift_max_px);
}

void PrintTo(const SimilarityBounds& b, std::ostream* os) { *os << b.image; }

// Achieved (every one of 55 windows x 6 cases per sweep):
//   park:   rotation max 0.085 deg, p90 0.045; scale max 0.20 %, p90 0.12 %; shift max 0.04 px.
//           Meets the targets (0.1 deg, 0.3 %) on every window.
//   indoor: rotation max 0.22 deg, p90 0.068; scale max 0.52 %, p90 0.20 %; shift max 0.15 px.
//           A 1024 px photo upsampled 4.3x (little fine texture, blank walls): the targets
//           hold for 90 % of the windows, not for the worst ones.
INSTANTIATE_TEST_SUITE_P(RealTexture, SimilarityAccuracy,
                         ::testing::Values(SimilarityBounds{kPark, 0.1, 0.07, 0.003, 0.002, 0.06},
                                           SimilarityBounds{kIndoor, 0.3, 0.1, 0.007, 0.003, 0.2}),
                         [](const auto& info) {
                           return std::string(info.param.image == kIndoor ? "Indoor" : "Park");
                         });

/// A window that is de-rotated or de-scaled is re-sampled; phase correlation reads any
/// non-linear phase of the sampler as a shift. Given each window's exact rotation and scale
/// (so only the sampler is tested), every window should read no shift. Bilinear (the default)
/// leaves an RMS du of 0.0076 px (park) and 0.0117 px (indoor) here; Keys cubic
/// (Options::cubic_sampling) 0.0048-0.0051 and 0.0089-0.0092 (the rest: the warp's own
/// sampling and the content that enters and leaves the window).
struct SamplerBounds {
  const char* image;
  double cubic_du_rms_px;  ///< RMS du over every window of the sweep, at 0 and at 1 degree
};

class DeScalingSampler : public ::testing::TestWithParam<SamplerBounds> {};

/// RMS du of every window of the scale sweep (0.97..1.03) at `degrees`, (phi, s) given.
double deScaledDuRms(const test::Supersampled& ss, bool cubic, double degrees) {
  WindowRegistration::Options options = paperOptions();
  options.cubic_sampling = cubic;
  WindowRegistration reg(kPaperPanorama, options);
  double du2 = 0.0;
  int count = 0;
  for (double s : {0.97, 0.98, 0.99, 1.01, 1.02, 1.03}) {
    for (const WindowMotion& w : similaritySweep(reg, ss, degrees * kDeg, s, Given::kKnown)) {
      EXPECT_TRUE(w.valid) << s;
      EXPECT_DOUBLE_EQ(w.scale, s);  // the given scale was used, not searched
      du2 += w.du * w.du;
      ++count;
    }
  }
  return std::sqrt(du2 / count);
}

TEST_P(DeScalingSampler, TheCubicSamplerReadsADeScaledWindowsShiftCloserToZero) {
  const SamplerBounds bounds = GetParam();
  const test::Supersampled ss = test::loadSupersampled(bounds.image, 1100, 110);
  REQUIRE_IMAGE(ss.image, bounds.image);
  for (double degrees : {0.0, 1.0}) {
    const std::string at = degrees == 0.0 ? "_at_0deg" : "_at_1deg";
    const double bilinear =
        testing::recordFigure("bilinear_du_rms_px" + at, deScaledDuRms(ss, false, degrees), 4);
    const double cubic =
        testing::recordFigure("cubic_du_rms_px" + at, deScaledDuRms(ss, true, degrees), 4);
    EXPECT_LT(cubic, bounds.cubic_du_rms_px) << degrees << " deg";
    EXPECT_LT(cubic, 0.9 * bilinear) << degrees << " deg";
  }
}

void PrintTo(const SamplerBounds& b, std::ostream* os) { *os << b.image; }

INSTANTIATE_TEST_SUITE_P(RealTexture, DeScalingSampler,
                         ::testing::Values(SamplerBounds{kPark, 0.0062},
                                           SamplerBounds{kIndoor, 0.0102}),
                         [](const auto& info) {
                           return std::string(info.param.image == kIndoor ? "Indoor" : "Park");
                         });

TEST(WindowRegistrationDewarp, AGivenDewarpReplacesEachWindowsOwnForItsShiftOnly) {
  const test::Supersampled ss = test::loadSupersampled(kPark, 1100, 110);
  REQUIRE_IMAGE(ss.image, kPark);
  WindowRegistration reg(kPaperPanorama, paperOptions());
  const double phi = 0.5 * kDeg, s = 1.02;
  const std::vector<WindowMotion> own = similaritySweep(reg, ss, phi, s);
  const std::vector<WindowMotion> known = similaritySweep(reg, ss, phi, s, Given::kKnown);
  const std::vector<WindowMotion> dewarp = similaritySweep(reg, ss, phi, s, Given::kDewarp);
  const std::vector<WindowMotion> none = similaritySweep(reg, ss, phi, s, Given::kNoDewarp);
  int differ = 0;
  for (std::size_t k = 0; k < own.size(); ++k) {
    ASSERT_TRUE(own[k].valid && dewarp[k].valid) << k;
    // The rotation and scale reported are the window's own, as measured without a de-warp.
    EXPECT_EQ(dewarp[k].rotation, own[k].rotation) << k;
    EXPECT_EQ(dewarp[k].scale, own[k].scale) << k;
    EXPECT_EQ(dewarp[k].rs_confidence, own[k].rs_confidence) << k;
    // The shift is measured on the window de-warped by the given values, as when they are known.
    EXPECT_EQ(dewarp[k].du, known[k].du) << k;
    EXPECT_EQ(dewarp[k].dv, known[k].dv) << k;
    differ += dewarp[k].du != own[k].du;
    // Entries without a scale leave the window to its own.
    EXPECT_EQ(none[k].du, own[k].du) << k;
    EXPECT_EQ(none[k].dv, own[k].dv) << k;
    EXPECT_EQ(none[k].scale, own[k].scale) << k;
  }
  EXPECT_GT(differ, static_cast<int>(own.size()) / 2);  // the own values are not exact
}

// ---------------------------------------------------------------------------------------
// (d) Whole panorama: windows wrap around u
// ---------------------------------------------------------------------------------------

TEST(WindowRegistrationPanorama, WindowsWrapAroundU) {
  for (const char* name : {kIndoor, kPark}) {
    const cv::Mat& eq = equirect(name);
    REQUIRE_IMAGE(eq, name);
    WindowRegistration reg(kPaperPanorama, paperOptions());
    reg.setReference(test::fourierShiftedBand(eq, eq.rows / 2, 110, 0.0, 0.0));
    // The whole (periodic) panorama circularly shifted by 7.3 px in u.
    const auto out = measureAll(reg, test::fourierShiftedBand(eq, eq.rows / 2, 110, -7.3, 0.0));
    for (int k = 0; k < reg.windowCount(); ++k) {
      const bool crosses_seam = k * 20 + 110 > 1100;
      ASSERT_TRUE(out[k].valid) << name << " window " << k;
      EXPECT_NEAR(out[k].du, 7.3, 0.05) << name << " window " << k << (crosses_seam ? " (crosses u = W)" : "");
      EXPECT_NEAR(out[k].dv, 0.0, 0.05) << name << " window " << k;
    }
  }
}

TEST(WindowRegistrationPanorama, WindowSmallerThanHeightIsVerticallyCentredAndWOddToStep) {
  const cv::Mat& eq = equirect(kPark);
  REQUIRE_IMAGE(eq, kPark);
  WindowRegistration::Options o;
  o.window = 96;  // rows 16 .. 111 of a 128-row panorama
  WindowRegistration reg(cv::Size(1100, 128), o);
  const cv::Mat reference = test::fourierShiftedBand(eq, eq.rows / 2, 128, 0.0, 0.0);
  cv::Mat current = test::fourierShiftedBand(eq, eq.rows / 2, 128, -1.5, -0.5);
  // Rows outside the window band must not matter: replace them with unrelated noise.
  cv::Mat noise(16, 1100, CV_32F);
  cv::randu(noise, 0.0, 255.0);
  noise.copyTo(current.rowRange(0, 16));
  cv::randu(noise, 0.0, 255.0);
  noise.copyTo(current.rowRange(112, 128));
  reg.setReference(reference);
  const auto out = measureAll(reg, current);
  for (const WindowMotion& w : out) {
    ASSERT_TRUE(w.valid);
    EXPECT_NEAR(w.du, 1.5, 0.05);
    EXPECT_NEAR(w.dv, 0.5, 0.05);
  }
}

TEST(WindowRegistrationPanorama, SmallWindowsWork) {
  const cv::Mat eq = test::loadEquirect(kPark, 320);
  REQUIRE_IMAGE(eq, kPark);
  WindowRegistration::Options o;
  o.window = 32;
  o.step = 16;
  WindowRegistration reg(cv::Size(320, 48), o);
  reg.setReference(test::fourierShiftedBand(eq, eq.rows / 2, 48, 0.0, 0.0));
  const auto out = measureAll(reg, test::fourierShiftedBand(eq, eq.rows / 2, 48, -1.3, 0.6));
  int valid = 0;
  for (const WindowMotion& w : out) {
    if (!w.valid) continue;
    ++valid;
    EXPECT_NEAR(w.du, 1.3, 0.1);
    EXPECT_NEAR(w.dv, -0.6, 0.1);
  }
  EXPECT_GE(valid, reg.windowCount() - 2);
}

// ---------------------------------------------------------------------------------------
// (e) Texture and confidence
// ---------------------------------------------------------------------------------------

TEST(WindowRegistrationConfidence, ConstantPanoramaIsInvalid) {
  WindowRegistration reg(kPaperPanorama, paperOptions());
  const cv::Mat flat(110, 1100, CV_32FC1, cv::Scalar(97.0f));
  reg.setReference(flat);
  for (const WindowMotion& w : measureAll(reg, flat)) {
    EXPECT_FALSE(w.valid);
    EXPECT_EQ(w.confidence, 0.0);
    EXPECT_EQ(w.rs_confidence, 0.0);
    EXPECT_EQ(w.du, 0.0);
  }
  // A textured reference against a flat current frame: nothing to match either.
  const cv::Mat textured = horizonBand(kIndoor);
  REQUIRE_IMAGE(textured, kIndoor);
  reg.setReference(textured);
  for (const WindowMotion& w : measureAll(reg, flat)) EXPECT_FALSE(w.valid);
}

TEST(WindowRegistrationConfidence, FlatRegionsAreInvalidTexturedOnesValid) {
  cv::Mat pano = horizonBand(kPark);
  REQUIRE_IMAGE(pano, kPark);
  pano.colRange(0, 500).setTo(cv::Scalar(120.0f));  // windows 0 .. 19 lie inside
  WindowRegistration reg(kPaperPanorama, paperOptions());
  reg.setReference(pano);
  const auto out = measureAll(reg, pano);
  for (int k = 0; k + 5 < 25; ++k) EXPECT_FALSE(out[k].valid) << k;
  for (int k = 25; k < 50; ++k) {
    EXPECT_TRUE(out[k].valid) << k;
    EXPECT_GT(out[k].confidence, 0.9) << k;  // identical frames: a perfect peak
  }
}

TEST(WindowRegistrationConfidence, UnrelatedTextureHasLowConfidence) {
  const cv::Mat park = horizonBand(kPark), indoor = horizonBand(kIndoor);
  REQUIRE_IMAGE(park, kPark);
  REQUIRE_IMAGE(indoor, kIndoor);
  WindowRegistration reg(kPaperPanorama, paperOptions());
  reg.setReference(park);
  const auto out = measureAll(reg, indoor);
  int confident = 0;
  for (const WindowMotion& w : out) confident += w.confidence > 0.1;
  EXPECT_LE(confident, 2) << "noise peaks should stay near the floor";
}

// ---------------------------------------------------------------------------------------
// Reference bookkeeping: advance(), keep_as_next
// ---------------------------------------------------------------------------------------

void expectSame(const std::vector<WindowMotion>& a, const std::vector<WindowMotion>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    EXPECT_DOUBLE_EQ(a[k].du, b[k].du) << k;
    EXPECT_DOUBLE_EQ(a[k].dv, b[k].dv) << k;
    EXPECT_DOUBLE_EQ(a[k].rotation, b[k].rotation) << k;
    EXPECT_DOUBLE_EQ(a[k].scale, b[k].scale) << k;
    EXPECT_DOUBLE_EQ(a[k].confidence, b[k].confidence) << k;
    EXPECT_EQ(a[k].valid, b[k].valid) << k;
  }
}

TEST(WindowRegistrationReference, AdvanceEqualsSettingTheMeasuredFrameAsReference) {
  const cv::Mat& eq = equirect(kPark);
  REQUIRE_IMAGE(eq, kPark);
  const int c = eq.rows / 2;
  const cv::Mat a = test::fourierShiftedBand(eq, c, 110, 0.0, 0.0);
  const cv::Mat b = test::fourierShiftedBand(eq, c, 110, 0.7, -0.3);
  const cv::Mat d = test::fourierShiftedBand(eq, c, 110, 1.9, 0.4);

  WindowRegistration chained(kPaperPanorama, paperOptions());
  chained.setReference(a);
  measureAll(chained, b, true);
  measureAll(chained, d, false);  // a re-registration must not replace the candidate (b)
  chained.advance();
  const auto via_advance = measureAll(chained, d);

  WindowRegistration fresh(kPaperPanorama, paperOptions());
  fresh.setReference(b);
  const auto via_set = measureAll(fresh, d);
  expectSame(via_advance, via_set);
  for (const WindowMotion& w : via_set) {
    // Content at x in d is base content from x - (1.9, 0.4); b holds it at x - (1.2, 0.7).
    EXPECT_NEAR(w.du, -1.2, 0.05);
    EXPECT_NEAR(w.dv, -0.7, 0.05);
  }
}

TEST(WindowRegistrationReference, AdvanceWithoutMeasureKeepsTheReference) {
  const cv::Mat& eq = equirect(kIndoor);
  REQUIRE_IMAGE(eq, kIndoor);
  const cv::Mat a = test::fourierShiftedBand(eq, eq.rows / 2, 110, 0.0, 0.0);
  const cv::Mat b = test::fourierShiftedBand(eq, eq.rows / 2, 110, -0.6, 0.0);
  WindowRegistration reg(kPaperPanorama, paperOptions());
  reg.setReference(a);
  const auto before = measureAll(reg, b, false);
  reg.advance();  // nothing measured with keep_as_next: no-op
  expectSame(measureAll(reg, b, false), before);
}

// ---------------------------------------------------------------------------------------
// Motion blur (setMotionBlur())
// ---------------------------------------------------------------------------------------

/// The current band moved by (du, 0) and blurred along `path` (du's sense, pixels): the mean
/// of the exactly shifted bands, as a row exposed while the camera turns.
cv::Mat blurredBand(const cv::Mat& eq, double du, const std::vector<float>& path) {
  cv::Mat sum = cv::Mat::zeros(110, 1100, CV_32F);
  for (float x : path) sum += test::fourierShiftedBand(eq, eq.rows / 2, 110, -(du + x), 0.0);
  return sum / static_cast<double>(path.size());
}

/// A turn that speeds up over the exposure: the path x(t) = L t^2, t in [0, 1] (a blur L px
/// long, its mean L / 3 and its kernel lopsided).
std::vector<float> speedingUpPath(double length, int samples) {
  std::vector<float> path(samples);
  for (int j = 0; j < samples; ++j) {
    const double t = (j + 0.5) / samples;
    path[j] = static_cast<float>(length * t * t);
  }
  return path;
}

TEST(WindowRegistrationMotionBlur, ALopsidedBlurIsMeasuredAtItsMeanShift) {
  // Both frames blurred along a speeding-up path 4 px long (the current one 3 px further on):
  // the correlation's peak is not at the kernels' mean shift, and with their phases taken
  // out it is.
  for (const char* name : {kIndoor, kPark}) {
    const cv::Mat& eq = equirect(name);
    REQUIRE_IMAGE(eq, name);
    constexpr int kSamples = 32;
    const double shift = 0.6;
    const std::vector<float> reference_path = speedingUpPath(2.0, kSamples);
    const std::vector<float> current_path = speedingUpPath(4.0, kSamples);
    const double mean_ref = 2.0 / 3.0, mean_cur = 4.0 / 3.0;
    const cv::Mat reference = blurredBand(eq, 0.0, reference_path);
    const cv::Mat current = blurredBand(eq, shift, current_path);
    const double expected = shift + mean_cur - mean_ref;

    auto errors = [&](bool remove_blur) {
      WindowRegistration reg(kPaperPanorama, paperOptions());
      std::vector<float> paths;
      auto give = [&](const std::vector<float>& path) {
        paths.clear();
        for (int k = 0; k < reg.windowCount(); ++k) paths.insert(paths.end(), path.begin(), path.end());
        reg.setMotionBlur(remove_blur ? std::span<const float>(paths) : std::span<const float>(),
                          kSamples);
      };
      give(reference_path);
      reg.setReference(reference);
      give(current_path);
      double sum_sq = 0.0;
      int valid = 0;
      for (const WindowMotion& w : measureAll(reg, current, false)) {
        if (!w.valid) continue;
        sum_sq += (w.du - expected) * (w.du - expected);
        ++valid;
      }
      EXPECT_GT(valid, reg.windowCount() * 9 / 10) << name;
      return std::sqrt(sum_sq / std::max(valid, 1));
    };
    const double plain = errors(false), removed = errors(true);
    testing::recordFigure(std::string(name == kIndoor ? "indoor" : "park") + "_plain_rms_px", plain, 4);
    testing::recordFigure(std::string(name == kIndoor ? "indoor" : "park") + "_removed_rms_px", removed, 4);
    // Achieved: 0.529 px plain (the peak sits near the kernels' slow ends, where they pile
    // up), 0.005 (indoor) and 0.003 (park) px with the phases taken out.
    EXPECT_GT(plain, 0.3) << name << ": the lopsided blur no longer biases the peak";
    EXPECT_LT(removed, 0.02) << name;
  }
}

TEST(WindowRegistrationMotionBlur, AShortUnusableOrClearedBlurChangesNothing) {
  const cv::Mat& eq = equirect(kIndoor);
  REQUIRE_IMAGE(eq, kIndoor);
  const cv::Mat a = test::fourierShiftedBand(eq, eq.rows / 2, 110, 0.0, 0.0);
  const cv::Mat b = test::fourierShiftedBand(eq, eq.rows / 2, 110, -0.6, 0.0);
  WindowRegistration plain(kPaperPanorama, paperOptions());
  plain.setReference(a);
  const auto expected = measureAll(plain, b, false);

  WindowRegistration reg(kPaperPanorama, paperOptions());
  const int samples = 8;
  // Shorter than kMinBlurExtentPx in every window: left alone.
  std::vector<float> short_paths(static_cast<std::size_t>(reg.windowCount()) * samples);
  for (std::size_t i = 0; i < short_paths.size(); ++i)
    short_paths[i] = static_cast<float>(0.9 * WindowRegistration::kMinBlurExtentPx *
                                        static_cast<double>(i % samples) / (samples - 1));
  reg.setMotionBlur(short_paths, samples);
  reg.setReference(a);
  expectSame(measureAll(reg, b, false), expected);
  // Paths no window can use: not finite, or longer than kMaxBlurExtentPx.
  std::vector<float> unusable(short_paths.size());
  for (std::size_t i = 0; i < unusable.size(); ++i)
    unusable[i] = (i / samples) % 2 == 0 ? std::numeric_limits<float>::quiet_NaN()
                                         : static_cast<float>(i % samples) * 10.0f;
  reg.setMotionBlur(unusable, samples);
  reg.setReference(a);
  expectSame(measureAll(reg, b, false), expected);
  // A long blur given, then cleared (too few values clear it as well).
  std::vector<float> long_paths(short_paths.size());
  for (std::size_t i = 0; i < long_paths.size(); ++i) long_paths[i] = static_cast<float>(i % samples);
  reg.setMotionBlur(long_paths, samples);
  reg.setMotionBlur(std::span<const float>(long_paths).first(long_paths.size() - 1), samples);
  reg.setReference(a);
  expectSame(measureAll(reg, b, false), expected);
}

}  // namespace
}  // namespace omnipose
