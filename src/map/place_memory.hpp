#pragma once
/// \file place_memory.hpp
/// Places the robot has seen (private to the core library): for each, its panorama (8-bit,
/// for the registration that verifies a match) and a signature that does not change with
/// the heading, so that a place is recognised whichever way the robot faces. The places
/// are the nodes of the map's pose graph (map/pose_graph.hpp): a place's id is its node's.
///
/// The signature (Menegatti et al., Robotics and Autonomous Systems 2004; Labrosse 2006):
/// per band of panorama rows, the magnitudes of the Fourier series along the azimuth of the
/// band's mean row, harmonics 1..kHarmonics (square-rooted). A yaw shifts every row
/// circularly, which changes the phases and not the magnitudes; the mean (DC) is left out
/// and the whole is centred and scaled to unit length, so brightness and contrast do not
/// count either, and two signatures compare by their correlation.
///
/// Realtime: the constructor allocates every place's storage (capacity x the panorama's
/// pixels, zeroed); nothing else allocates or throws.

#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace omnipose::map {

class PlaceSignature {
 public:
  static constexpr int kBands = 4;
  static constexpr int kHarmonics = 24;
  /// Below this variance of the bands' mean rows (grey levels squared, summed over the
  /// bands) a panorama has no texture to recognise.
  static constexpr double kMinVariance = 0.25;
  using Vector = std::array<float, static_cast<std::size_t>(kBands * kHarmonics)>;

  /// For panoramas of `panorama` pixels (at least kBands rows, 2 kHarmonics + 1 columns).
  explicit PlaceSignature(cv::Size panorama);
  /// The signature of `panorama` (CV_32FC1 of the constructor's size): unit length, or all
  /// zeros for a panorama without texture.
  void compute(const cv::Mat& panorama, Vector& out);
  /// The correlation of two signatures, clamped to [0, 1] (0 when either is zero).
  static double similarity(const Vector& a, const Vector& b);

 private:
  int width_, height_;
  std::vector<double> cos_, sin_;  ///< kHarmonics x width: the Fourier basis
  std::vector<double> profile_;    ///< a band's mean row
};

struct Place {
  bool valid = false;
  std::int64_t sequence = -1;  ///< the frame it was taken from
  double time_s = 0.0;
  double yaw_rate = 0.0;       ///< the camera's turn rate about z then, rad/s (rolling shutter)
  long last_used = 0;          ///< PlaceMemory::touch()'s clock
  long serial = 0;             ///< its number in the order places were stored (1 = the first)
  cv::Mat panorama;            ///< CV_8UC1
  PlaceSignature::Vector signature{};
};

class PlaceMemory {
 public:
  /// `capacity` places of `panorama` pixels.
  PlaceMemory(int capacity, cv::Size panorama);

  int capacity() const { return static_cast<int>(places_.size()); }
  int size() const { return size_; }
  /// Places stored since construction or clear(), forgotten ones included: the newest
  /// place's Place::serial.
  long stored() const { return stored_; }
  const Place& operator[](int id) const { return places_[static_cast<std::size_t>(id)]; }

  /// Stores the place of id `id` (a node id, < capacity): the panorama `panorama`
  /// (CV_32FC1, the constructor's size; rounded to 8 bits) with its signature.
  void store(int id, const cv::Mat& panorama, const PlaceSignature::Vector& signature,
             std::int64_t sequence, double time_s, double yaw_rate);
  /// Stores a place as it was saved (map_file.hpp): `panorama` CV_8UC1 of the
  /// constructor's size, its serial and last use kept (the memory's counters follow them).
  void restore(int id, const cv::Mat& panorama, const PlaceSignature::Vector& signature,
               std::int64_t sequence, double time_s, double yaw_rate, long serial,
               long last_used);
  void remove(int id);
  /// Marks place `id` as used now (a match): the least recently used goes first when full.
  void touch(int id) { places_[static_cast<std::size_t>(id)].last_used = ++clock_; }
  /// The least recently used place other than `keep_a` and `keep_b`; -1 when none.
  int leastRecentlyUsed(int keep_a, int keep_b) const;
  void clear();

 private:
  std::vector<Place> places_;
  int size_ = 0;
  long stored_ = 0;
  long clock_ = 0;
};

}  // namespace omnipose::map
