// omnipose-plot-angles: the paper's Fig. 5 for one sequence: the per-frame rotation about
// one axis (relative rotation vector of each consecutive pair, as omnipose-eval scores it)
// of the ground truth and of every estimate, with each method's RMSE in the legend; below,
// the per-frame error of each method. Missing pairs (lost) are gaps.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "chart.hpp"
#include "cli.hpp"
#include "omnipose/eval/evaluation.hpp"
#include "omnipose/io/trajectory.hpp"

namespace {

using namespace omnipose;
constexpr double kDeg = 180.0 / M_PI;

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> parts;
  std::stringstream in(s);
  for (std::string p; std::getline(in, p, sep);) parts.push_back(p);
  return parts;
}

/// The command line, as parsed.
struct Args {
  std::vector<std::string> files, labels;
  std::string out, title, axis_name = "auto", labels_text;
  int width = 1100;
};

void addOptions(CLI::App& app, Args& a) {
  app.add_option("FILES", a.files,
                 "GT.tum EST.tum [EST2.tum ...]: the ground-truth trajectory, then one or more "
                 "estimated ones (TUM format)")
      ->required();
  app.add_option("--out", a.out, "figure to write (PNG)")->type_name("FIG.png")->required();
  app.add_option("--labels", a.labels_text,
                 "legend name of each estimate, comma-separated (default: the file names)")
      ->type_name("A,B,...");
  app.add_option("--axis", a.axis_name,
                 "the rotation axis drawn; auto takes the axis the ground truth turns most about")
      ->type_name("roll|pitch|yaw|auto")
      ->check(tools::oneOf({"roll", "pitch", "yaw", "auto"}))
      ->capture_default_str();
  app.add_option("--title", a.title, "figure title")->type_name("TEXT");
  app.add_option("--width", a.width, "figure width, pixels")
      ->type_name("PIXELS")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
}

/// The axis drawn: `axis_name`, or with "auto" the one the ground truth turns most about.
int chooseAxis(const std::string& axis_name, const EvaluationResult& truth) {
  int axis = -1;
  const std::map<std::string, int> axes = {{"roll", 0}, {"pitch", 1}, {"yaw", 2}};
  if (axis_name == "auto") {
    Eigen::Vector3d power = Eigen::Vector3d::Zero();
    for (const PairError& p : truth.pairs) power += p.gt_rotvec.cwiseAbs2();
    power.maxCoeff(&axis);
  } else if (auto it = axes.find(axis_name); it != axes.end()) {
    axis = it->second;
  } else {
    throw std::invalid_argument("--axis must be roll, pitch, yaw or auto, not '" + axis_name + "'");
  }
  return axis;
}

const char* const kAxisNames[] = {"roll (x)", "pitch (y)", "yaw (z)"};

