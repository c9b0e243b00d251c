#include "registration/worker_pool.hpp"

#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>

namespace omnipose::registration {
namespace {

/// How long a worker waiting for the next job, and the caller waiting for the workers, spin
/// before they block on the condition variable. A pipeline frame is seven jobs (unwrap;
/// column FFTs, windows; projection grid, de-rotated rows; column FFTs, windows), most of them
/// back to back or a fit (~0.15 ms) apart; a futex wake-up costs tens of microseconds per job
/// on the development VM. 50 us takes most of the gain of spinning (docs/PERFORMANCE.md)
/// and leaves the core to the daemon's capture thread between frames.
constexpr auto kSpin = std::chrono::microseconds(50);

}  // namespace

template <class Waiting>
bool WorkerPool::spinWhile(Waiting waiting) const {
  const auto deadline = std::chrono::steady_clock::now() + kSpin;
  for (;;) {
    for (int i = 0; i < 64; ++i) {
      if (!waiting()) return true;
#if defined(__x86_64__) || defined(__i386__)
      __builtin_ia32_pause();
#elif defined(__aarch64__)
      asm volatile("yield");
#endif
    }
    if (!burst_.load(std::memory_order_relaxed) && std::chrono::steady_clock::now() > deadline)
      return !waiting();
  }
}

int WorkerPool::onlineCores() {
  // The cores this process may run on (taskset, cgroup cpusets), within the online ones.
  cpu_set_t set;
  CPU_ZERO(&set);
  long n = sched_getaffinity(0, sizeof(set), &set) == 0 ? CPU_COUNT(&set) : 0;
  const long online = sysconf(_SC_NPROCESSORS_ONLN);
  if (n <= 0 || (online > 0 && n > online)) n = online;
  return n > 0 ? static_cast<int>(std::min(n, 256L)) : 1;
}

WorkerPool::WorkerPool(int threads) {
  const int extra = std::max(threads, 1) - 1;
  threads_.reserve(extra);
  for (int w = 1; w <= extra; ++w) threads_.emplace_back([this, w] { work(w); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    burst_.store(false, std::memory_order_relaxed);
  }
  start_.notify_all();
  for (auto& t : threads_) t.join();
}

void WorkerPool::drain(int worker) {
  for (int i = next_.fetch_add(1, std::memory_order_relaxed); i < count_;
       i = next_.fetch_add(1, std::memory_order_relaxed))
    function_(context_, worker, i);
}

void WorkerPool::beginBurst() {
  if (threads_.empty()) return;
  {
    std::lock_guard lock(mutex_);
    burst_.store(true, std::memory_order_relaxed);
  }
  start_.notify_all();
}

void WorkerPool::endBurst() { burst_.store(false, std::memory_order_relaxed); }

void WorkerPool::runRaw(int count, Function function, void* context) {
  if (count <= 0) return;
  if (threads_.empty() || count == 1) {
    for (int i = 0; i < count; ++i) function(context, 0, i);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    function_ = function;
    context_ = context;
    count_ = count;
    next_.store(0, std::memory_order_relaxed);
    busy_.store(static_cast<int>(threads_.size()), std::memory_order_relaxed);
    generation_.fetch_add(1, std::memory_order_release);
  }
  start_.notify_all();
  drain(0);
  if (spinWhile([this] { return busy_.load(std::memory_order_acquire) != 0; })) return;
  std::unique_lock lock(mutex_);
  done_.wait(lock, [this] { return busy_.load(std::memory_order_acquire) == 0; });
}

void WorkerPool::work(int worker) {
  unsigned long seen = 0;
  for (;;) {
    if (spinWhile([&] { return generation_.load(std::memory_order_acquire) == seen; })) {
      seen = generation_.load(std::memory_order_acquire);
    } else {
      std::unique_lock lock(mutex_);
      sleeps_.fetch_add(1, std::memory_order_relaxed);
      start_.wait(lock, [&] {
        return stop_ || burst_.load(std::memory_order_relaxed) ||
               generation_.load(std::memory_order_relaxed) != seen;
      });
      if (stop_) return;
      if (generation_.load(std::memory_order_relaxed) == seen) continue;  // a burst: spin
      seen = generation_.load(std::memory_order_relaxed);
    }
    // The job's fields were written under the mutex before generation_ changed.
    drain(worker);
    bool last = false;
    {
      std::lock_guard lock(mutex_);
      last = busy_.fetch_sub(1, std::memory_order_acq_rel) == 1;
    }
    if (last) done_.notify_one();
  }
}

}  // namespace omnipose::registration
