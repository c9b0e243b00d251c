#include "allocation_counter.hpp"

#include <dlfcn.h>
#include <execinfo.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

// Under ASan/TSan the sanitizer owns the malloc family: replacing it with glibc's entry
// points would hand the sanitizer memory it never allocated. Then nothing is replaced or
// counted and available() says so.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define OMNIPOSE_ALLOCATION_COUNTER_OFF 1
#endif

namespace {

// Every allocation of the binary is counted, always (relaxed atomics: cheap); a counter is
// the difference of the totals between its start and its end, so counters may overlap and
// nest. Allocations inside an ExcludedScope go to the *_excluded totals instead.
std::atomic<std::int64_t> g_total{0};
std::atomic<std::int64_t> g_total_excluded{0};
thread_local std::int64_t t_total = 0;
thread_local std::int64_t t_total_excluded = 0;
thread_local int t_excluded_depth = 0;
thread_local bool t_in_hook = false;  // the diagnostics' own allocations (backtrace) are not counted

// Diagnostics (while a counter with record_callers runs).
std::atomic<int> g_recording{0};
constexpr int kMaxTraces = 8;
constexpr int kTraceDepth = 24;
void* g_traces[kMaxTraces][kTraceDepth];
int g_trace_sizes[kMaxTraces];
std::atomic<int> g_trace_count{0};
constexpr int kCallerSlots = 256;
std::atomic<void*> g_callers[kCallerSlots];
std::atomic<long> g_caller_counts[kCallerSlots];

void recordCaller(void* caller) {
  const auto h = (reinterpret_cast<std::uintptr_t>(caller) >> 4) % kCallerSlots;
  for (std::size_t i = 0; i < kCallerSlots; ++i) {
    auto& slot = g_callers[(h + i) % kCallerSlots];
    void* expected = nullptr;
    if (slot.load() == caller || slot.compare_exchange_strong(expected, caller) ||
        expected == caller) {
      g_caller_counts[(h + i) % kCallerSlots].fetch_add(1);
      return;
    }
  }
}

[[maybe_unused]] inline void countAllocation(void* caller) {
  if (t_in_hook) return;
  if (t_excluded_depth > 0) {
    g_total_excluded.fetch_add(1, std::memory_order_relaxed);
    ++t_total_excluded;
    return;
  }
  g_total.fetch_add(1, std::memory_order_relaxed);
  ++t_total;
  if (g_recording.load(std::memory_order_relaxed) > 0) {
    recordCaller(caller);
    const int slot = g_trace_count.fetch_add(1);
    if (slot < kMaxTraces) {
      t_in_hook = true;
      g_trace_sizes[slot] = backtrace(g_traces[slot], kTraceDepth);
      t_in_hook = false;
    }
  }
}

}  // namespace

#ifndef OMNIPOSE_ALLOCATION_COUNTER_OFF

// glibc's own entry points; the replacements below count and forward to them.
extern "C" {
void* __libc_malloc(std::size_t);
void __libc_free(void*);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);
}

