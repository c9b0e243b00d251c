#include "registration/fft_plan.hpp"

#include <algorithm>
#include <new>
#include <stdexcept>
#include <utility>

namespace omnipose::registration {

std::mutex& fftwPlannerMutex() {
  static std::mutex mutex;
  return mutex;
}

bool importWisdom(const std::string& path) {
  std::lock_guard lock(fftwPlannerMutex());
  return !path.empty() && fftwf_import_wisdom_from_filename(path.c_str()) != 0;
}

bool exportWisdom(const std::string& path) {
  std::lock_guard lock(fftwPlannerMutex());
  return !path.empty() && fftwf_export_wisdom_to_filename(path.c_str()) != 0;
}

template <class T>
FftwArray<T>::FftwArray(std::size_t size) : size_(size) {
  data_ = static_cast<T*>(fftwf_malloc(sizeof(T) * std::max<std::size_t>(size, 1)));
  if (data_ == nullptr) throw std::bad_alloc();
  clear();
}

template <class T>
FftwArray<T>::~FftwArray() {
  fftwf_free(data_);
}

template <class T>
FftwArray<T>::FftwArray(FftwArray&& other) noexcept
    : data_(std::exchange(other.data_, nullptr)), size_(std::exchange(other.size_, 0)) {}

template <class T>
FftwArray<T>& FftwArray<T>::operator=(FftwArray&& other) noexcept {
  if (this != &other) {
    fftwf_free(data_);
    data_ = std::exchange(other.data_, nullptr);
    size_ = std::exchange(other.size_, 0);
  }
  return *this;
}

template <class T>
void FftwArray<T>::clear() {
  std::fill(data_, data_ + size_, T{});
}

template class FftwArray<float>;
template class FftwArray<Complex>;

FftPlan FftPlan::realToComplex(int rows, int cols, float* in, Complex* out) {
  std::lock_guard lock(fftwPlannerMutex());
  // FFTW_NO_BUFFERING: multi-dimensional real transforms of sizes that are not powers of
  // two otherwise malloc a scratch buffer on every execute (the realtime path must not).
  fftwf_plan plan = fftwf_plan_dft_r2c_2d(rows, cols, in, reinterpret_cast<fftwf_complex*>(out),
                                          FFTW_MEASURE | FFTW_NO_BUFFERING);
  if (plan == nullptr) throw std::runtime_error("FFTW could not plan a real-to-complex transform");
  return FftPlan(plan);
}

FftPlan FftPlan::complexToReal(int rows, int cols, Complex* in, float* out) {
  std::lock_guard lock(fftwPlannerMutex());
  fftwf_plan plan = fftwf_plan_dft_c2r_2d(rows, cols, reinterpret_cast<fftwf_complex*>(in), out,
                                          FFTW_MEASURE | FFTW_NO_BUFFERING);
  if (plan == nullptr) throw std::runtime_error("FFTW could not plan a complex-to-real transform");
  return FftPlan(plan);
}

FftPlan::~FftPlan() {
  if (plan_ != nullptr) {
    std::lock_guard lock(fftwPlannerMutex());
    fftwf_destroy_plan(plan_);
  }
}

FftPlan::FftPlan(FftPlan&& other) noexcept : plan_(std::exchange(other.plan_, nullptr)) {}

FftPlan& FftPlan::operator=(FftPlan&& other) noexcept {
  if (this != &other) {
    FftPlan old(std::move(*this));
    plan_ = std::exchange(other.plan_, nullptr);
  }
  return *this;
}

}  // namespace omnipose::registration
