#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <sstream>

#include "common/problem_list.hpp"
#include "omnipose/synth/scene.hpp"
#include "synth/seeding.hpp"
#include "synth/walker_hit.hpp"

namespace omnipose::synth {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kMaxWalkers = 100;
constexpr double kMaxWidth = 2.0;   ///< metres
constexpr double kMaxSpeed = 20.0;  ///< m/s
constexpr double kMinGrey = 16.0, kMaxGrey = 240.0;

std::string number(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

/// The interval [lo, hi] of ray parameters s where origin + s * direction is inside the
/// solid, or an empty one (lo > hi).
struct Interval {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
};

/// Where a ray is inside a slab a <= o + s d <= b (one coordinate).
Interval slab(double o, double d, double a, double b) {
  if (d == 0.0) {
    if (o >= a && o <= b) return {};
    return {1.0, 0.0};
  }
  const double s1 = (a - o) / d, s2 = (b - o) / d;
  return {std::min(s1, s2), std::max(s1, s2)};
}

}  // namespace

std::vector<std::string> Walkers::validate() const {
  std::vector<std::string> p;
  if (count < 0 || count > kMaxWalkers) {
    p.push_back("walkers.count: must be in [0, " + std::to_string(kMaxWalkers) + "]");
  }
  if (!(width_m > 0 && width_m <= kMaxWidth)) {
    p.push_back("walkers.width_m: must be in (0, " + number(kMaxWidth) + "] metres");
  }
  if (!(height_m > 0 && std::isfinite(height_m))) {
    p.push_back("walkers.height_m: must be > 0 metres");
  }
  if (base_z && !std::isfinite(*base_z)) p.push_back("walkers.base_z: must be finite");
  if (!(speed_m_s >= 0 && speed_m_s <= kMaxSpeed)) {
    p.push_back("walkers.speed_m_s: must be in [0, " + number(kMaxSpeed) + "] m/s");
  }
  if (!(std::isfinite(min_distance_m) && min_distance_m > 0.5 * width_m)) {
    p.push_back("walkers.min_distance_m: must be more than width_m / 2 (a walker must not "
                "cover the world origin)");
  }
  if (!(std::isfinite(max_distance_m) && max_distance_m >= min_distance_m)) {
    p.push_back("walkers.max_distance_m: must be finite and >= min_distance_m");
  }
  return p;
}

std::vector<std::string> Walkers::validate(SceneKind kind, const Box& box) const {
  std::vector<std::string> p = validate();
  if (kind != SceneKind::kBox || !p.empty() || count == 0) return p;
  const double room = 0.5 * std::min(box.length, box.width);
  if (max_distance_m + 0.5 * width_m > room) {
    p.push_back("walkers.max_distance_m: " + number(max_distance_m) +
                " m + width_m / 2 leaves the " + number(box.length) + " x " +
                number(box.width) + " m room (at most " + number(room - 0.5 * width_m) + " m)");
  }
  const double base = base_z.value_or(box.floor);
  if (base < box.floor) {
    p.push_back("walkers.base_z: " + number(base) + " m is below the floor (" +
                number(box.floor) + " m)");
  }
  if (base + height_m > box.ceiling) {
    p.push_back("walkers.height_m: the top (" + number(base + height_m) +
                " m) is above the ceiling (" + number(box.ceiling) + " m)");
  }
  return p;
}

Eigen::Vector2d Walker::position(double t) const {
  const double a = azimuth(t);
  return distance_m * Eigen::Vector2d(std::cos(a), std::sin(a));
}

double Walker::grey(double angle_rad, double height_fraction) const {
  const double f = std::clamp(height_fraction, 0.0, 1.0);
  // The band holding f (the last band includes f = 1).
  std::size_t band = 0;
  while (band + 1 < band_grey.size() && f >= band_edge[band + 1]) ++band;
  const Stripes& s = band_stripes[band];
  double value = band_grey[band] + s.amplitude * std::sin(s.cycles * angle_rad + s.phase_rad);
  for (const Blotch& b : blotches) {
    const double da = std::remainder(angle_rad - b.angle_rad, 2.0 * kPi) / b.sigma_rad;
    const double df = (f - b.height_fraction) / b.sigma_fraction;
    value += b.amplitude * std::exp(-0.5 * (da * da + df * df));
  }
  return std::clamp(value, kMinGrey, kMaxGrey);
}

std::optional<double> Walker::hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                                  double t) const {
  return detail::hitWalker(*this, position(t), origin, direction);
}

