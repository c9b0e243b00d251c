// omnipose-plot-fit: the paper's Fig. 4 for one frame pair of a dataset: the two
// panoramas, the du and dv that iFMI measured per window (first, linear pass of the
// pipeline) and the sinusoids of the fitted motion model (DESIGN.md section 3); with the
// ground-truth sinusoids when the dataset has groundtruth.tum and the pair does not
// translate (tau needs the unknown scene distance).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "chart.hpp"
#include "cli.hpp"
#include "daemon/config.hpp"
#include "omnipose/io/dataset.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/motion_fit.hpp"
#include "omnipose/motion_model.hpp"
#include "omnipose/pipeline.hpp"
#include "quiet_opencv.hpp"

namespace {

using namespace omnipose;

/// Ground-truth relative pose of frame k w.r.t. k-1, if both poses are in the file.
std::optional<Eigen::Isometry3d> groundTruthStep(const Dataset& d, int k) {
  if (!d.groundtruth) return std::nullopt;
  auto find = [&](double t) -> const StampedPose* {
    for (const StampedPose& p : *d.groundtruth)
      if (std::abs(p.timestamp - t) < 1e-3) return &p;
    return nullptr;
  };
  const StampedPose* a = find(d.frames[k - 1].timestamp);
  const StampedPose* b = find(d.frames[k].timestamp);
  if (!a || !b) return std::nullopt;
  return a->pose.inverse() * b->pose;
}

/// The command line, as parsed.
struct Args {
  std::string dataset_dir, out, config, pair_text, input_text;
  int width = 1400;
};

void addOptions(CLI::App& app, Args& a) {
  app.add_option("DATASET", a.dataset_dir, "dataset directory (calibration.yaml, frames/, ...)")
      ->required();
  app.add_option("--pair", a.pair_text,
                 "the frame pair (K-1, K), K >= 1 a frame index; max: the pair with the "
                 "largest ground-truth rotation")
      ->type_name("K|max")
      ->required()
      ->check(CLI::Validator(
          [](std::string& v) -> std::string {
            if (v == "max") return {};
            try {
              std::size_t pos = 0;
              if (std::stoi(v, &pos) >= 1 && pos == v.size()) return {};
            } catch (const std::exception&) {
            }
            return "must be a frame index >= 1 or max, not '" + v + "'";
          },
          "", ""));
  app.add_option("--out", a.out, "figure to write (PNG)")->type_name("FIG.png")->required();
  app.add_option("--config", a.config, "daemon.yaml whose input/pipeline sections are used")
      ->type_name("daemon.yaml");
  app.add_option("--input", a.input_text, "frames are omni donuts (default) or panoramas")
      ->type_name("omni|panorama")
      ->check(tools::oneOf({"omni", "panorama"}));
  app.add_option("--width", a.width, "figure width, pixels")
      ->type_name("PIXELS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

/// The pair's K: --pair K, or with --pair max the pair with the largest ground-truth rotation.
int choosePair(const Dataset& d, const std::string& pair_text) {
  int pair = -1;
  if (pair_text == "max") {
    double best = -1.0;
    for (int k = 1; k < static_cast<int>(d.frames.size()); ++k) {
      if (const auto gt = groundTruthStep(d, k)) {
        const double angle = rotationVector(gt->linear()).norm();
        if (angle > best) best = angle, pair = k;
      }
    }
    if (pair < 1) throw std::invalid_argument("--pair max: the dataset has no ground truth");
  } else {
    pair = std::stoi(pair_text);
  }
  if (pair >= static_cast<int>(d.frames.size()))
    throw std::invalid_argument("--pair " + std::to_string(pair) + ": the dataset has " +
                                std::to_string(d.frames.size()) + " frames");
  return pair;
}

/// What the pipeline measured for the pair (K-1, K), and the first-pass linear fit to
/// exactly these windows (what the sinusoids describe).
struct MeasuredPair {
  cv::Mat previous_panorama, panorama;
  std::vector<WindowMotion> windows;
  MotionEstimate linear;
  double kappa = 0.0;
};

MeasuredPair measurePair(const Dataset& d, const Args& a, int pair) {
  PipelineOptions options;
  if (!a.config.empty()) options = DaemonConfig::load(a.config, DaemonConfig::Use::kReplay).pipeline;
  if (a.input_text == "omni") options.unwrap.input = InputKind::kOmni;
  else if (a.input_text == "panorama") options.unwrap.input = InputKind::kPanorama;
  Pipeline pipeline(d.calibration, options);

  // Frame K-1 becomes the reference, frame K is measured against it.
  MeasuredPair result;
  for (int k : {pair - 1, pair}) {
    auto image = readFrame(d.frames[k].path, inputFrameSize(d.calibration, options.unwrap.input));
    if (!image) throw std::runtime_error(std::string(image.error().message()));
    auto m = pipeline.process(*image);
    if (!m) throw std::runtime_error(d.frames[k].path.string() + ": " + m.error().c_str());
    if (k == pair - 1) result.previous_panorama = pipeline.lastPanorama().clone();
  }
  result.panorama = pipeline.lastPanorama().clone();
  result.windows.assign(pipeline.lastWindows().begin(), pipeline.lastWindows().end());
  MotionFit fit(options.fit, d.calibration.panorama.gamma(), options.registration.window,
                static_cast<int>(result.windows.size()));
  result.linear = fit.fit(result.windows, d.calibration.panorama.forward_column);
  result.kappa = fit.kappa();
  return result;
}

/// The figure: both panoramas, then du and dv per window with the fitted (and, for a pair
/// that does not translate, the true) sinusoids.
cv::Mat drawFigure(const Dataset& d, const MeasuredPair& m, int pair, int width) {
  const PanoramaGeometry& g = d.calibration.panorama;
  const double gamma = g.gamma();
  // Measured points: valid windows filled, invalid ones hollow.
  plot::Series du_ok{{}, {}, plot::paletteColor(0), "measured (iFMI)", plot::Style::kMarkers, 1};
  plot::Series dv_ok = du_ok;
  plot::Series du_bad{{}, {}, {150, 150, 150}, "invalid window", plot::Style::kHollowMarkers, 1};
  plot::Series dv_bad = du_bad;
  for (const WindowMotion& w : m.windows) {
    plot::Series& su = w.valid ? du_ok : du_bad;
    plot::Series& sv = w.valid ? dv_ok : dv_bad;
    su.x.push_back(w.center_u);
    su.y.push_back(w.du);
    sv.x.push_back(w.center_u);
    sv.y.push_back(w.dv);
  }

  // Sinusoids of a motion x over every column.
  auto curves = [&](const Eigen::Matrix<double, 6, 1>& x, cv::Scalar color, std::string label,
                    plot::Style style) {
    plot::Series u{{}, {}, color, label, style, 2}, v = u;
    for (int c = 0; c <= g.width; c += 2) {
      const ModelMotion p = predictMotion(x, g.azimuth(c), m.kappa);
      u.x.push_back(c);
      u.y.push_back(p.du_rad / gamma);
      v.x.push_back(c);
      v.y.push_back(p.dv_rad / gamma);
    }
    return std::pair{u, v};
  };
  char label[160];
  const Eigen::Vector3d w_deg = m.linear.omega * 180.0 / M_PI;
  std::snprintf(label, sizeof(label), "fit: omega = (%.2f, %.2f, %.2f) deg", w_deg.x(), w_deg.y(),
                w_deg.z());
  auto [fit_u, fit_v] = curves(m.linear.vector(), plot::paletteColor(3), label, plot::Style::kLine);

  plot::Chart du_chart("du per window (pair " + std::to_string(pair - 1) + " -> " +
                           std::to_string(pair) + ")",
                       "panorama column u (u0 = +x axis)", "du [px]");
  plot::Chart dv_chart("dv per window", "panorama column u (u0 = +x axis)", "dv [px]");
  if (const auto gt = groundTruthStep(d, pair); gt && gt->translation().norm() < 1e-9) {
    Eigen::Matrix<double, 6, 1> x = Eigen::Matrix<double, 6, 1>::Zero();
    x.head<3>() = rotationVector(gt->linear());
    const Eigen::Vector3d t_deg = x.head<3>() * 180.0 / M_PI;
    std::snprintf(label, sizeof(label), "truth: omega = (%.2f, %.2f, %.2f) deg", t_deg.x(),
                  t_deg.y(), t_deg.z());
    auto [gt_u, gt_v] = curves(x, {0, 0, 0}, label, plot::Style::kDashed);
    du_chart.add(gt_u);
    dv_chart.add(gt_v);
  }
  for (plot::Chart* c : {&du_chart, &dv_chart}) c->setXRange(0, g.width);
  du_chart.setMinRightMargin(320);
  dv_chart.setMinRightMargin(320);
  du_chart.add(fit_u);
  dv_chart.add(fit_v);
  du_chart.add(du_ok);
  dv_chart.add(dv_ok);
  if (!du_bad.x.empty()) {
    du_chart.add(du_bad);
    dv_chart.add(dv_bad);
  }

  return plot::stackVertical({
      plot::captioned(m.previous_panorama, width,
                      "(a) frame " + std::to_string(pair - 1) + ": " +
                          d.frames[pair - 1].path.filename().string(),
                      plot::Chart::kLeftMargin, du_chart.rightMargin()),
      plot::captioned(m.panorama, width,
                      "(b) frame " + std::to_string(pair) + ": " +
                          d.frames[pair].path.filename().string(),
                      plot::Chart::kLeftMargin, du_chart.rightMargin()),
      du_chart.render({width, 330}),
      dv_chart.render({width, 330}),
  });
}

constexpr const char* kUsage =
    "usage: omnipose-plot-fit DATASET --pair K|max --out FIG.png\n"
    "                         [--config daemon.yaml] [--input omni|panorama]\n"
    "                         [--width PIXELS]";

constexpr const char* kDescription =
    "Fig. 4 of the paper for the frame pair (K-1, K): both panoramas, the du and\n"
    "dv (pixels) measured by iFMI per window and the fitted sinusoids (+ ground\n"
    "truth). Exit codes: 0 drawn, 1 failed, 2 bad command line.";

int run(const tools::Cli&, Args& a) {

  const Dataset d = Dataset::open(a.dataset_dir);
  const int pair = choosePair(d, a.pair_text);
  const MeasuredPair m = measurePair(d, a, pair);
  const cv::Mat figure = drawFigure(d, m, pair, a.width);
  if (!cv::imwrite(a.out, figure, {cv::IMWRITE_PNG_COMPRESSION, 9}))
    throw std::runtime_error(a.out + ": cannot write");
  const auto valid = std::count_if(m.windows.begin(), m.windows.end(),
                                   [](const WindowMotion& w) { return w.valid; });
  std::printf("omnipose-plot-fit: %s: pair %d, %d of %zu windows valid, linear fit omega = "
              "(%.5f, %.5f, %.5f) rad, status %s\n",
              a.out.c_str(), pair, static_cast<int>(valid), m.windows.size(),
              m.linear.omega.x(), m.linear.omega.y(), m.linear.omega.z(), toString(m.linear.status));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  omnipose::tools::quietOpenCvWarnings();
  return omnipose::tools::runMain<Args>(argc, argv, {"omnipose-plot-fit", kUsage, kDescription}, addOptions,
                                        run);
}
