#include "runtime/event_loop.hpp"

#include <csignal>
#include <iostream>
#include <stdexcept>

#include <boost/asio/post.hpp>

namespace lmf::runtime {

struct EventLoop::Timer {
  Timer(boost::asio::io_context& io, int timer_id, std::chrono::milliseconds timer_period, bool is_repeating,
        std::function<void()> cb)
      : timer(io), id(timer_id), period(timer_period), repeating(is_repeating), callback(std::move(cb)) {}
  boost::asio::steady_timer timer;
  int id;
  std::chrono::milliseconds period;
  bool repeating;
  std::function<void()> callback;
  bool cancelled = false;
};

EventLoop::EventLoop(Bus& bus, EventLoopOptions options) : bus_(bus), options_(options) {
  const int fd = bus_.fileno();
  if (fd >= 0) {
    boost::system::error_code error;
    descriptor_.emplace(io_);
    descriptor_->assign(fd, error);
    if (error) {
      std::cerr << "lmf event loop: cannot watch LCM descriptor " << fd << " (" << error.message()
                << "); polling every " << options_.poll_interval.count() << " ms\n";
      descriptor_->release();
      descriptor_.reset();
    }
  }
  if (descriptor_) {
    // Drain whatever is already queued, then wait: see on_readable().
    boost::asio::post(io_, [this] { on_readable(); });
  } else {
    poll_timer_.emplace(io_);
    arm_poll_timer();
  }
  if (options_.handle_signals) {
    signals_.emplace(io_, SIGINT, SIGTERM);
    signals_->async_wait([this](const boost::system::error_code& error, int signal_number) {
      if (error) return;
      signal_ = signal_number;
      io_.stop();
    });
  }
}

EventLoop::~EventLoop() {
  if (signals_) {
    boost::system::error_code ignored;
    signals_->cancel(ignored);
  }
  for (const auto& t : timers_) t->timer.cancel();
  if (descriptor_) {
    boost::system::error_code ignored;
    descriptor_->cancel(ignored);
    descriptor_->release();  // LCM owns the descriptor: never close it here
  }
}

// The reactor is edge-triggered and async_wait does not look at the
// descriptor before waiting, so a wait armed while messages are still queued
// could sleep until the next message. Hence: drain completely, then re-arm,
// all in one handler on the single loop thread; a message arriving meanwhile
// leaves an edge that the next reactor pass reports to the new wait.
void EventLoop::on_readable() {
  const int handled = bus_.handle_pending(options_.max_messages_per_wakeup);
  if (handled < 0) {
    std::cerr << "lmf event loop: LCM handle failed; retrying in " << options_.poll_interval.count() << " ms\n";
  }
  if (handled >= options_.max_messages_per_wakeup) {
    boost::asio::post(io_, [this] { on_readable(); });  // more queued: let timers run first
    return;
  }
  if (handled < 0) {
    // Avoid a busy loop on a broken provider: retry on the poll timer.
    if (!poll_timer_) poll_timer_.emplace(io_);
    poll_timer_->expires_after(options_.poll_interval);
    poll_timer_->async_wait([this](const boost::system::error_code& error) {
      if (!error) on_readable();
    });
    return;
  }
  arm_descriptor();
}

void EventLoop::arm_descriptor() {
  descriptor_->async_wait(boost::asio::posix::descriptor_base::wait_read,
                          [this](const boost::system::error_code& error) {
                            if (error) return;  // cancelled: the loop is going away
                            on_readable();
                          });
}

void EventLoop::arm_poll_timer() {
  poll_timer_->expires_after(options_.poll_interval);
  poll_timer_->async_wait([this](const boost::system::error_code& error) {
    if (error) return;
    bus_.handle_pending(options_.max_messages_per_wakeup);
    arm_poll_timer();
  });
}

int EventLoop::every(std::chrono::milliseconds period, std::function<void()> callback) {
  if (period.count() <= 0) {
    throw std::invalid_argument("EventLoop::every: period must be > 0 ms, got " + std::to_string(period.count()));
  }
  auto timer = std::make_shared<Timer>(io_, next_timer_id_++, period, true, std::move(callback));
  timer->timer.expires_after(period);
  timers_.push_back(timer);
  arm_timer(*timer);
  return timer->id;
}

int EventLoop::after(std::chrono::milliseconds delay, std::function<void()> callback) {
  auto timer = std::make_shared<Timer>(io_, next_timer_id_++, delay, false, std::move(callback));
  timer->timer.expires_after(delay);
  timers_.push_back(timer);
  arm_timer(*timer);
  return timer->id;
}

void EventLoop::arm_timer(Timer& timer) {
  timer.timer.async_wait([this, &timer](const boost::system::error_code& error) {
    if (error || timer.cancelled) return;
    if (timer.repeating) {
      // Next deadline on the period grid; skip ticks already missed.
      auto next = timer.timer.expiry() + timer.period;
      const auto now = std::chrono::steady_clock::now();
      while (next <= now) next += timer.period;
      timer.timer.expires_at(next);
      arm_timer(timer);
      timer.callback();  // may throw out of run(): the timer is already re-armed
    } else {
      const int id = timer.id;
      auto callback = std::move(timer.callback);
      cancel(id);  // destroys `timer`
      callback();
    }
  });
}

void EventLoop::cancel(int timer_id) {
  for (auto it = timers_.begin(); it != timers_.end(); ++it) {
    if ((*it)->id != timer_id) continue;
    (*it)->cancelled = true;
    (*it)->timer.cancel();
    // A completion handler may still be queued and refers to the Timer: keep
    // it alive until the io_context has run that handler.
    boost::asio::post(io_, [keep = *it] {});
    timers_.erase(it);
    return;
  }
}

void EventLoop::post(std::function<void()> task) { boost::asio::post(io_, std::move(task)); }

void EventLoop::prepare_run() {
  if (io_.stopped()) io_.restart();
}

void EventLoop::run() {
  prepare_run();
  io_.run();
}

void EventLoop::run_for(std::chrono::steady_clock::duration duration) {
  prepare_run();
  io_.run_for(duration);
}

std::size_t EventLoop::poll() {
  prepare_run();
  std::size_t count = io_.poll();
  // The reactor may not have reported the descriptor yet; dispatching here
  // makes poll() deterministic for tests (a later wakeup finds nothing).
  const int handled = bus_.handle_pending(options_.max_messages_per_wakeup);
  if (handled > 0) count += static_cast<std::size_t>(handled);
  return count;
}

void EventLoop::stop() { io_.stop(); }

}  // namespace lmf::runtime
