#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "common/problem_list.hpp"
#include "omnipose/file_io.hpp"
#include "omnipose/config_error.hpp"
#include "omnipose/limits.hpp"
#include "omnipose/lens_model.hpp"

namespace omnipose {
namespace {

/// One data line of the file: its 1-based number, the comment line above it, its numbers.
struct DataLine {
  int number = 0;
  std::string comment;
  std::vector<double> values;
  bool parsed = true;  ///< false: a token was not a number
  std::string bad_token;
};

std::vector<DataLine> dataLines(const std::string& text) {
  std::vector<DataLine> lines;
  std::istringstream in(text);
  std::string line, last_comment;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos) continue;
    if (line[first] == '#') {
      last_comment = line.substr(first);
      continue;
    }
    DataLine d;
    d.number = number;
    d.comment = last_comment;
    std::istringstream tokens(line);
    std::string token;
    while (tokens >> token) {
      char* end = nullptr;
      const double v = std::strtod(token.c_str(), &end);
      if (end == token.c_str() || *end != '\0') {
        d.parsed = false;
        d.bad_token = token;
        break;
      }
      d.values.push_back(v);
    }
    lines.push_back(std::move(d));
  }
  return lines;
}

bool mentions(const std::string& comment, const char* word) {
  std::string lower = comment;
  for (auto& ch : lower) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return lower.find(word) != std::string::npos;
}

double polyval(const std::vector<double>& p, double x) {
  double y = 0.0;
  for (auto it = p.rbegin(); it != p.rend(); ++it) y = y * x + *it;
  return y;
}

double polyder(const std::vector<double>& p, double x) {
  double y = 0.0;
  for (std::size_t i = p.size(); i-- > 1;) y = y * x + static_cast<double>(i) * p[i];
  return y;
}

/// The problems of one file, each "ORIGIN: line N: what".
struct FileProblems {
  const std::string& origin;
  std::vector<std::string> list;

  void add(int line, const std::string& what) {
    list.push_back(origin + (line > 0 ? ": line " + std::to_string(line) : std::string()) + ": " +
                   what);
  }
  /// Whether every value of `d` is finite (else the problem is added).
  bool finite(const DataLine& d, const char* what) {
    for (double v : d.values) {
      if (!std::isfinite(v)) {
        add(d.number, std::string(what) + ": values must be finite");
        return false;
      }
    }
    return true;
  }
  void throwIfAny() const {
    if (!list.empty()) throw ConfigError(detail::joinProblems(list), list);
  }
};

/// pyomniunwarp's extensions after the five standard lines, recognised by their comment
/// lines: the ROI (max min radius) and the crop (left right).
void readExtensions(const std::vector<DataLine>& lines, OcamCalibModel& m, FileProblems& problems) {
  for (std::size_t i = 5; i < lines.size(); ++i) {
    const DataLine& d = lines[i];
    if (!d.parsed) {
      problems.add(d.number, "'" + detail::shown(d.bad_token) + "' is not a number");
    } else if (mentions(d.comment, "roi")) {
      if (d.values.size() != 2 || !problems.finite(d, "ROI")) {
        if (d.values.size() != 2) problems.add(d.number, "ROI: expected 2 numbers (max min radius)");
        continue;
      }
      m.roi_max_radius = d.values[0];
      m.roi_min_radius = d.values[1];
      if (!(d.values[1] >= 0 && d.values[0] > d.values[1]))
        problems.add(d.number, "ROI: expected max radius > min radius >= 0");
    } else if (mentions(d.comment, "crop")) {
      if (d.values.size() != 2 || !problems.finite(d, "crop")) {
        if (d.values.size() != 2) problems.add(d.number, "crop: expected 2 numbers (left right)");
        continue;
      }
      const double l = d.values[0], r = d.values[1];
      if (l != std::floor(l) || r != std::floor(r) || l < 0 || r < 0 || l > limits::kMaxImageSide ||
          r > limits::kMaxImageSide) {
        problems.add(d.number, "crop: left and right must be whole numbers of pixels >= 0");
        continue;
      }
      m.crop_left = static_cast<int>(l);
      m.crop_right = static_cast<int>(r);
    } else {
      problems.add(d.number, "unexpected data line (after the image size only the ROI and crop "
                             "lines are known, each below a comment naming it)");
    }
  }
}

}  // namespace

