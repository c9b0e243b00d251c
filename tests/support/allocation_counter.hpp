#pragma once
// Counts every heap allocation of the process (malloc family and operator new) while
// counting is on. Link tests/support/allocation_counter.cpp into a test binary of its own:
// it interposes malloc/calloc/realloc/memalign/posix_memalign/aligned_alloc/valloc and
// replaces the global operator new/delete, so FFTW's and OpenCV's mallocs count too.

namespace omnipose::testing {

/// Resets the counter and starts counting (all threads).
void startCountingAllocations();
/// Stops counting and returns the number of allocations since startCountingAllocations().
long stopCountingAllocations();

}  // namespace omnipose::testing
