// omnipose-plot-uncertainty: does each window's predicted (du, dv) variance
// (WindowMotion::var_du, var_dv) agree with the error the noise actually causes, on renders?
//
// For each texture, random frame pairs are rendered through the lens (the exact renderer:
// a random attitude, then a rotation step of 0.5-3 deg about a random axis) and registered
// by the pipeline's first pass twice: once noise-free and several times with Gaussian sensor
// noise of known sigma in both frames (8-bit, as a camera delivers them). A window's error is
// its noisy shift minus its noise-free shift: the part of the error the variance describes
// (what the lens, the texture or the first-order model add is the same in both and cancels).
//
// The variances are for panorama noise of unit variance; the unwrap filters the sensor's
// noise by an amount that depends on the lens and the row, so one scale s per texture,
// pooled over du and dv, turns them into pixels^2 (the motion fit likewise estimates it
// from its residuals). What is checked is therefore the shape: whether a window predicted
// to know its dv 3x worse than another, or worse than its own du, does. The figure bins the
// windows by predicted standard deviation (equal counts) and draws the RMS observed error
// of each bin against its RMS prediction, du and dv apart: on the diagonal is calibrated.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "chart.hpp"
#include "cli.hpp"
#include "daemon/config.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "quiet_opencv.hpp"

namespace {

using namespace omnipose;

constexpr const char* kUsage =
    "usage: omnipose-plot-uncertainty --texture PHOTO [--texture PHOTO ...] --out FIG.png\n"
    "                                 [--calibration CAL.yaml] [--pairs N] [--draws N]\n"
    "                                 [--noise SIGMA] [--bins N] [--seed S] [--width PIXELS]\n"
    "                                 [--supersample K] [--table TABLE.md] [--label NAME ...]\n"
    "                                 [--config daemon.yaml]";
constexpr const char* kDescription =
    "Calibration of the per-window shift uncertainty on renders: frame pairs of each\n"
    "texture (equirectangular photo) rendered through the lens, registered noise-free and\n"
    "with sensor noise; the RMS error of the noisy shifts against their predicted standard\n"
    "deviation, du and dv apart, in bins of equal count (one noise scale per texture).\n"
    "Prints a table of the bins. Exit codes: 0 drawn, 1 failed, 2 bad command line.";

struct Args {
  std::vector<std::string> textures, labels;
  std::string out, calibration, table, config;
  int pairs = 12, draws = 4, bins = 6, width = 1000, supersample = 3;
  double noise = 3.0;
  unsigned seed = 29;
};

/// One valid window of one noisy registration: its errors and its predicted variances
/// (unit panorama noise).
struct Sample {
  double err_u, err_v, var_u, var_v;
};

/// What the noise does to the mean shift over a registration's windows (the yaw is the
/// mean du): its error with every window alike and with each weighted by its inverse
/// variance. Measured rather than derived from the variances: windows overlap, so their
/// errors correlate.
struct MeanErrors {
  double plain_u = 0.0, weighted_u = 0.0, plain_v = 0.0, weighted_v = 0.0;
};

struct Measurements {
  std::vector<Sample> windows;
  std::vector<MeanErrors> means;  ///< one per noisy registration
};

/// The plain and inverse-variance-weighted means of `samples`' errors.
MeanErrors meanErrors(std::span<const Sample> samples) {
  MeanErrors m;
  double wu = 0.0, wv = 0.0;
  for (const Sample& s : samples) {
    m.plain_u += s.err_u / samples.size();
    m.plain_v += s.err_v / samples.size();
    m.weighted_u += s.err_u / s.var_u, wu += 1.0 / s.var_u;
    m.weighted_v += s.err_v / s.var_v, wv += 1.0 / s.var_v;
  }
  m.weighted_u /= wu;
  m.weighted_v /= wv;
  return m;
}

double median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

/// The median of |z| for z ~ N(0, 1).
constexpr double kMedianAbsNormal = 0.6745;

struct Bin {
  double predicted = 0.0;  ///< RMS predicted standard deviation, pixels
  double observed = 0.0;   ///< RMS error, pixels
  double robust = 0.0;     ///< median |error / predicted sd| / kMedianAbsNormal (1: calibrated)
};

/// Equal-count bins of (predicted variance, error) pairs ordered by the variance; `scale2`
/// turns the variances into pixels^2.
std::vector<Bin> calibrationBins(std::vector<std::pair<double, double>> var_err, double scale2,
                                 int bins) {
  std::sort(var_err.begin(), var_err.end());
  std::vector<Bin> out;
  const std::size_t n = var_err.size();
  for (int b = 0; b < bins; ++b) {
    const std::size_t lo = n * b / bins, hi = n * (b + 1) / bins;
    if (hi <= lo) continue;
    double v = 0.0, e2 = 0.0;
    std::vector<double> z;
    for (std::size_t i = lo; i < hi; ++i) {
      const auto [var, err] = var_err[i];
      v += var, e2 += err * err;
      z.push_back(std::abs(err) / std::sqrt(scale2 * var));
    }
    const double count = static_cast<double>(hi - lo);
    out.push_back({std::sqrt(scale2 * v / count), std::sqrt(e2 / count),
                   median(z) / kMedianAbsNormal});
  }
  return out;
}

/// Every window of frame pair (a, b) through `pipeline` (valid or not): false when the
/// pipeline rejected a frame.
bool registerPair(Pipeline& pipeline, const cv::Mat& a, const cv::Mat& b,
                  std::vector<WindowMotion>& windows) {
  pipeline.reset();
  for (const cv::Mat* frame : {&a, &b}) {
    if (!pipeline.process(*frame)) return false;
  }
  windows.assign(pipeline.lastWindows().begin(), pipeline.lastWindows().end());
  return true;
}

/// Noisy-minus-clean errors of every window valid in both, over `a.pairs` pairs and
/// `a.draws` noise draws each.
Measurements textureSamples(const Args& a, const std::string& texture,
                            const Calibration& calibration, PipelineOptions options,
                            std::mt19937& rng) {
  const synth::Renderer renderer(synth::Scene::load(texture, synth::SceneKind::kSphere),
                                 calibration, {synth::OutputKind::kOmni, a.supersample});
  options.registration.shift_covariance = true;
  options.refine_iterations = 0;  // the first pass's windows are the ones compared
  options.unwrap.input = InputKind::kOmni;
  Pipeline pipeline(calibration, options);

  constexpr double kDeg = std::numbers::pi / 180.0;
  std::uniform_real_distribution<double> unit(-1.0, 1.0), turn(0.0, 2.0 * std::numbers::pi),
      step(0.5 * kDeg, 3.0 * kDeg);
  Measurements out;
  std::vector<WindowMotion> clean, noisy;
  std::uint64_t frame = 0;
  for (int p = 0; p < a.pairs; ++p) {
    Eigen::Isometry3d A = Eigen::Isometry3d::Identity();
    A.linear() = rotationFromVector({5.0 * kDeg * unit(rng), 5.0 * kDeg * unit(rng), turn(rng)});
    Eigen::Vector3d axis(unit(rng), unit(rng), unit(rng));
    if (axis.norm() < 1e-3) axis = Eigen::Vector3d::UnitZ();
    Eigen::Isometry3d B = A;
    B.linear() = A.linear() * rotationFromVector(axis.normalized() * step(rng));
    const cv::Mat render_a = renderer.render(A), render_b = renderer.render(B);
    if (!registerPair(pipeline, synth::degrade(render_a, {}, 0), synth::degrade(render_b, {}, 0),
                      clean)) {
      continue;
    }
    synth::DegradeOptions noise;
    noise.noise_sigma = a.noise;
    noise.seed = a.seed;
    for (int d = 0; d < a.draws; ++d) {
      const cv::Mat noisy_a = synth::degrade(render_a, noise, frame++);
      const cv::Mat noisy_b = synth::degrade(render_b, noise, frame++);
      if (!registerPair(pipeline, noisy_a, noisy_b, noisy)) continue;
      const std::size_t first = out.windows.size();
      for (std::size_t k = 0; k < noisy.size(); ++k) {
        const WindowMotion& n = noisy[k];
        const WindowMotion& c = clean[k];
        if (!n.valid || !c.valid || n.var_du <= 0.0 || n.var_dv <= 0.0) continue;
        out.windows.push_back({n.du - c.du, n.dv - c.dv, n.var_du, n.var_dv});
      }
      if (out.windows.size() > first) {
        out.means.push_back(meanErrors(std::span(out.windows).subspan(first)));
      }
    }
  }
  return out;
}

/// What one texture's windows say: the noise scale, the bins of each axis and the RMS
/// error of the windows' mean shift (MeanErrors, pixels).
struct TextureCalibration {
  std::string name;
  std::size_t measurements = 0;
  double panorama_noise = 0.0;  ///< the scale s, grey levels
  std::vector<Bin> du, dv;
  MeanErrors mean_rms;
};

TextureCalibration calibrate(const std::string& name, const Measurements& measured, int bins) {
  const std::vector<Sample>& samples = measured.windows;
  // One scale per texture, pooled over du and dv: chi-square(1)'s median is 0.455.
  std::vector<double> z2;
  std::vector<std::pair<double, double>> u, v;
  for (const Sample& s : samples) {
    z2.push_back(s.err_u * s.err_u / s.var_u);
    z2.push_back(s.err_v * s.err_v / s.var_v);
    u.emplace_back(s.var_u, s.err_u);
    v.emplace_back(s.var_v, s.err_v);
  }
  const double scale2 = median(z2) / 0.455;
  MeanErrors rms;
  for (const MeanErrors& m : measured.means) {
    rms.plain_u += m.plain_u * m.plain_u, rms.weighted_u += m.weighted_u * m.weighted_u;
    rms.plain_v += m.plain_v * m.plain_v, rms.weighted_v += m.weighted_v * m.weighted_v;
  }
  const double n = static_cast<double>(std::max<std::size_t>(measured.means.size(), 1));
  for (double* x : {&rms.plain_u, &rms.weighted_u, &rms.plain_v, &rms.weighted_v})
    *x = std::sqrt(*x / n);
  return {name, samples.size(), std::sqrt(scale2), calibrationBins(u, scale2, bins),
          calibrationBins(v, scale2, bins), rms};
}

/// "1.24 1.09 ...": the observed over the predicted RMS of each bin, or the robust ratio.
std::string ratios(const std::vector<Bin>& bins, bool robust) {
  std::string out;
  for (const Bin& b : bins)
    out += cv::format("%s%.2f", out.empty() ? "" : " ", robust ? b.robust : b.observed / b.predicted);
  return out;
}

void writeTable(const std::string& path, const std::vector<TextureCalibration>& textures) {
  std::ofstream file(path);
  file << "| texture | windows | panorama noise | axis | predicted sd [px] | "
          "RMS ratio per bin | robust ratio per bin | mean over windows: plain / weighted [px] |\n"
          "|---|---:|---:|---|---|---|---|---|\n";
  for (const TextureCalibration& t : textures) {
    for (const auto& [axis, bins] : {std::pair{"du", &t.du}, std::pair{"dv", &t.dv}}) {
      const bool du = axis[1] == 'u';
      file << cv::format("| %s | %zu | %.2f | %s | %.4f..%.4f | %s | %s | %.4f / %.4f |\n",
                         t.name.c_str(), t.measurements, t.panorama_noise, axis,
                         bins->front().predicted, bins->back().predicted,
                         ratios(*bins, false).c_str(), ratios(*bins, true).c_str(),
                         du ? t.mean_rms.plain_u : t.mean_rms.plain_v,
                         du ? t.mean_rms.weighted_u : t.mean_rms.weighted_v);
    }
  }
  if (!file.flush()) throw std::runtime_error(path + ": cannot write");
}

int run(const Args& a) {
  const Calibration calibration =
      a.calibration.empty() ? Calibration{} : Calibration::load(a.calibration);
  const std::string lens = a.calibration.empty()
                               ? std::string("the linear lens")
                               : std::filesystem::path(a.calibration).filename().string();
  PipelineOptions options;
  if (a.config.empty()) options.threads = 0;  // every core, as omnipose-replay
  else options = DaemonConfig::load(a.config, DaemonConfig::Use::kReplay).pipeline;
  std::mt19937 rng(a.seed);
  std::vector<TextureCalibration> textures;
  for (std::size_t t = 0; t < a.textures.size(); ++t) {
    const std::string& texture = a.textures[t];
    const Measurements measured = textureSamples(a, texture, calibration, options, rng);
    if (measured.windows.size() < static_cast<std::size_t>(4 * a.bins)) {
      throw std::runtime_error(texture + ": only " + std::to_string(measured.windows.size()) +
                               " window measurements; more --pairs or a textured photo needed");
    }
    const std::string name =
        a.labels.empty() ? std::filesystem::path(texture).stem().string() : a.labels[t];
    textures.push_back(calibrate(name, measured, a.bins));
  }

  std::printf("%-24s %-4s %4s %10s %10s %6s %7s\n", "texture", "axis", "bin", "predicted",
              "observed", "ratio", "robust");
  plot::Chart chart("Per-window shift uncertainty through " + lens + " (sensor noise " +
                        cv::format("%.1f", a.noise) + ")",
                    "predicted standard deviation [px]", "RMS error [px]");
  double largest = 0.0, smallest = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < textures.size(); ++t) {
    const TextureCalibration& c = textures[t];
    for (const auto& [axis, bins] : {std::pair{"du", &c.du}, std::pair{"dv", &c.dv}}) {
      const bool dv = axis[1] == 'v';
      plot::Series line{{}, {}, plot::paletteColor(static_cast<int>(t)), c.name + " " + axis,
                        dv ? plot::Style::kDashed : plot::Style::kLineMarkers, 2};
      for (std::size_t b = 0; b < bins->size(); ++b) {
        const Bin& bin = (*bins)[b];
        std::printf("%-24s %-4s %4zu %10.4f %10.4f %6.2f %7.2f\n", c.name.c_str(), axis, b + 1,
                    bin.predicted, bin.observed, bin.observed / bin.predicted, bin.robust);
        line.x.push_back(bin.predicted);
        line.y.push_back(bin.observed);
        largest = std::max({largest, bin.predicted, bin.observed});
        smallest = std::min({smallest, bin.predicted, bin.observed});
      }
      if (dv) {  // the same colour as du, dashed, with hollow markers
        plot::Series marks = line;
        marks.label.clear();
        marks.style = plot::Style::kHollowMarkers;
        chart.add(marks);
      }
      chart.add(line);
    }
  }
  for (const TextureCalibration& c : textures) {
    std::printf("%s: %zu window measurements, panorama noise %.2f grey levels; RMS error of the "
                "windows' mean du %.4f px (inverse-variance weighted %.4f), dv %.4f (%.4f)\n",
                c.name.c_str(), c.measurements, c.panorama_noise, c.mean_rms.plain_u,
                c.mean_rms.weighted_u, c.mean_rms.plain_v, c.mean_rms.weighted_v);
  }
  const double lo = 0.8 * smallest, hi = 1.25 * largest;
  chart.add({{lo, hi}, {lo, hi}, {0, 0, 0}, "calibrated (y = x)", plot::Style::kDashed, 1});
  chart.setLogScale(true, true);
  chart.setXRange(lo, hi);
  chart.setYRange(lo, hi);
  const cv::Mat figure = chart.render({a.width, a.width * 3 / 4});
  if (!cv::imwrite(a.out, figure, {cv::IMWRITE_PNG_COMPRESSION, 9}))
    throw std::runtime_error(a.out + ": cannot write");
  if (!a.table.empty()) writeTable(a.table, textures);
  std::printf("omnipose-plot-uncertainty: wrote %s\n", a.out.c_str());
  return 0;
}

