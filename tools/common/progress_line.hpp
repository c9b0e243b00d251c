#pragma once
/// \file progress_line.hpp
/// One self-overwriting line of progress for long work on a terminal: items done, rate and
/// time left. Silent when the stream is not a terminal (logs, pipes, CI) or when disabled.

#include <chrono>
#include <cstdio>
#include <string>
#include <unistd.h>

namespace omnipose::tools {

class ProgressLine {
 public:
  /// `unit`: what is counted ("frames"); `enabled`: false for --quiet.
  ProgressLine(std::FILE* stream, int total, std::string unit, bool enabled = true)
      : stream_(stream),
        total_(total),
        unit_(std::move(unit)),
        enabled_(enabled && stream != nullptr && isatty(fileno(stream))),
        start_(Clock::now()),
        last_(start_) {}

  /// `done` items finished; redraws at most twice a second.
  void update(int done) {
    if (!enabled_) return;
    const auto now = Clock::now();
    if (done < total_ && now - last_ < std::chrono::milliseconds(500)) return;
    last_ = now;
    const double seconds = std::chrono::duration<double>(now - start_).count();
    const double rate = seconds > 0 ? done / seconds : 0.0;
    const int left = rate > 0 ? static_cast<int>((total_ - done) / rate + 0.5) : 0;
    std::fprintf(stream_, "\r%d/%d %s  %.1f %s/s  %d:%02d left   ", done, total_, unit_.c_str(),
                 rate, unit_.c_str(), left / 60, left % 60);
    std::fflush(stream_);
    drawn_ = true;
  }
  /// Ends the line (a newline after the last redraw).
  void finish() {
    if (drawn_) std::fputc('\n', stream_);
    drawn_ = false;
  }
  ~ProgressLine() { finish(); }

 private:
  using Clock = std::chrono::steady_clock;
  std::FILE* stream_;
  int total_;
  std::string unit_;
  bool enabled_;
  Clock::time_point start_, last_;
  bool drawn_ = false;
};

}  // namespace omnipose::tools
