#pragma once
/// \file alloc_counter.hpp
/// Counts heap allocations made by the calling thread: malloc, calloc, realloc,
/// posix_memalign, aligned_alloc, memalign (so operator new and cv::fastMalloc too).
/// Linking alloc_counter.cpp replaces those functions for the whole test binary; they
/// forward to glibc's implementations.
///
///   AllocationCounter counter;      // starts counting on this thread
///   ... code under test ...
///   EXPECT_EQ(counter.count(), 0);

#include <cstdint>

namespace omnipose::testing {

class AllocationCounter {
 public:
  AllocationCounter();
  ~AllocationCounter();
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;
  /// False in a sanitizer build (ASan/TSan own the allocator; nothing is counted).
  static bool available();
  /// Allocations on this thread since construction.
  std::int64_t count() const;

 private:
  std::int64_t start_;
};

}  // namespace omnipose::testing