void addOptions(CLI::App& app, Args& a) {
  app.add_option("--texture", a.textures, "equirectangular photo (2:1), repeatable")->required();
  app.add_option("--label", a.labels,
                 "name of each texture in the figure and the table, one per --texture in "
                 "their order (default: the file names)");
  app.add_option("--out", a.out, "figure to write (PNG)")->type_name("FIG.png")->required();
  app.add_option("--table", a.table,
                 "also write a Markdown table: per texture and axis, every bin's ratios and "
                 "the noise of the windows' mean shift")
      ->type_name("TABLE.md");
  app.add_option("--config", a.config,
                 "daemon.yaml whose pipeline section is used (window, step, FFTW wisdom, "
                 "threads); the covariance is always measured")
      ->type_name("daemon.yaml");
  app.add_option("--calibration", a.calibration,
                 "calibration.yaml of the lens (default: the built-in linear lens)");
  app.add_option("--pairs", a.pairs, "frame pairs per texture")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  app.add_option("--draws", a.draws, "noise draws per pair")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--noise", a.noise, "sensor noise sigma, grey levels")
      ->check(CLI::Range(0.1, 50.0))
      ->capture_default_str();
  app.add_option("--bins", a.bins, "bins per texture and axis")
      ->check(CLI::Range(2, 50))
      ->capture_default_str();
  app.add_option("--supersample", a.supersample, "renderer anti-aliasing: K x K rays per pixel")
      ->check(CLI::Range(1, 16))
      ->capture_default_str();
  app.add_option("--seed", a.seed, "random poses and noise")->capture_default_str();
  app.add_option("--width", a.width, "figure width, pixels")
      ->check(CLI::Range(400, 4000))
      ->capture_default_str();
}

}  // namespace

int main(int argc, char** argv) {
  omnipose::tools::quietOpenCvWarnings();
  return tools::runMain<Args>(
      argc, argv, {"omnipose-plot-uncertainty", kUsage, kDescription}, addOptions,
      [](tools::Cli& cli, const Args& args) {
        if (!args.labels.empty() && args.labels.size() != args.textures.size()) {
          return cli.usageError("--label given " + std::to_string(args.labels.size()) +
                                " times for " + std::to_string(args.textures.size()) + " --texture");
        }
        return run(args);
      });
}
