#pragma once
/// \file worker_pool.hpp
/// A fixed pool of worker threads created at start-up (private). run(count, task) calls
/// task(worker, index) once for every index in [0, count), spread over the calling thread
/// (worker 0) and the pool's threads (workers 1 .. size() - 1), and returns when all are
/// done. Indices are claimed one at a time, so which worker runs which index varies from call
/// to call: a task must give the same result on every worker (each worker owns its own
/// scratch, indexed by `worker`).
///
/// On a shared machine: run() waits only for indices a worker has claimed and not finished,
/// never for a worker that has not started on the job. A worker the kernel has descheduled
/// (another process has its core) simply claims nothing: the caller and the workers that run
/// take its share, so other processes' load costs the frame the CPU time it takes away, not a
/// scheduler time slice per job. A worker that wakes for a job already over claims nothing
/// either: each job carries a tag, and a claim is one compare-and-swap of tag, count and index.
/// No path takes a lock: a worker descheduled anywhere but inside an index holds nobody up.
/// Sleeping and waking are futex calls on two words, made only when someone sleeps.
///
/// Realtime: run() allocates nothing; the threads are created in the constructor and joined
/// in the destructor. A worker waiting for the next job, and run() waiting for a claimed index,
/// spin for up to 50 microseconds before they sleep (worker_pool.cpp): a frame's jobs come
/// back to back, and a futex wake-up per job cost 5-35 % of the 2-thread frame
/// (docs/PERFORMANCE.md, section 6).
/// While a Burst is open (one frame's processing) a worker may spin between jobs without that
/// limit, so the workers wake once per frame instead of once per job; past the limit it yields
/// its core at every look (sched_yield), so any other thread that wants the core runs first.
/// It spins within the limit until the burst ends when it arrived at a job after the others had
/// claimed every index while it spun (its core was taken). Threads under a real-time policy
/// (SCHED_FIFO, SCHED_RR) always spin within the limit.
/// How the next frame runs is chosen frame by frame (WorkerCountTuner, from the bursts' wall
/// times): how many workers take part, the others parked (asleep, not woken by jobs), and
/// whether the burst keeps them spinning or they sleep between jobs; on a machine whose other
/// processes take cores away, fewer workers or sleeping ones can make the frame faster.
/// Outside bursts the count stays as the last burst left it.
/// One caller at a time (the pipeline's processing thread).

#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>
#include <vector>

#include "runtime/worker_count_tuner.hpp"

namespace omnipose::runtime {

class WorkerPool {
 public:
  /// `threads` >= 1 workers in all, the calling thread included (threads - 1 are started).
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  /// Number of workers, the calling thread included.
  int size() const { return static_cast<int>(threads_.size()) + 1; }
  /// Workers that take part in jobs now, the calling thread included, in [1, size()].
  int activeWorkers() const { return active_.load(std::memory_order_relaxed); }

  /// Calls task(worker, index) for every index in [0, count); returns when all returned.
  /// `task` must not throw.
  template <class Task>
  void run(int count, Task& task) {
    runRaw(count, [](void* context, int worker, int index) {
      (*static_cast<Task*>(context))(worker, index);
    }, &task);
  }

  /// Keeps the workers spinning, instead of sleeping, between the jobs of one frame (when the
  /// tuner chose spinning for it): opened at the start of a frame (waking the workers), closed
  /// at its end. No allocation.
  class Burst {
   public:
    explicit Burst(WorkerPool& pool) : pool_(pool) { pool_.beginBurst(); }
    ~Burst() { pool_.endBurst(); }
    Burst(const Burst&) = delete;
    Burst& operator=(const Burst&) = delete;

   private:
    WorkerPool& pool_;
  };

