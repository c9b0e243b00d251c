#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "common/problem_list.hpp"
#include "omnipose/file_io.hpp"
#include "omnipose/config_error.hpp"
#include "omnipose/lens_model.hpp"

namespace omnipose {
namespace {

/// Radial-tangential distortion of a normalised point (omnidir's order: k1, k2, p1, p2).
Eigen::Vector2d distort(const MeiModel& m, const Eigen::Vector2d& p) {
  const double x = p.x(), y = p.y(), r2 = x * x + y * y;
  const double radial = 1.0 + m.k1 * r2 + m.k2 * r2 * r2;
  return {x * radial + 2.0 * m.p1 * x * y + m.p2 * (r2 + 2.0 * x * x),
          y * radial + m.p1 * (r2 + 2.0 * y * y) + 2.0 * m.p2 * x * y};
}

/// Jacobian of distort() at p.
Eigen::Matrix2d distortJacobian(const MeiModel& m, const Eigen::Vector2d& p) {
  const double x = p.x(), y = p.y(), r2 = x * x + y * y;
  const double radial = 1.0 + m.k1 * r2 + m.k2 * r2 * r2;
  const double dradial = m.k1 + 2.0 * m.k2 * r2;  // d radial / d r2
  Eigen::Matrix2d J;
  J(0, 0) = radial + x * dradial * 2.0 * x + 2.0 * m.p1 * y + m.p2 * 6.0 * x;
  J(0, 1) = x * dradial * 2.0 * y + 2.0 * m.p1 * x + m.p2 * 2.0 * y;
  J(1, 0) = y * dradial * 2.0 * x + m.p1 * 2.0 * x + 2.0 * m.p2 * y;
  J(1, 1) = radial + y * dradial * 2.0 * y + m.p1 * 6.0 * y + 2.0 * m.p2 * x;
  return J;
}

}  // namespace

std::vector<std::string> MeiModel::validate() const {
  std::vector<std::string> p;
  for (auto [v, name] : {std::pair{xi, "xi"}, {fx, "fx"}, {fy, "fy"}, {s, "s"}, {cx, "cx"},
                         {cy, "cy"}, {k1, "k1"}, {k2, "k2"}, {p1, "p1"}, {p2, "p2"}}) {
    if (!std::isfinite(v)) p.push_back(std::string(name) + ": must be finite");
  }
  if (!(fx > 0)) p.push_back("fx: must be > 0");
  if (!(fy > 0)) p.push_back("fy: must be > 0");
  if (!(xi >= 0)) p.push_back("xi: must be >= 0");
  return p;
}

MeiModel MeiModel::loadFileStorage(const std::filesystem::path& path) {
  cv::FileStorage fs;
  Expected<std::string> text = readTextFile(path);
  if (!text)
    throw std::runtime_error(std::string(text.error().message()) + " (the omnidir calibration file)");
  try {
    // From memory: the file was read with file_io's checks (regular, bounded); OpenCV tells
    // YAML, XML and JSON apart by the content, as it does when it reads a file.
    if (text->empty() || !fs.open(*text, cv::FileStorage::READ | cv::FileStorage::MEMORY))
      throw std::runtime_error(path.string() + ": cannot open omnidir calibration file");
  } catch (const cv::Exception& e) {
    throw std::runtime_error(path.string() + ": not a readable cv::FileStorage file: " + e.msg);
  }
  std::vector<std::string> problems;
  const auto problem = [&](const std::string& what) { problems.push_back(path.string() + ": " + what); };
  const auto node = [&](std::initializer_list<const char*> names) -> std::pair<cv::FileNode, std::string> {
    for (const char* n : names) {
      cv::FileNode f = fs[n];
      if (!f.empty()) return {f, n};
    }
    return {cv::FileNode(), *names.begin()};
  };
  const auto matrix = [&](std::initializer_list<const char*> names, int count) {
    auto [n, name] = node(names);
    cv::Mat m;
    if (n.empty()) {
      problem(name + ": missing");
      return m;
    }
    try {
      if (n.isReal() || n.isInt()) {
        m = (cv::Mat_<double>(1, 1) << static_cast<double>(n));
      } else if (n.isMap()) {
        // An opencv-matrix: its declared shape must hold `count` numbers before OpenCV
        // allocates it (a crafted "cols" would make it allocate gigabytes).
        const cv::FileNode rows = n["rows"], cols = n["cols"], data = n["data"];
        const bool shaped = rows.isInt() && cols.isInt() && data.isSeq() &&
                            static_cast<int>(rows) >= 1 && static_cast<int>(cols) >= 1 &&
                            static_cast<long long>(static_cast<int>(rows)) * static_cast<int>(cols) == count &&
                            static_cast<int>(data.size()) == count;
        if (shaped) n >> m;
      }
    } catch (const cv::Exception&) {
      m.release();
    }
    if (m.empty() || static_cast<int>(m.total()) != count || m.channels() != 1) {
      problem(name + ": expected " + std::to_string(count) + " numbers");
      return cv::Mat();
    }
    m.convertTo(m, CV_64F);
    return m.reshape(1, 1);
  };
  MeiModel model;
  const cv::Mat xi = matrix({"xi", "Xi"}, 1);
  const cv::Mat K = matrix({"K", "camera_matrix"}, 9);
  const cv::Mat D = matrix({"D", "distortion_coefficients"}, 4);
  if (!xi.empty()) model.xi = xi.at<double>(0);
  if (!K.empty()) {
    model.fx = K.at<double>(0);
    model.s = K.at<double>(1);
    model.cx = K.at<double>(2);
    model.fy = K.at<double>(4);
    model.cy = K.at<double>(5);
  }
  if (!D.empty()) {
    model.k1 = D.at<double>(0);
    model.k2 = D.at<double>(1);
    model.p1 = D.at<double>(2);
    model.p2 = D.at<double>(3);
  }
  if (problems.empty())
    for (const auto& p : model.validate()) problem(p);
  if (!problems.empty()) throw ConfigError(detail::joinProblems(problems), problems);
  return model;
}

std::optional<Eigen::Vector2d> MeiModel::project(const Eigen::Vector3d& X) const {
  const Eigen::Vector3d Xs = X.normalized();
  const double denom = Xs.z() + xi;
  // Beyond the fold (xi > 1: zs <= -1/xi) two sphere points share a pixel.
  if (!(denom > 1e-9) || (xi > 1.0 && Xs.z() <= -1.0 / xi)) return std::nullopt;
  const Eigen::Vector2d pd = distort(*this, Eigen::Vector2d(Xs.x() / denom, Xs.y() / denom));
  return Eigen::Vector2d(fx * pd.x() + s * pd.y() + cx, fy * pd.y() + cy);
}

std::optional<Eigen::Vector3d> MeiModel::unproject(const Eigen::Vector2d& pixel) const {
  // Remove K, then invert the distortion by Newton's method (start: the distorted point).
  const double yd = (pixel.y() - cy) / fy;
  const double xd = (pixel.x() - cx - s * yd) / fx;
  const Eigen::Vector2d target(xd, yd);
  Eigen::Vector2d p = target;
  bool converged = false;
  for (int it = 0; it < 30; ++it) {
    const Eigen::Vector2d r = distort(*this, p) - target;
    if (r.norm() < 1e-13) {
      converged = true;
      break;
    }
    const Eigen::Matrix2d J = distortJacobian(*this, p);
    if (std::abs(J.determinant()) < 1e-12) return std::nullopt;
    p -= J.inverse() * r;
    if (!p.allFinite()) return std::nullopt;
  }
  if (!converged && (distort(*this, p) - target).norm() > 1e-9) return std::nullopt;
  // Lift onto the unit sphere: Xs = eta (x, y, 1) - (0, 0, xi).
  const double r2 = p.squaredNorm();
  const double disc = 1.0 + (1.0 - xi * xi) * r2;
  if (disc < 0) return std::nullopt;
  const double eta = (xi + std::sqrt(disc)) / (1.0 + r2);
  const Eigen::Vector3d Xs(eta * p.x(), eta * p.y(), eta - xi);
  if (xi > 1.0 && Xs.z() <= -1.0 / xi) return std::nullopt;
  return Xs;
}

std::optional<LensDirection> MeiModel::direction(const Eigen::Vector2d& pixel) const {
  const auto Xs = unproject(pixel);
  if (!Xs) return std::nullopt;
  // Robot up is -z of omnidir's frame.
  return LensDirection{std::atan2(Xs->y(), Xs->x()), std::asin(std::clamp(-Xs->z(), -1.0, 1.0)),
                       std::hypot(pixel.x() - cx, pixel.y() - cy)};
}

std::optional<Eigen::Vector2d> MeiModel::pixel(double image_angle, double elevation) const {
  const double ce = std::cos(elevation);
  return project(Eigen::Vector3d(ce * std::cos(image_angle), ce * std::sin(image_angle),
                                 -std::sin(elevation)));
}

}  // namespace omnipose
