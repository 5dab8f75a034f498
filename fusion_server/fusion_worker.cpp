#include "fusion_server/fusion_worker.hpp"

#include <exception>
#include <iostream>
#include <stdexcept>
#include <utility>

namespace lmf::server {

FusionWorker::FusionWorker(std::size_t capacity) : capacity_(capacity) {
  if (capacity == 0) throw std::invalid_argument("FusionWorker: queue capacity must be >= 1");
  thread_ = std::thread([this] { run(); });
}

FusionWorker::~FusionWorker() { stop(); }

bool FusionWorker::try_push(Task task, Bound bound) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return false;
    if (bound == Bound::kBounded) {
      if (bounded_waiting_ >= capacity_) return false;
      ++bounded_waiting_;
    }
    queue_.push_back(Entry{std::move(task), bound});
  }
  wake_.notify_one();
  return true;
}

std::size_t FusionWorker::stop() {
  std::size_t discarded = 0;
  {
    std::lock_guard lock(mutex_);
    if (stopping_ && !thread_.joinable()) return 0;
    stopping_ = true;
    discarded = queue_.size();
    queue_.clear();
    bounded_waiting_ = 0;
  }
  wake_.notify_one();
  if (thread_.joinable()) thread_.join();
  return discarded;
}

bool FusionWorker::has_room() const {
  std::lock_guard lock(mutex_);
  return !stopping_ && bounded_waiting_ < capacity_;
}

std::size_t FusionWorker::waiting() const {
  std::lock_guard lock(mutex_);
  return queue_.size();
}

bool FusionWorker::busy() const {
  std::lock_guard lock(mutex_);
  return running_task_ || !queue_.empty();
}

std::int64_t FusionWorker::task_errors() const {
  std::lock_guard lock(mutex_);
  return task_errors_;
}

void FusionWorker::run() {
  while (true) {
    Entry entry;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;  // waiting tasks were discarded by stop()
      entry = std::move(queue_.front());
      queue_.pop_front();
      if (entry.bound == Bound::kBounded) --bounded_waiting_;
      running_task_ = true;
    }
    bool failed = false;
    try {
      entry.task();
    } catch (const std::exception& e) {
      std::cerr << "lmf-server: fusion worker task failed: " << e.what() << '\n';
      failed = true;
    } catch (...) {
      std::cerr << "lmf-server: fusion worker task failed (unknown exception)\n";
      failed = true;
    }
    std::lock_guard lock(mutex_);
    running_task_ = false;
    if (failed) ++task_errors_;
  }
}

}  // namespace lmf::server
