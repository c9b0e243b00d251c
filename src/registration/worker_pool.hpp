#pragma once
/// \file worker_pool.hpp
/// A fixed pool of worker threads created at start-up (private). run(count, task) calls
/// task(worker, index) once for every index in [0, count), spread over the calling thread
/// (worker 0) and the pool's threads (workers 1 .. size() - 1), and returns when all are
/// done. Indices are handed out one at a time from an atomic counter, so which worker runs
/// which index varies from call to call: a task must give the same result on every worker
/// (each worker owns its own scratch, indexed by `worker`).
///
/// Realtime: run() allocates nothing (a mutex, two condition variables and a function
/// pointer); the threads are created in the constructor and joined in the destructor.
/// A worker waiting for the next job, and run() waiting for the workers, spin for up to
/// 50 microseconds before blocking on the condition variables (worker_pool.cpp): a frame's
/// jobs come back to back, and a futex wake-up per job cost ~5 % of the 2-thread frame.
/// While a Burst is open (one frame's processing) they spin without that limit, so the
/// workers wake once per frame instead of once per job after every gap (the fit between
/// jobs); between frames they sleep (docs/PERFORMANCE.md, the realistic path).
/// One caller at a time (the pipeline's processing thread).

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

namespace omnipose::registration {

class WorkerPool {
 public:
  /// `threads` >= 1 workers in all, the calling thread included (threads - 1 are started).
  explicit WorkerPool(int threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  /// Number of workers, the calling thread included.
  int size() const { return static_cast<int>(threads_.size()) + 1; }

  /// Calls task(worker, index) for every index in [0, count); returns when all returned.
  /// `task` must not throw.
  template <class Task>
  void run(int count, Task& task) {
    runRaw(count, [](void* context, int worker, int index) {
      (*static_cast<Task*>(context))(worker, index);
    }, &task);
  }

  /// Keeps the workers spinning, instead of sleeping, between the jobs of one frame: opened
  /// at the start of a frame (waking the workers), closed at its end. No allocation.
  class Burst {
   public:
    explicit Burst(WorkerPool& pool) : pool_(pool) { pool_.beginBurst(); }
    ~Burst() { pool_.endBurst(); }
    Burst(const Burst&) = delete;
    Burst& operator=(const Burst&) = delete;

   private:
    WorkerPool& pool_;
  };

  /// How many times a worker has gone to sleep on the condition variable (for tests).
  long sleeps() const { return sleeps_.load(std::memory_order_relaxed); }

  /// The online cores this process may run on (its CPU affinity: taskset, a cgroup cpuset;
  /// sysconf(_SC_NPROCESSORS_ONLN) without one), at least 1.
  static int onlineCores();

 private:
  using Function = void (*)(void* context, int worker, int index);
  void runRaw(int count, Function function, void* context);
  void work(int worker);
  void drain(int worker);
  void beginBurst();
  void endBurst();
  /// Spins while `waiting()` holds, for at most kSpin unless a burst is open; returns true
  /// when it stopped holding.
  template <class Waiting>
  bool spinWhile(Waiting waiting) const;

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable start_, done_;
  // The current job (written under mutex_ before generation_ is bumped).
  Function function_ = nullptr;
  void* context_ = nullptr;
  int count_ = 0;
  std::atomic<int> next_{0};
  /// Bumped under mutex_ (release) for every job; read without it by spinning workers.
  std::atomic<unsigned long> generation_{0};
  std::atomic<int> busy_{0};  ///< pool threads still working on the current job
  /// A Burst is open (written under mutex_ when set, so a worker deciding to sleep sees it).
  std::atomic<bool> burst_{false};
  std::atomic<long> sleeps_{0};
  bool stop_ = false;
};

}  // namespace omnipose::registration