std::optional<double> detail::hitWalker(const Walker& w, const Eigen::Vector2d& axis,
                                        const Eigen::Vector3d& origin,
                                        const Eigen::Vector3d& direction) {
  // Inside the infinite vertical cylinder: |o_xy - axis + s d_xy|^2 <= r^2.
  const double ox = origin.x() - axis.x(), oy = origin.y() - axis.y();
  const double dx = direction.x(), dy = direction.y();
  const double a = dx * dx + dy * dy;
  const double b = ox * dx + oy * dy;  // half the linear coefficient
  const double c = ox * ox + oy * oy - w.radius_m * w.radius_m;
  Interval side;
  if (a == 0.0) {
    if (c > 0.0) return std::nullopt;
  } else {
    const double disc = b * b - a * c;
    if (disc < 0.0) return std::nullopt;
    const double root = std::sqrt(disc);
    side = {(-b - root) / a, (-b + root) / a};
  }
  const Interval z = slab(origin.z(), direction.z(), w.base_z, w.top_z);
  const double enter = std::max(side.lo, z.lo), leave = std::min(side.hi, z.hi);
  if (enter > leave || leave <= 0.0) return std::nullopt;
  return enter > 0.0 ? enter : leave;
}

std::vector<Walker> drawWalkers(const Walkers& w, double floor_z) {
  omnipose::detail::throwIfProblems("drawWalkers: invalid walkers", w.validate());
  std::vector<Walker> people;
  for (int i = 0; i < w.count; ++i) {
    std::mt19937_64 rng(detail::itemSeed(w.seed, static_cast<std::uint64_t>(i)));
    const auto uniform = [&](double lo, double hi) {
      return std::uniform_real_distribution<>(lo, hi)(rng);
    };
    Walker p;
    p.distance_m = w.min_distance_m == w.max_distance_m
                       ? w.min_distance_m
                       : uniform(w.min_distance_m, w.max_distance_m);
    p.azimuth0_rad = uniform(0.0, 2.0 * kPi);
    const double direction = std::bernoulli_distribution(0.5)(rng) ? 1.0 : -1.0;
    p.rate_rad_s = direction * w.speed_m_s / p.distance_m;
    p.radius_m = 0.5 * w.width_m;
    p.base_z = w.base_z.value_or(floor_z);
    p.top_z = p.base_z + w.height_m;
    // Texture: 3..6 horizontal bands of clothing (grey 30..225, stripes of 2..8 cycles
    // around the body and amplitude 0..40), then 2..5 blotches.
    const int bands = std::uniform_int_distribution<int>(3, 6)(rng);
    p.band_edge = {0.0};
    for (int j = 1; j < bands; ++j) p.band_edge.push_back(uniform(0.1, 0.9));
    std::sort(p.band_edge.begin(), p.band_edge.end());
    p.band_edge.push_back(1.0);
    for (int j = 0; j < bands; ++j) {
      p.band_grey.push_back(uniform(30.0, 225.0));
      const double cycles = std::uniform_int_distribution<int>(2, 8)(rng);
      p.band_stripes.push_back({uniform(0.0, 40.0), cycles, uniform(0.0, 2.0 * kPi)});
    }
    const int blotches = std::uniform_int_distribution<int>(2, 5)(rng);
    for (int j = 0; j < blotches; ++j) {
      Walker::Blotch b{};
      b.angle_rad = uniform(-kPi, kPi);
      b.height_fraction = uniform(0.0, 1.0);
      b.sigma_rad = uniform(0.2, 0.6);
      b.sigma_fraction = uniform(0.03, 0.1);
      b.amplitude = (std::bernoulli_distribution(0.5)(rng) ? 1.0 : -1.0) * uniform(25.0, 70.0);
      p.blotches.push_back(b);
    }
    people.push_back(std::move(p));
  }
  return people;
}

Walkers parseWalkers(const std::string& text, const Walkers& base) {
  Walkers w = base;
  try {
    std::vector<std::string> fields;
    std::size_t start = 0;
    for (;;) {
      const std::size_t comma = text.find(',', start);
      fields.push_back(text.substr(start, comma - start));
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    if (fields.size() > 4) throw std::invalid_argument("more than 4 fields");
    const auto read = [](const std::string& field) {
      std::size_t end = std::string::npos;
      double v = 0.0;
      try {
        v = std::stod(field, &end);
      } catch (const std::logic_error&) {  // std::invalid_argument, std::out_of_range
      }
      if (end != field.size()) throw std::invalid_argument("'" + field + "' is not a number");
      return v;
    };
    const double count = read(fields[0]);
    if (count != std::floor(count)) throw std::invalid_argument("COUNT must be a whole number");
    w.count = static_cast<int>(std::clamp(count, -1.0, static_cast<double>(kMaxWalkers) + 1));
    if (fields.size() > 1) w.width_m = read(fields[1]);
    if (fields.size() > 2) w.height_m = read(fields[2]);
    if (fields.size() > 3) w.speed_m_s = read(fields[3]);
    if (const auto p = w.validate(); !p.empty()) throw std::invalid_argument(p.front());
    return w;
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("'" + text + "' is not COUNT[,WIDTH_M,HEIGHT_M,SPEED_M_S] (" +
                                e.what() + ")");
  }
}

}  // namespace omnipose::synth
