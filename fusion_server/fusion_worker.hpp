// The fusion server's one background thread (STYLE "one thread per process
// unless a worker is needed"): a FIFO of tasks run one at a time, so local
// maps and sightings reach the GlobalMap in arrival order, exactly as in
// lmf-offline's lockstep loop.
//
// Bound (the server's back-pressure policy): at most `capacity` BOUNDED tasks
// (local maps) wait at once; try_push() of one more returns false and the
// caller must not acknowledge that local map, so its agent resends it later —
// nothing is dropped silently. UNBOUNDED tasks (sightings, which nobody
// resends, and output writes) are always taken; they are few and small.
//
// Threading: try_push(), waiting() and busy() from any thread; stop() from the
// owner's thread (not from a task). Tasks run on the worker thread; a task
// that throws is caught here, logged to stderr and counted (task_errors()).
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>

namespace lmf::server {

class FusionWorker {
 public:
  using Task = std::function<void()>;
  enum class Bound { kBounded, kUnbounded };

  // Starts the thread. capacity >= 1, else std::invalid_argument.
  explicit FusionWorker(std::size_t capacity);
  // stop().
  ~FusionWorker();
  FusionWorker(const FusionWorker&) = delete;
  FusionWorker& operator=(const FusionWorker&) = delete;

  // Queues `task` behind the ones already waiting. False (task not taken) if
  // the worker is stopped, or if `bound` is kBounded and `capacity` bounded
  // tasks are already waiting.
  bool try_push(Task task, Bound bound = Bound::kBounded);

  // Lets the running task finish, discards the waiting ones (never started, so
  // never acknowledged) and joins the thread. Returns how many were discarded.
  // Idempotent (later calls return 0).
  std::size_t stop();

  // try_push(task, kBounded) would take a task now. With one pushing thread
  // (the server's loop) a true answer stays true until that thread pushes,
  // unless stop() is called in between.
  bool has_room() const;

  std::size_t capacity() const { return capacity_; }
  // Tasks waiting (not counting the running one).
  std::size_t waiting() const;
  // A task is running or waiting.
  bool busy() const;
  std::int64_t task_errors() const;

 private:
  struct Entry {
    Task task;
    Bound bound = Bound::kBounded;
  };
  void run();

  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Entry> queue_;
  std::size_t bounded_waiting_ = 0;
  bool running_task_ = false;
  bool stopping_ = false;
  std::int64_t task_errors_ = 0;
  std::thread thread_;  // last: started after everything above exists
};

}  // namespace lmf::server