  /// How many times a worker has gone to sleep (for tests).
  long sleeps() const { return sleeps_.load(std::memory_order_relaxed); }
  /// How many jobs ended with the caller waiting for an index still running on a worker
  /// (after it had run out of indices to claim itself), and for how long in all, seconds.
  long waits() const { return waits_.load(std::memory_order_relaxed); }
  double waitSeconds() const { return 1e-9 * wait_ns_.load(std::memory_order_relaxed); }
  /// How many times a worker arrived at a job every index of which was already claimed.
  long lateArrivals() const { return late_.load(std::memory_order_relaxed); }
  /// Bursts (frames) in which the caller waited for a worker at least once (the caller's).
  long waitedBursts() const { return waited_bursts_; }

  /// The online cores this process may run on (its CPU affinity: taskset, a cgroup cpuset;
  /// sysconf(_SC_NPROCESSORS_ONLN) without one), at least 1.
  static int onlineCores();

 private:
  using Function = void (*)(void* context, int worker, int index);
  /// The job's function and context; two, used alternately by consecutive jobs, so a worker
  /// that looked at the last job can never read one being written for the next.
  struct Slot {
    std::atomic<Function> function{nullptr};
    std::atomic<void*> context{nullptr};
  };
  /// The ticket: job tag (32 bits) | count (16 bits) | next index to claim (16 bits).
  static constexpr int kMaxCount = 0xFFFF;
  static std::uint32_t tagOf(std::uint64_t t) { return static_cast<std::uint32_t>(t >> 32); }
  static int countOf(std::uint64_t t) { return static_cast<int>((t >> 16) & 0xFFFF); }
  static int indexOf(std::uint64_t t) { return static_cast<int>(t & 0xFFFF); }

  void runRaw(int count, Function function, void* context);
  void work(int worker);
  /// Claims and runs indices of the job `ticket` belongs to until none is left or another job
  /// began; returns how many it ran.
  int drain(int worker, std::uint64_t ticket);
  void beginBurst();
  void endBurst();
  /// Spins while `waiting()` holds, for at most kSpin unless `unbounded` (re-read each time)
  /// holds; returns true when it stopped holding.
  template <class Waiting, class Unbounded>
  bool spinWhile(Waiting waiting, Unbounded unbounded) const;

  /// Wakes the sleeping workers after a change of what they wait for (ticket, burst, stop).
  void wakeWorkers();
  /// Sets how many workers take part (the caller's, between jobs); wakes the parked ones.
  void setActive(int count);

  std::vector<std::thread> threads_;
  Slot slots_[2];
  std::atomic<std::uint64_t> ticket_{0};
  std::uint32_t last_tag_ = 0;   ///< the caller's: the tag of the last job
  /// Indices of the current job that have returned (a futex word: the caller sleeps on it).
  alignas(4) std::uint32_t finished_ = 0;
  std::atomic<bool> caller_sleeps_{false};
  /// Bumped after every change the workers wait for (a futex word: they sleep on it).
  alignas(4) std::uint32_t wake_ = 0;
  std::atomic<int> sleepers_{0};  ///< workers asleep or about to be
  std::atomic<bool> burst_{false};
  /// Bursts begun so far (from 1), to tell one burst from the next.
  std::atomic<unsigned> bursts_{0};
  std::atomic<bool> stop_{false};
  /// Workers 0 .. active_ - 1 claim indices; the others sleep on park_ (a futex word, bumped
  /// when active_ changes or the pool stops).
  std::atomic<int> active_{1};
  alignas(4) std::uint32_t park_ = 0;
  WorkerCountTuner tuner_;  ///< the caller's
  bool spin_through_ = true;  ///< the caller's: bursts keep the workers spinning
  long burst_waits_ = 0;      ///< the caller's: waits_ when the burst began
  long waited_bursts_ = 0;    ///< the caller's
  std::chrono::steady_clock::time_point burst_start_;
  std::atomic<long> sleeps_{0}, waits_{0}, late_{0};
  std::atomic<std::int64_t> wait_ns_{0};
};

}  // namespace omnipose::runtime
