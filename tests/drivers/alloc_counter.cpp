#include "alloc_counter.hpp"

#include <cerrno>
#include <cstddef>

// Under ASan/TSan the sanitizer owns the malloc family: replacing it with glibc's entry
// points would hand the sanitizer memory it never allocated. Then nothing is counted and
// AllocationCounter::available() says so (the counting test is skipped, not faked).
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define OMNIPOSE_ALLOC_COUNTER_OFF 1
#endif

// glibc's own entry points; the replacements below count and forward to them.
#ifndef OMNIPOSE_ALLOC_COUNTER_OFF
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* p);
}
#endif

namespace {
thread_local std::int64_t t_allocations = 0;
thread_local int t_counting = 0;
[[maybe_unused]] inline void note() {
  if (t_counting > 0) ++t_allocations;
}
}  // namespace

#ifndef OMNIPOSE_ALLOC_COUNTER_OFF
extern "C" {
void* malloc(std::size_t size) {
  note();
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  note();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  note();
  return __libc_realloc(p, size);
}
void free(void* p) { __libc_free(p); }
void* memalign(std::size_t alignment, std::size_t size) {
  note();
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  note();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  note();
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
}
#endif  // OMNIPOSE_ALLOC_COUNTER_OFF

namespace omnipose::testing {

bool AllocationCounter::available() {
#ifdef OMNIPOSE_ALLOC_COUNTER_OFF
  return false;
#else
  return true;
#endif
}

AllocationCounter::AllocationCounter() : start_(t_allocations) { ++t_counting; }
AllocationCounter::~AllocationCounter() { --t_counting; }
std::int64_t AllocationCounter::count() const { return t_allocations - start_; }

}  // namespace omnipose::testing
