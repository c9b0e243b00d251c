#include "runtime/worker_pool.hpp"

#include <linux/futex.h>
#include <sched.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <climits>

namespace omnipose::runtime {
namespace {

/// How long a worker waiting for the next job, and the caller waiting for a claimed index,
/// spin before they sleep on a futex. A pipeline frame is seven jobs (unwrap;
/// column FFTs, windows; projection grid, de-rotated rows; column FFTs, windows), most of them
/// back to back or a fit (~0.15 ms) apart; a futex wake-up costs tens of microseconds per job
/// on the development VM. 50 us takes most of the gain of spinning (docs/PERFORMANCE.md)
/// and leaves the core to the daemon's capture thread between frames.
constexpr auto kSpin = std::chrono::microseconds(50);

using Word = std::atomic_ref<std::uint32_t>;

/// Sleeps while `*word` holds `expected` (returns at once when it does not; may return early).
void futexWait(std::uint32_t* word, std::uint32_t expected) {
  syscall(SYS_futex, word, FUTEX_WAIT_PRIVATE, expected, nullptr, nullptr, 0);
}

void futexWake(std::uint32_t* word, int count) {
  syscall(SYS_futex, word, FUTEX_WAKE_PRIVATE, count, nullptr, nullptr, 0);
}

inline void cpuRelax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#elif defined(__aarch64__)
  asm volatile("yield");
#endif
}

}  // namespace

