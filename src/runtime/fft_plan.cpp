#include "runtime/fft_plan.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <initializer_list>
#include <new>
#include <stdexcept>
#include <utility>

#include "omnipose/file_io.hpp"

namespace omnipose::runtime {

std::mutex& fftwPlannerMutex() {
  static std::mutex mutex;
  return mutex;
}

namespace {

constexpr FileKind kWisdomKind{"an FFTW wisdom file", looksLikeFftwWisdom};
constexpr std::uintmax_t kMaxWisdomBytes = std::uintmax_t{16} << 20;

}  // namespace

std::optional<std::string> wisdomFileProblem(const std::string& path) {
  std::error_code ec;
  if (path.empty() || !std::filesystem::exists(std::filesystem::symlink_status(path, ec)))
    return std::nullopt;  // written when planned, where the directory exists
  if (Expected<void> ok = checkReplaceable(path, kWisdomKind); !ok) return std::string(ok.error().message());
  return std::nullopt;
}

bool importWisdom(const std::string& path) {
  if (path.empty() || wisdomFileProblem(path)) return false;
  const Expected<std::string> text = readTextFile(path, kMaxWisdomBytes);
  if (!text || !looksLikeFftwWisdom(*text)) return false;
  std::lock_guard lock(fftwPlannerMutex());
  return fftwf_import_wisdom_from_string(text->c_str()) != 0;
}

bool exportWisdom(const std::string& path) {
  if (path.empty()) return false;
  const std::string text = wisdomText();
  return !text.empty() && writeFileAtomically(path, text, kWisdomKind).has_value();
}

std::string wisdomText() {
  std::lock_guard lock(fftwPlannerMutex());
  char* text = fftwf_export_wisdom_to_string();
  if (text == nullptr) return {};
  std::string copy(text);
  std::free(text);  // FFTW allocates it with malloc
  return copy;
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

unsigned planFlags(PlanEffort effort) {
  return (effort == PlanEffort::kPatient ? FFTW_PATIENT : FFTW_MEASURE) | FFTW_NO_BUFFERING;
}

namespace {

fftwf_complex* fftw(Complex* z) { return reinterpret_cast<fftwf_complex*>(z); }

}  // namespace

FftPlan::FftPlan(int rows, int cols)
    : scratch_(static_cast<std::size_t>(rows) * (cols / 2 + 1)) {}

FftPlan FftPlan::realToComplex(int rows, int cols, float* in, Complex* out, PlanEffort effort) {
  FftPlan plan(rows, cols);
  const unsigned flags = planFlags(effort);
  const int bins = cols / 2 + 1;
  std::lock_guard lock(fftwPlannerMutex());
  // Rows: `rows` real transforms of length cols, in -> scratch (both row-major).
  plan.first_ = fftwf_plan_many_dft_r2c(1, &cols, rows, in, nullptr, 1, cols,
                                        fftw(plan.scratch_.data()), nullptr, 1, bins, flags);
  // Columns: `bins` complex transforms of length rows, stride bins, scratch -> out.
  plan.second_ = fftwf_plan_many_dft(1, &rows, bins, fftw(plan.scratch_.data()), nullptr, bins, 1,
                                     fftw(out), nullptr, bins, 1, FFTW_FORWARD, flags);
  if (plan.first_ == nullptr || plan.second_ == nullptr)
    throw std::runtime_error("FFTW could not plan a real-to-complex transform");
  return plan;
}

FftPlan FftPlan::complexToReal(int rows, int cols, Complex* in, float* out, PlanEffort effort,
                               int row_reach) {
  FftPlan plan(rows, cols);
  const unsigned flags = planFlags(effort);
  const int bins = cols / 2 + 1;
  std::lock_guard lock(fftwPlannerMutex());
  // Columns first (in -> scratch, `in` kept), then the rows' c2r (destroys scratch): every
  // row, or the runs [0, reach] and [rows - reach, rows).
  plan.first_ = fftwf_plan_many_dft(1, &rows, bins, fftw(in), nullptr, bins, 1,
                                    fftw(plan.scratch_.data()), nullptr, bins, 1, FFTW_BACKWARD,
                                    flags);
  const auto row_pass = [&](int first_row, int count) {
    return fftwf_plan_many_dft_c2r(1, &cols, count,
                                   fftw(plan.scratch_.data() + static_cast<std::size_t>(first_row) * bins),
                                   nullptr, 1, bins, out + static_cast<std::size_t>(first_row) * cols,
                                   nullptr, 1, cols, flags);
  };
  const bool some_rows = row_reach >= 0 && 2 * row_reach + 1 < rows;
  const bool negative_run = some_rows && row_reach > 0;
  plan.second_ = row_pass(0, some_rows ? row_reach + 1 : rows);
  if (negative_run) plan.third_ = row_pass(rows - row_reach, row_reach);
  if (plan.first_ == nullptr || plan.second_ == nullptr || (negative_run && plan.third_ == nullptr))
    throw std::runtime_error("FFTW could not plan a complex-to-real transform");
  return plan;
}

void FftPlan::reset() {
  if (first_ == nullptr && second_ == nullptr && third_ == nullptr) return;
  std::lock_guard lock(fftwPlannerMutex());
  for (fftwf_plan* p : {&first_, &second_, &third_})
    if (*p != nullptr) fftwf_destroy_plan(std::exchange(*p, nullptr));
}

FftPlan::~FftPlan() { reset(); }

FftPlan::FftPlan(FftPlan&& other) noexcept
    : scratch_(std::move(other.scratch_)),
      first_(std::exchange(other.first_, nullptr)),
      second_(std::exchange(other.second_, nullptr)),
      third_(std::exchange(other.third_, nullptr)) {}

FftPlan& FftPlan::operator=(FftPlan&& other) noexcept {
  if (this != &other) {
    reset();
    scratch_ = std::move(other.scratch_);
    first_ = std::exchange(other.first_, nullptr);
    second_ = std::exchange(other.second_, nullptr);
    third_ = std::exchange(other.third_, nullptr);
  }
  return *this;
}

}  // namespace omnipose::runtime