/// The figure: the angles of the ground truth and every estimate above, their errors below.
cv::Mat drawFigure(const Args& a, const std::vector<StampedPose>& gt,
                   const EvaluationResult& truth, int axis) {
  const std::vector<std::string>& files = a.files;
  const std::vector<std::string>& labels = a.labels;
  const std::string& title = a.title;
  const int width = a.width;
  // Frame index of each ground-truth timestamp: pair (k-1, k) is drawn at k.
  auto frameOf = [&](double t) {
    for (std::size_t k = 0; k < gt.size(); ++k)
      if (std::abs(gt[k].timestamp - t) < 1e-3) return static_cast<double>(k);
    return std::numeric_limits<double>::quiet_NaN();
  };

  plot::Chart angles(title.empty() ? std::string("rotation about ") + kAxisNames[axis] : title,
                     "frame", std::string(kAxisNames[axis]) + " per frame [deg]");
  std::vector<plot::Series> error_series;
  std::vector<double> rmses;  // per estimate, radians
  plot::Series gt_series{{}, {}, {0, 0, 0}, "ground truth", plot::Style::kDashed, 2};
  for (const PairError& p : truth.pairs) {
    gt_series.x.push_back(frameOf(p.t));
    gt_series.y.push_back(p.gt_rotvec[axis] * kDeg);
  }
  const double x_max = gt.empty() ? 1.0 : static_cast<double>(gt.size() - 1);

  for (std::size_t f = 1; f < files.size(); ++f) {
    const EvaluationResult r = evaluate(gt, readTum(files[f]));
    // One point per ground-truth pair; NaN where the estimate has none (a gap).
    std::map<double, const PairError*> by_frame;
    for (const PairError& p : r.pairs) by_frame[frameOf(p.t)] = &p;
    plot::Series est{{}, {}, plot::paletteColor(static_cast<int>(f - 1)), "",
                     plot::Style::kLineMarkers, 2};
    plot::Series err = est;
    for (const PairError& p : truth.pairs) {
      const double k = frameOf(p.t);
      const auto it = by_frame.find(k);
      est.x.push_back(k);
      err.x.push_back(k);
      est.y.push_back(it == by_frame.end() ? NAN : it->second->est_rotvec[axis] * kDeg);
      err.y.push_back(it == by_frame.end() ? NAN : it->second->rotvec_error[axis] * 1e3);
    }
    const ErrorStats& s = axis == 0 ? r.roll : axis == 1 ? r.pitch : r.yaw;
    if (s.count > 0) rmses.push_back(s.rmse);
    char label[160];
    std::snprintf(label, sizeof(label), "%s (mu = %.3f mrad%s)",
                  labels.empty() ? files[f].c_str() : labels[f - 1].c_str(), 1e3 * s.rmse,
                  r.pairs_missing > 0 ? (", " + std::to_string(r.pairs_missing) + " lost").c_str()
                                      : "");
    est.label = label;
    angles.add(est);
    error_series.push_back(std::move(err));
  }
  angles.add(gt_series);  // last: drawn on top of the estimates
  // Error panel zoomed to the two most accurate estimates (4x the second-best RMSE), so
  // their errors stay visible next to methods that are 100x worse.
  std::sort(rmses.begin(), rmses.end());
  const bool zoom = rmses.size() > 2;
  plot::Chart errors(zoom ? "error (estimate - truth), zoomed to the two best methods"
                          : "error (estimate - truth)",
                     "frame", std::string(kAxisNames[axis]) + " error [mrad]");
  if (zoom) {
    const double half = 4e3 * std::max(rmses[1], 1e-6);  // mrad
    errors.setYRange(-half, half);
  }
  for (plot::Series& e : error_series) errors.add(std::move(e));
  errors.setMinRightMargin(angles.rightMargin());
  angles.setXRange(0, x_max);
  errors.setXRange(0, x_max);

  return plot::stackVertical({angles.render({width, 420}), errors.render({width, 260})});
}

constexpr const char* kUsage =
    "usage: omnipose-plot-angles GT.tum EST.tum [EST2.tum ...] --out FIG.png\n"
    "                            [--labels A,B,...] [--axis roll|pitch|yaw|auto]\n"
    "                            [--title TEXT] [--width PIXELS]";

constexpr const char* kDescription =
    "Fig. 5 of the paper: per-frame rotation about one axis (degrees) of the\n"
    "ground truth and each estimate, RMSE (mrad) in the legend, errors below.\n"
    "Exit codes: 0 drawn, 1 failed, 2 bad command line.";

int run(const tools::Cli& cli, Args& a) {
  if (a.files.size() < 2) return cli.usageError("FILES: give GT.tum and at least one EST.tum");
  if (cli.app().count("--labels") > 0) a.labels = split(a.labels_text, ',');
  if (!a.labels.empty() && a.labels.size() != a.files.size() - 1)
    return cli.usageError("--labels: " + std::to_string(a.labels.size()) + " labels for " +
                          std::to_string(a.files.size() - 1) + " estimates");

  const std::vector<StampedPose> gt = readTum(a.files[0]);
  const EvaluationResult truth = evaluate(gt, gt);
  const int axis = chooseAxis(a.axis_name, truth);
  const cv::Mat figure = drawFigure(a, gt, truth, axis);
  if (!cv::imwrite(a.out, figure, {cv::IMWRITE_PNG_COMPRESSION, 9}))
    throw std::runtime_error(a.out + ": cannot write");
  std::printf("omnipose-plot-angles: %s (%s, %zu estimates)\n", a.out.c_str(), kAxisNames[axis],
              a.files.size() - 1);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return omnipose::tools::runMain<Args>(argc, argv, {"omnipose-plot-angles", kUsage, kDescription}, addOptions,
                                        run);
}