template <class Waiting, class Unbounded>
bool WorkerPool::spinWhile(Waiting waiting, Unbounded unbounded) const {
  const auto deadline = std::chrono::steady_clock::now() + kSpin;
  for (;;) {
    for (int i = 0; i < 64; ++i) {
      if (!waiting()) return true;
      cpuRelax();
    }
    if (std::chrono::steady_clock::now() > deadline) {
      if (!unbounded()) return !waiting();
      // Spinning through a burst: any other thread that wants this core gets it first (the
      // pipeline's caller, the capture thread, another process); alone, the call returns at once.
      sched_yield();
    }
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

WorkerPool::WorkerPool(int threads) : active_(std::max(threads, 1)), tuner_(threads) {
  const int extra = std::max(threads, 1) - 1;
  threads_.reserve(extra);
  for (int w = 1; w <= extra; ++w) threads_.emplace_back([this, w] { work(w); });
}

WorkerPool::~WorkerPool() {
  stop_.store(true);
  burst_.store(false);
  wakeWorkers();
  setActive(active_.load());  // wakes the parked workers, which see stop_
  for (auto& t : threads_) t.join();
}

void WorkerPool::wakeWorkers() {
  // After the change (sequentially consistent): a worker that counted itself a sleeper before
  // the bump below sees the change, or sleeps on the old word value and is woken here.
  Word(wake_).fetch_add(1);
  if (sleepers_.load() > 0) futexWake(&wake_, INT_MAX);
}

void WorkerPool::setActive(int count) {
  active_.store(count);
  Word(park_).fetch_add(1);
  futexWake(&park_, INT_MAX);
}

int WorkerPool::drain(int worker, std::uint64_t ticket) {
  const std::uint32_t tag = tagOf(ticket);
  int ran = 0;
  while (tagOf(ticket) == tag && indexOf(ticket) < countOf(ticket)) {
    // A claim succeeds only while the ticket still holds this job's tag and index: a worker
    // that read the ticket of a job since finished cannot take an index of the next one.
    if (!ticket_.compare_exchange_weak(ticket, ticket + 1, std::memory_order_acq_rel,
                                       std::memory_order_acquire))
      continue;  // `ticket` now holds the current value
    // The job's slot was written before its ticket was published (release), and is not
    // rewritten before this index has finished (two jobs later).
    const Slot& slot = slots_[tag & 1];
    const int index = indexOf(ticket);
    slot.function.load(std::memory_order_relaxed)(slot.context.load(std::memory_order_relaxed),
                                                  worker, index);
    ++ran;
    const auto count = static_cast<std::uint32_t>(countOf(ticket));
    if (Word(finished_).fetch_add(1) + 1 == count && worker != 0 && caller_sleeps_.load())
      futexWake(&finished_, 1);
    ticket = ticket_.load(std::memory_order_acquire);
  }
  return ran;
}

void WorkerPool::beginBurst() {
  if (threads_.empty()) return;
  burst_start_ = std::chrono::steady_clock::now();
  burst_waits_ = waits_.load(std::memory_order_relaxed);
  // Nobody to keep awake, or the frames were faster with the workers asleep between jobs.
  if (active_.load(std::memory_order_relaxed) == 1 || !spin_through_) return;
  bursts_.fetch_add(1);
  burst_.store(true);
  wakeWorkers();
}

void WorkerPool::endBurst() {
  if (threads_.empty()) return;
  burst_.store(false, std::memory_order_relaxed);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - burst_start_).count();
  if (waits_.load(std::memory_order_relaxed) != burst_waits_) ++waited_bursts_;
  const PoolSetting next = tuner_.frameEnded(seconds);
  spin_through_ = next.spin;
  if (next.workers != active_.load(std::memory_order_relaxed)) setActive(next.workers);
}

void WorkerPool::runRaw(int count, Function function, void* context) {
  if (count <= 0) return;
  // Jobs of more than kMaxCount indices are not expected (a frame's largest is its rows or
  // columns); they run on the caller alone rather than overflow the ticket.
  if (threads_.empty() || count == 1 || count > kMaxCount ||
      active_.load(std::memory_order_relaxed) == 1) {
    for (int i = 0; i < count; ++i) function(context, 0, i);
    return;
  }
  const std::uint32_t tag = ++last_tag_;
  Slot& slot = slots_[tag & 1];
  slot.function.store(function, std::memory_order_relaxed);
  slot.context.store(context, std::memory_order_relaxed);
  Word(finished_).store(0, std::memory_order_relaxed);
  const std::uint64_t ticket = (std::uint64_t{tag} << 32) | (std::uint64_t(count) << 16);
  ticket_.store(ticket);  // publishes the slot and the reset count (sequentially consistent)
  wakeWorkers();
  drain(0, ticket);
  const auto total = static_cast<std::uint32_t>(count);
  if (Word(finished_).load() == total) return;
  const auto waiting_since = std::chrono::steady_clock::now();
  if (!spinWhile([&] { return Word(finished_).load(std::memory_order_acquire) != total; },
                 [] { return false; })) {
    caller_sleeps_.store(true);
    // The worker that finishes the last index wakes the caller if it saw caller_sleeps_; if it
    // did not, its increment came first and the load here sees it.
    for (std::uint32_t done = Word(finished_).load(); done != total;
         done = Word(finished_).load())
      futexWait(&finished_, done);
    caller_sleeps_.store(false);
  }
  waits_.fetch_add(1, std::memory_order_relaxed);
  wait_ns_.fetch_add(std::chrono::duration_cast<std::chrono::nanoseconds>(
                         std::chrono::steady_clock::now() - waiting_since).count(),
                     std::memory_order_relaxed);
}

void WorkerPool::work(int worker) {
  std::uint32_t seen = 0;  // the tag of the last job this worker looked at
  // Set (to the burst's number) when this worker, spinning through that burst, found a job
  // already fully claimed: its core is shared, so it spins within kSpin until the burst ends.
  unsigned crowded_in = 0;
  // A real-time thread (SCHED_FIFO, SCHED_RR: daemon.yaml's scheduling) never spins without
  // a limit: it would keep every normal thread off its core for the whole frame.
  const int policy = sched_getscheduler(0);
  const bool may_spin_through = policy != SCHED_FIFO && policy != SCHED_RR;
  const auto fresh = [&] { return tagOf(ticket_.load(std::memory_order_acquire)) != seen; };
  const auto spin_on = [&] {
    return may_spin_through && burst_.load(std::memory_order_relaxed) &&
           crowded_in != bursts_.load(std::memory_order_relaxed);
  };
  for (;;) {
    if (worker >= active_.load()) {
      // Parked: asleep until the count of workers taking part changes or the pool stops.
      // The word is read before the count, so a change after the look wakes it.
      const std::uint32_t word = Word(park_).load();
      if (!stop_.load() && worker >= active_.load()) futexWait(&park_, word);
      if (stop_.load()) return;
      continue;
    }
    const bool spun = spinWhile([&] { return !fresh(); }, spin_on);
    if (!spun) {
      // Counted as a sleeper before the last look: a change after the look bumps wake_ and
      // wakes it (wakeWorkers()).
      const std::uint32_t word = Word(wake_).load();
      sleepers_.fetch_add(1);
      sleeps_.fetch_add(1, std::memory_order_relaxed);
      while (!stop_.load() && !fresh() && !spin_on() && Word(wake_).load() == word)
        futexWait(&wake_, word);
      sleepers_.fetch_sub(1);
      if (stop_.load()) return;
      if (!fresh()) continue;  // a burst began, or woken early: look again
    }
    const std::uint64_t ticket = ticket_.load(std::memory_order_acquire);
    seen = tagOf(ticket);
    if (worker >= active_.load(std::memory_order_relaxed)) continue;  // parked since
    if (drain(worker, ticket) == 0) {
      late_.fetch_add(1, std::memory_order_relaxed);
      if (spun && burst_.load(std::memory_order_relaxed))
        crowded_in = bursts_.load(std::memory_order_relaxed);
    }
  }
}

}  // namespace omnipose::runtime
