// One boost::asio::io_context per process (STYLE "main.cpp is short"): it
// watches the Bus's descriptor with a posix::stream_descriptor and dispatches
// queued messages when it becomes readable, runs periodic timers, and stops
// cleanly on SIGINT/SIGTERM.
//
// If the Bus has no usable descriptor (fileno() < 0), messages are polled on a
// short timer instead (poll_interval). LCM 1.3.1's memq:// does expose a pipe,
// so memq tests take the descriptor path.
//
// The descriptor belongs to LCM: the loop releases it, never closes it. The
// Bus must outlive the loop.
//
// Threading: run()/run_for()/poll() on one thread; every callback (bus
// handlers, timers) runs on it. stop() may be called from any thread or from
// a callback; it takes effect when the running handler returns (a batch of
// bus messages being dispatched is finished first). post() is the way for
// another thread (e.g. the fusion worker) to hand work to the loop.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <optional>

#include <boost/asio/io_context.hpp>
#include <boost/asio/posix/stream_descriptor.hpp>
#include <boost/asio/signal_set.hpp>
#include <boost/asio/steady_timer.hpp>

#include "runtime/bus.hpp"

namespace lmf::runtime {

struct EventLoopOptions {
  bool handle_signals = true;  // stop on SIGINT/SIGTERM (tests with several loops may turn this off)
  std::chrono::milliseconds poll_interval{5};  // only when the bus has no descriptor
  int max_messages_per_wakeup = 1000;          // then yield to timers before draining more
};

class EventLoop {
 public:
  explicit EventLoop(Bus& bus, EventLoopOptions options = {});
  ~EventLoop();
  EventLoop(const EventLoop&) = delete;
  EventLoop& operator=(const EventLoop&) = delete;

  boost::asio::io_context& context() { return io_; }
  Bus& bus() { return bus_; }

  // Calls `callback` every `period` (> 0, else std::invalid_argument), first
  // after one period. Deadlines advance by whole periods (no drift); missed
  // ticks after a stall are skipped, not replayed. An exception from the
  // callback propagates out of run() (a bug in our own code, not bad input);
  // the timer stays armed. Returns an id for cancel().
  int every(std::chrono::milliseconds period, std::function<void()> callback);
  // Calls `callback` once after `delay`.
  int after(std::chrono::milliseconds delay, std::function<void()> callback);
  void cancel(int timer_id);

  // Runs `task` on the loop thread (thread-safe).
  void post(std::function<void()> task);

  // Runs until stop() or a signal. Restarts a stopped loop.
  void run();
  // Runs until stop(), a signal or `duration` elapsed.
  void run_for(std::chrono::steady_clock::duration duration);
  // Runs what is ready now (bus messages included) without blocking; returns
  // the number of handlers run (bus messages count as one each).
  std::size_t poll();
  void stop();

  // The signal that stopped the loop, if one did.
  std::optional<int> stopped_by_signal() const { return signal_; }
  bool watching_descriptor() const { return descriptor_.has_value(); }

 private:
  struct Timer;
  void arm_descriptor();
  void on_readable();
  void arm_poll_timer();
  void arm_timer(Timer& timer);
  void prepare_run();

  Bus& bus_;
  EventLoopOptions options_;
  boost::asio::io_context io_;  // declared first: destroyed after everything that uses it
  std::optional<boost::asio::posix::stream_descriptor> descriptor_;
  std::optional<boost::asio::steady_timer> poll_timer_;
  std::optional<boost::asio::signal_set> signals_;
  std::list<std::shared_ptr<Timer>> timers_;
  int next_timer_id_ = 1;
  std::optional<int> signal_;
};

}  // namespace lmf::runtime