OcamCalibModel OcamCalibModel::parse(const std::string& text, const std::string& origin) {
  OcamCalibModel m;
  m.origin = origin;
  m.text = text;
  FileProblems problems{origin, {}};
  const auto problem = [&](int line, const std::string& what) { problems.add(line, what); };
  const std::vector<DataLine> lines = dataLines(text);
  static constexpr const char* kFields[] = {
      "direct polynomial (ss: count, then coefficients)",
      "inverse polynomial (invpol: count, then coefficients)", "centre (row column)",
      "affine parameters (c d e)", "image size (height width)"};
  for (std::size_t i = 0; i < std::size(kFields); ++i) {
    if (i >= lines.size()) {
      problem(0, std::string("truncated: expected the ") + kFields[i] + " line, found the end of the file");
    } else if (!lines[i].parsed) {
      problem(lines[i].number, std::string(kFields[i]) + ": '" + detail::shown(lines[i].bad_token) + "' is not a number");
    }
  }
  problems.throwIfAny();

  const auto finite = [&](const DataLine& d, const char* what) { return problems.finite(d, what); };
  // Polynomials: "N a0 a1 ... a(N-1)".
  const auto polynomial = [&](const DataLine& d, const char* what, std::vector<double>& out) {
    if (d.values.empty() || !finite(d, what)) return;
    const double n = d.values[0];
    if (n != std::floor(n) || n < 1 || n > limits::kMaxPolynomialTerms) {
      problem(d.number, std::string(what) + ": count " + std::to_string(n) + " must be a whole number in [1, " +
                            std::to_string(limits::kMaxPolynomialTerms) + "]");
      return;
    }
    if (d.values.size() - 1 != static_cast<std::size_t>(n)) {
      problem(d.number, std::string(what) + ": the count says " + std::to_string(static_cast<int>(n)) +
                            " coefficients, the line has " + std::to_string(d.values.size() - 1));
      return;
    }
    out.assign(d.values.begin() + 1, d.values.end());
  };
  polynomial(lines[0], "ss", m.ss);
  polynomial(lines[1], "invpol", m.invpol);
  m.ss_line = lines[0].number;
  if (lines[2].values.size() != 2) {
    problem(lines[2].number, "centre: expected 2 numbers (row column)");
  } else if (finite(lines[2], "centre")) {
    m.xc = lines[2].values[0];
    m.yc = lines[2].values[1];
  }
  if (lines[3].values.size() != 3) {
    problem(lines[3].number, "affine: expected 3 numbers (c d e)");
  } else if (finite(lines[3], "affine")) {
    m.c = lines[3].values[0];
    m.d = lines[3].values[1];
    m.e = lines[3].values[2];
    if (std::abs(m.c - m.d * m.e) < 1e-6) problem(lines[3].number, "affine: c - d*e is 0 (singular)");
  }
  double height = 0, width = 0;
  if (lines[4].values.size() != 2) {
    problem(lines[4].number, "image size: expected 2 numbers (height width)");
  } else if (finite(lines[4], "image size")) {
    height = lines[4].values[0];
    width = lines[4].values[1];
    for (auto [v, name] : {std::pair{height, "height"}, std::pair{width, "width"}}) {
      if (v != std::floor(v) || v < 1 || v > limits::kMaxImageSide) {
        problem(lines[4].number, std::string("image size: ") + name + " " + std::to_string(v) +
                                     " must be a whole number in [1, " +
                                     std::to_string(limits::kMaxImageSide) + "]");
      }
    }
  }
  readExtensions(lines, m, problems);
  problems.throwIfAny();
  m.height = static_cast<int>(height);
  m.width = static_cast<int>(width) + m.crop_left + m.crop_right;
  m.yc += m.crop_left;
  if (m.width > limits::kMaxImageSide) {
    problem(lines[4].number, "image size: width plus crops exceeds " + std::to_string(limits::kMaxImageSide));
    problems.throwIfAny();
  }
  return m;
}

OcamCalibModel OcamCalibModel::load(const std::filesystem::path& path) {
  Expected<std::string> text = readTextFile(path);
  if (!text)
    throw std::runtime_error(std::string(text.error().message()) + " (the OCamCalib file)");
  return parse(*text, path.string());
}

double OcamCalibModel::f(double rho) const { return polyval(ss, rho); }

double OcamCalibModel::elevation(double rho) const { return std::atan2(f(rho), rho); }

std::optional<double> OcamCalibModel::radius(double elev) const {
  // world2cam's start, then Newton on g(rho) = f(rho) cos(e) - rho sin(e) (zero where
  // atan2(f, rho) = e, without the atan's branch cut).
  const double limit = 2.0 * std::max(width, height);
  double rho = invpol.empty() ? 0.25 * limit : polyval(invpol, elev);
  if (!(rho > 0 && rho < limit)) rho = 0.25 * limit;
  const double ce = std::cos(elev), se = std::sin(elev);
  for (int it = 0; it < 50; ++it) {
    const double g = f(rho) * ce - rho * se;
    const double dg = polyder(ss, rho) * ce - se;
    if (dg == 0.0 || !std::isfinite(dg)) return std::nullopt;
    double step = g / dg;
    step = std::clamp(step, -0.25 * limit, 0.25 * limit);
    rho -= step;
    if (!(rho > 0 && rho < limit)) return std::nullopt;
    if (std::abs(step) < 1e-10) return rho;
  }
  return std::nullopt;
}

LensDirection OcamCalibModel::direction(const Eigen::Vector2d& pixel) const {
  // cam2world: ideal offsets through A^-1.
  const double row = pixel.y() - xc, col = pixel.x() - yc;
  const double invdet = 1.0 / (c - d * e);
  const double xp = invdet * (row - d * col);
  const double yp = invdet * (-e * row + c * col);
  const double rho = std::hypot(xp, yp);
  return {std::atan2(xp, yp), elevation(rho), rho};
}

Eigen::Vector2d OcamCalibModel::pixel(double image_angle, double rho) const {
  // world2cam's last step: pixel = A [xp; yp] + centre, with (xp, yp) = rho (sin a, cos a).
  const double xp = rho * std::sin(image_angle), yp = rho * std::cos(image_angle);
  const double row = xp * c + yp * d + xc;
  const double col = xp * e + yp + yc;
  return {col, row};
}

double OcamCalibModel::invpolMaxErrorPx(double r0, double r1) const {
  double worst = 0.0;
  for (double r = r0; r <= r1; r += 0.5) worst = std::max(worst, std::abs(polyval(invpol, elevation(r)) - r));
  return worst;
}

}  // namespace omnipose
