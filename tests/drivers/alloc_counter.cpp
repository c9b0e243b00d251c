#include "alloc_counter.hpp"

#include <cerrno>
#include <cstddef>

// glibc's own entry points; the replacements below count and forward to them.
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t n, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* p);
}

namespace {
thread_local std::int64_t t_allocations = 0;
thread_local int t_counting = 0;
inline void note() {
  if (t_counting > 0) ++t_allocations;
}
}  // namespace

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

namespace omnipose::testing {

AllocationCounter::AllocationCounter() : start_(t_allocations) { ++t_counting; }
AllocationCounter::~AllocationCounter() { --t_counting; }
std::int64_t AllocationCounter::count() const { return t_allocations - start_; }

}  // namespace omnipose::testing
