#pragma once
/// \file allocation_counter.hpp
/// The one heap-allocation counter of the test suite. Linking the `omnipose_allocation_counter`
/// object library (tests/support/CMakeLists.txt) into a test binary replaces, for that whole
/// binary, the malloc family (malloc, calloc, realloc, memalign, aligned_alloc,
/// posix_memalign, valloc, pvalloc; by symbol interposition, so the allocations of C
/// libraries such as FFTW, OpenCV's fastMalloc, LCM and glib count) and every global
/// operator new/delete; each allocation is counted once and forwarded to glibc.
///
///   AllocationCounter counter;                                   // every thread
///   AllocationCounter mine(AllocationCounter::Scope::kThisThread);  // this thread only
///   ... code under test ...
///   EXPECT_EQ(counter.stop(), 0);
///
/// Under ASan/TSan the sanitizer owns the allocator: nothing is replaced, nothing is counted,
/// and available() is false (a test then skips, it does not pass vacuously). Binaries that
/// link the counter are listed in OMNIPOSE_ALLOCATION_COUNTING_TESTS (ctest label
/// "allocation") unless, like v4l2_test, they skip their counting tests themselves.

#include <cstdint>
#include <cstdio>

namespace omnipose::testing {

class AllocationCounter {
 public:
  enum class Scope {
    kProcess,     ///< allocations of every thread (worker pools, capture threads ...)
    kThisThread,  ///< allocations of the thread that made the counter only
  };

  /// Starts counting now. `record_callers`: remember who allocated (per immediate caller,
  /// and a backtrace of the first few), for printCallers() when a count is not 0.
  explicit AllocationCounter(Scope scope = Scope::kProcess, bool record_callers = false);
  ~AllocationCounter();
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;

  /// False in a sanitizer build: nothing is counted.
  static bool available();

  /// Allocations counted since construction, until stop() (after it: frozen). Allocations
  /// made inside an ExcludedScope are not in it.
  std::int64_t count() const;
  /// Allocations made inside an ExcludedScope (of the counted threads) in the same span.
  std::int64_t excluded() const;
  /// Stops counting; returns count().
  std::int64_t stop();

  /// With record_callers: the counted allocations per immediate caller (library and symbol)
  /// and the backtraces of the first few, to `out`. The caller table is process-wide.
  void printCallers(std::FILE* out) const;

  /// While alive, the calling thread's allocations are counted apart, in excluded() (e.g. an
  /// allocation inside a third-party library call that is accounted separately).
  class ExcludedScope {
   public:
    ExcludedScope();
    ~ExcludedScope();
    ExcludedScope(const ExcludedScope&) = delete;
    ExcludedScope& operator=(const ExcludedScope&) = delete;
  };

 private:
  std::int64_t total() const;
  std::int64_t excludedTotal() const;

  Scope scope_;
  bool record_callers_;
  bool running_ = true;
  std::int64_t start_ = 0, start_excluded_ = 0;
  std::int64_t stopped_ = 0, stopped_excluded_ = 0;
};

}  // namespace omnipose::testing
