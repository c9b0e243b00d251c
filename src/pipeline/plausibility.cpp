#include "pipeline/plausibility.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

namespace omnipose::pipeline {
namespace {

/// 64-bit hash of `n` bytes (FNV-1a over 8-byte words, then the tail): equal rows give equal
/// hashes; rows that differ collide with probability ~2^-64.
std::uint64_t hashBytes(const std::uint8_t* p, std::size_t n) {
  constexpr std::uint64_t kPrime = 1099511628211ull;
  std::uint64_t h = 14695981039346656037ull;
  std::size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    std::uint64_t word;
    std::memcpy(&word, p + i, 8);
    h = (h ^ word) * kPrime;
  }
  for (; i < n; ++i) h = (h ^ p[i]) * kPrime;
  return h ^ n;
}

/// Whether a row has content: not every byte the same (a black border row has none).
bool hasContent(const std::uint8_t* p, std::size_t n) {
  for (std::size_t i = 1; i < n; ++i)
    if (p[i] != p[0]) return true;
  return false;
}

}  // namespace

PlausibilityGate::PlausibilityGate(const PlausibilityOptions& options, int frame_rows, int windows)
    : options_(options),
      reference_rows_(static_cast<std::size_t>(std::max(frame_rows, 0))),
      candidate_rows_(reference_rows_.size()),
      reference_content_(reference_rows_.size()),
      candidate_content_(reference_rows_.size()) {
  scratch_.reserve(static_cast<std::size_t>(std::max(windows, 0)));
}

Expected<void> PlausibilityGate::checkFrame(const cv::Mat& frame) {
  candidate_confidence_ = -1.0;
  if (static_cast<std::size_t>(frame.rows) != candidate_rows_.size()) return {};  // not sized for it
  const std::size_t bytes = frame.cols * frame.elemSize();
  for (int r = 0; r < frame.rows; ++r) {
    const std::uint8_t* row = frame.ptr<std::uint8_t>(r);
    candidate_rows_[static_cast<std::size_t>(r)] = hashBytes(row, bytes);
    candidate_content_[static_cast<std::size_t>(r)] = hasContent(row, bytes) ? 1 : 0;
  }
  if (!options_.enabled || !has_reference_ || !reference_moved_) return {};
  int content = 0, repeated = 0;
  for (std::size_t r = 0; r < candidate_rows_.size(); ++r) {
    if (!candidate_content_[r] || !reference_content_[r]) continue;
    ++content;
    repeated += candidate_rows_[r] == reference_rows_[r];
  }
  if (content < 8) return {};
  const double share = static_cast<double>(repeated) / content;
  if (share > options_.max_repeated_rows)
    return fail(ErrorCode::kImplausible,
                "implausible frame: %d of its %d rows with content are the previous frame's "
                "(%.0f %%, at most %.0f %% after a pair that moved): a repeated or torn buffer",
                repeated, content, 100.0 * share, 100.0 * options_.max_repeated_rows);
  return {};
}

double PlausibilityGate::medianConfidence(std::span<const WindowMotion> windows) {
  scratch_.clear();
  for (const WindowMotion& w : windows) {
    if (w.masked) continue;
    if (scratch_.size() == scratch_.capacity()) break;  // never reallocates
    scratch_.push_back(w.valid ? w.confidence : 0.0);
  }
  if (scratch_.empty()) return 0.0;
  const auto mid = scratch_.begin() + static_cast<std::ptrdiff_t>(scratch_.size() / 2);
  std::nth_element(scratch_.begin(), mid, scratch_.end());
  return *mid;
}

Expected<void> PlausibilityGate::checkRotation(double angle_rad, double interval_s) const {
  if (!options_.enabled || !(interval_s > 0.0)) return {};
  // A camera's timestamps may bunch frames (two buffers dequeued at once): never less than
  // one frame at 30 fps.
  interval_s = std::max(interval_s, kMinRateInterval);
  if (angle_rad > options_.max_rotation_rad_s * interval_s)
    return fail(ErrorCode::kImplausible,
                "implausible motion: a rotation of %.1f deg in %.1f ms, faster than the %.0f "
                "deg/s the robot can turn",
                angle_rad * 180.0 / std::numbers::pi, interval_s * 1e3,
                options_.max_rotation_rad_s * 180.0 / std::numbers::pi);
  return {};
}

Expected<void> PlausibilityGate::checkConfidence(std::span<const WindowMotion> windows,
                                                 FitStatus status) {
  candidate_confidence_ = medianConfidence(windows);
  if (!options_.enabled) return {};
  if (candidate_confidence_ < kMinConfidence)
    return fail(ErrorCode::kImplausible,
                "implausible frame: its windows' median confidence %.3f is below %.2f: nothing "
                "in common with the previous frame (another scene, flipped, noise)",
                candidate_confidence_, kMinConfidence);
  if (history_size_ >= 3 && status != FitStatus::kOk) {
    std::array<double, kHistory> h{};
    std::copy_n(history_.begin(), history_size_, h.begin());
    const auto mid = h.begin() + history_size_ / 2;
    std::nth_element(h.begin(), mid, h.begin() + history_size_);
    const double reference = *mid;
    if (candidate_confidence_ < options_.min_confidence_ratio * reference)
      return fail(ErrorCode::kImplausible,
                  "implausible frame: its windows' median confidence %.3f is below %.2f of the "
                  "recent %.3f and its fit is %s: little in common with the previous frame",
                  candidate_confidence_, options_.min_confidence_ratio, reference, toString(status));
  }
  return {};
}

void PlausibilityGate::believe(bool moved) {
  reference_rows_.swap(candidate_rows_);
  reference_content_.swap(candidate_content_);
  has_reference_ = true;
  reference_moved_ = moved;
  if (candidate_confidence_ >= 0.0) {
    history_[static_cast<std::size_t>(history_next_)] = candidate_confidence_;
    history_next_ = (history_next_ + 1) % kHistory;
    history_size_ = std::min(history_size_ + 1, kHistory);
  }
  candidate_confidence_ = -1.0;
  rejected_in_a_row_ = 0;
}

void PlausibilityGate::restart() {
  has_reference_ = false;
  reference_moved_ = false;
  history_size_ = 0;
  history_next_ = 0;
  candidate_confidence_ = -1.0;
  rejected_in_a_row_ = 0;
}

}  // namespace omnipose::pipeline