namespace {
void* allocateOrThrow(std::size_t size, void* caller) {
  countAllocation(caller);
  if (void* p = __libc_malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void* allocateAlignedOrThrow(std::size_t size, std::align_val_t align, void* caller) {
  countAllocation(caller);
  if (void* p = __libc_memalign(static_cast<std::size_t>(align), size ? size : 1)) return p;
  throw std::bad_alloc();
}
}  // namespace

// The malloc family, interposed (the executable's definitions win over glibc's).
extern "C" {
void* malloc(std::size_t size) {
  countAllocation(__builtin_return_address(0));
  return __libc_malloc(size);
}
void free(void* p) { __libc_free(p); }
void* calloc(std::size_t n, std::size_t size) {
  countAllocation(__builtin_return_address(0));
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  countAllocation(__builtin_return_address(0));
  return __libc_realloc(p, size);
}
void* memalign(std::size_t align, std::size_t size) {
  countAllocation(__builtin_return_address(0));
  return __libc_memalign(align, size);
}
void* aligned_alloc(std::size_t align, std::size_t size) {
  countAllocation(__builtin_return_address(0));
  return __libc_memalign(align, size);
}
int posix_memalign(void** out, std::size_t align, std::size_t size) {
  countAllocation(__builtin_return_address(0));
  if (align < sizeof(void*) || (align & (align - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(align, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t size) {
  countAllocation(__builtin_return_address(0));
  return __libc_valloc(size);
}
void* pvalloc(std::size_t size) {
  countAllocation(__builtin_return_address(0));
  return __libc_pvalloc(size);
}
}

// Every global operator new/delete, on glibc's allocator (one count per allocation).
void* operator new(std::size_t size) { return allocateOrThrow(size, __builtin_return_address(0)); }
void* operator new[](std::size_t size) { return allocateOrThrow(size, __builtin_return_address(0)); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  countAllocation(__builtin_return_address(0));
  return __libc_malloc(size ? size : 1);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  countAllocation(__builtin_return_address(0));
  return __libc_malloc(size ? size : 1);
}
void* operator new(std::size_t size, std::align_val_t a) {
  return allocateAlignedOrThrow(size, a, __builtin_return_address(0));
}
void* operator new[](std::size_t size, std::align_val_t a) {
  return allocateAlignedOrThrow(size, a, __builtin_return_address(0));
}
void* operator new(std::size_t size, std::align_val_t a, const std::nothrow_t&) noexcept {
  countAllocation(__builtin_return_address(0));
  return __libc_memalign(static_cast<std::size_t>(a), size ? size : 1);
}
void* operator new[](std::size_t size, std::align_val_t a, const std::nothrow_t&) noexcept {
  countAllocation(__builtin_return_address(0));
  return __libc_memalign(static_cast<std::size_t>(a), size ? size : 1);
}
void operator delete(void* p) noexcept { __libc_free(p); }
void operator delete[](void* p) noexcept { __libc_free(p); }
void operator delete(void* p, std::size_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::size_t) noexcept { __libc_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { __libc_free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { __libc_free(p); }

#endif  // OMNIPOSE_ALLOCATION_COUNTER_OFF

namespace omnipose::testing {

bool AllocationCounter::available() {
#ifdef OMNIPOSE_ALLOCATION_COUNTER_OFF
  return false;
#else
  return true;
#endif
}

AllocationCounter::AllocationCounter(Scope scope, bool record_callers)
    : scope_(scope), record_callers_(record_callers) {
  if (record_callers_) {
    // Warm the backtrace machinery (it loads libgcc_s on first use) before counting.
    void* dummy[4];
    backtrace(dummy, 4);
    g_trace_count = 0;
    for (int i = 0; i < kCallerSlots; ++i) {
      g_callers[i] = nullptr;
      g_caller_counts[i] = 0;
    }
    g_recording.fetch_add(1);
  }
  start_ = total();
  start_excluded_ = excludedTotal();
}

AllocationCounter::~AllocationCounter() {
  if (running_) stop();
}

std::int64_t AllocationCounter::total() const {
  return scope_ == Scope::kProcess ? g_total.load() : t_total;
}
std::int64_t AllocationCounter::excludedTotal() const {
  return scope_ == Scope::kProcess ? g_total_excluded.load() : t_total_excluded;
}

std::int64_t AllocationCounter::count() const {
  return (running_ ? total() : stopped_) - start_;
}
std::int64_t AllocationCounter::excluded() const {
  return (running_ ? excludedTotal() : stopped_excluded_) - start_excluded_;
}

std::int64_t AllocationCounter::stop() {
  if (running_) {
    stopped_ = total();
    stopped_excluded_ = excludedTotal();
    running_ = false;
    if (record_callers_) g_recording.fetch_sub(1);
  }
  return count();
}

void AllocationCounter::printCallers(std::FILE* out) const {
  std::fprintf(out, "--- counted allocations by caller:\n");
  for (int i = 0; i < kCallerSlots; ++i) {
    void* caller = g_callers[i].load();
    if (!caller) continue;
    Dl_info info{};
    dladdr(caller, &info);
    std::fprintf(out, "  %8ld  %s (%s)\n", g_caller_counts[i].load(),
                 info.dli_fname ? info.dli_fname : "?", info.dli_sname ? info.dli_sname : "?");
  }
  const int n = std::min(g_trace_count.load(), kMaxTraces);
  std::fflush(out);
  for (int i = 0; i < n; ++i) {
    std::fprintf(out, "--- counted allocation %d:\n", i);
    std::fflush(out);
    backtrace_symbols_fd(g_traces[i], g_trace_sizes[i], fileno(out));
  }
}

AllocationCounter::ExcludedScope::ExcludedScope() { ++t_excluded_depth; }
AllocationCounter::ExcludedScope::~ExcludedScope() { --t_excluded_depth; }

}  // namespace omnipose::testing
