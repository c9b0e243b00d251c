#pragma once
/// \file fft_plan.hpp
/// Private RAII wrappers for FFTW single precision: aligned arrays and 2-D real<->complex
/// plans bound to fixed arrays. Plan creation and destruction are serialised by one
/// process-wide mutex (the FFTW planner is not thread-safe); execution is lock-free.

#include <fftw3.h>

#include <complex>
#include <cstddef>
#include <mutex>
#include <optional>
#include <string>

namespace omnipose::runtime {

using Complex = std::complex<float>;

/// The mutex that guards every FFTW planner call made by omnipose.
std::mutex& fftwPlannerMutex();

/// FFTW wisdom (the plans FFTW chose when it timed candidates), so every start-up uses the same
/// algorithms: FFTW_MEASURE alone times candidates and picks differently from run to run
/// (4 different r2c 112 x 112 plans in 12 start-ups), which changes both the speed and the
/// last bits of the results. importWisdom() merges the file into the process's wisdom
/// (false when it is missing, unreadable or not a wisdom file); exportWisdom() writes all
/// wisdom gathered so far (false on failure) atomically (file_io.hpp: a temporary file
/// renamed over the old one, never through a symbolic link, never over a file that is not
/// a wisdom file). Both take fftwPlannerMutex().
bool importWisdom(const std::string& path);
bool exportWisdom(const std::string& path);
/// Why the existing `path` cannot be the wisdom file, naming it ("...: exists and is not an
/// FFTW wisdom file; not replaced", "...: not a regular file (a FIFO); not written", a
/// symbolic link); nullopt when it can, when nothing is there yet, or for "" (no file).
std::optional<std::string> wisdomFileProblem(const std::string& path);
/// The process's wisdom as text (to notice that planning added to it). Takes the mutex.
std::string wisdomText();

/// How long FFTW searches for the fastest algorithm when a plan is made (with wisdom that
/// already holds the transform, neither searches). kPatient tries more algorithms: about
/// 0.5 s for the registration's four transforms on the development VM instead of 0.1 s,
/// and plans about 6 % faster per frame; worth it when the plans are kept in a wisdom file.
enum class PlanEffort { kMeasure, kPatient };

/// The FFTW planner flags of every omnipose plan: FFTW_MEASURE or FFTW_PATIENT, with
/// FFTW_NO_BUFFERING (transforms of sizes that are not powers of two otherwise malloc a
/// scratch buffer on every execute; the realtime path must not).
unsigned planFlags(PlanEffort effort);

/// A zero-initialised array from fftwf_malloc (SIMD-aligned), owned. Move-only.
template <class T>
class FftwArray {
 public:
  FftwArray() = default;
  explicit FftwArray(std::size_t size);
  ~FftwArray();
  FftwArray(FftwArray&& other) noexcept;
  FftwArray& operator=(FftwArray&& other) noexcept;
  FftwArray(const FftwArray&) = delete;
  FftwArray& operator=(const FftwArray&) = delete;

  T* data() { return data_; }
  const T* data() const { return data_; }
  std::size_t size() const { return size_; }
  T& operator[](std::size_t i) { return data_[i]; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  /// Sets every element to T{}.
  void clear();

 private:
  T* data_ = nullptr;
  std::size_t size_ = 0;
};

extern template class FftwArray<float>;
extern template class FftwArray<Complex>;

/// A 2-D real transform bound to the arrays it was made for (rows x cols real samples,
/// rows x (cols/2+1) complex bins, row-major), made of two batched 1-D FFTW plans through a
/// scratch array the plan owns: r2c along the rows, then c2c along the columns (the
/// inverse in the opposite order). At this project's sizes (a 112 x 112 window, 108 x 108
/// correlation surface, 96 x 64 log-polar image) that is faster than FFTW's own 2-D plan
/// (build/bin/omnipose-bench-fft), whose faster variants (FFTW_EXHAUSTIVE) transpose in
/// place through a buffer malloc'ed on every execute. Planning (FFTW_MEASURE or FFTW_PATIENT) scribbles on the
/// arrays: clear them after planning. Move-only.
class FftPlan {
 public:
  /// Forward real-to-complex transform of `in` (rows x cols) into `out`.
  static FftPlan realToComplex(int rows, int cols, float* in, Complex* out,
                               PlanEffort effort = PlanEffort::kMeasure);
  /// Inverse (unnormalised) complex-to-real transform of `in` into `out` (`in` is kept).
  /// With `row_reach` in [0, rows/2), only the output rows r with |r| <= row_reach
  /// (periodic: r in [0, row_reach] and [rows - row_reach, rows)) are computed, and the other
  /// rows of `out` are left as they are: a correlation searched near zero shift skips most
  /// of the row transforms. A negative `row_reach` (the default) computes every row.
  static FftPlan complexToReal(int rows, int cols, Complex* in, float* out,
                               PlanEffort effort = PlanEffort::kMeasure, int row_reach = -1);

  FftPlan() = default;
  ~FftPlan();
  FftPlan(FftPlan&& other) noexcept;
  FftPlan& operator=(FftPlan&& other) noexcept;
  FftPlan(const FftPlan&) = delete;
  FftPlan& operator=(const FftPlan&) = delete;

  /// Runs the transform on the bound arrays (and the plan's scratch array: one plan must
  /// not run on two threads at once). Allocation-free.
  void execute() const {
    fftwf_execute(first_);
    fftwf_execute(second_);
    if (third_ != nullptr) fftwf_execute(third_);
  }

 private:
  FftPlan(int rows, int cols);
  void reset();

  FftwArray<Complex> scratch_;  ///< rows x (cols/2+1) bins between the two passes
  /// first_: the first pass; second_ (and third_, when only some output rows are computed:
  /// the negative rows' run): the second.
  fftwf_plan first_ = nullptr, second_ = nullptr, third_ = nullptr;
};

}  // namespace omnipose::runtime
