#include "runtime/bus.hpp"

#include <algorithm>
#include <exception>

namespace lmf::runtime {

struct Bus::Subscription {
  Bus* bus = nullptr;
  int id = 0;
  std::string pattern;
  RawHandler handler;
  lcm::Subscription* lcm_subscription = nullptr;
};

Bus::Bus(const std::string& url) : url_(url), lcm_(url) {}

Bus::~Bus() {
  for (const auto& s : subscriptions_) {
    if (s->lcm_subscription != nullptr) lcm_.unsubscribe(s->lcm_subscription);
  }
}

bool Bus::publish_raw(const std::string& channel, const std::vector<std::uint8_t>& bytes) {
  if (!good() || lcm_.publish(channel, bytes.data(), static_cast<unsigned int>(bytes.size())) != 0) {
    ++publish_failures_;
    return false;
  }
  return true;
}

int Bus::subscribe(const std::string& channel, RawHandler handler) {
  auto subscription = std::make_unique<Subscription>();
  subscription->bus = this;
  subscription->id = next_id_++;
  subscription->pattern = channel;
  subscription->handler = std::move(handler);
  subscription->lcm_subscription = lcm_.subscribeFunction(channel, &Bus::dispatch, subscription.get());
  const int id = subscription->id;
  subscriptions_.push_back(std::move(subscription));
  return id;
}

void Bus::unsubscribe(int subscription_id) {
  const auto it = std::find_if(subscriptions_.begin(), subscriptions_.end(),
                               [subscription_id](const auto& s) { return s->id == subscription_id; });
  if (it == subscriptions_.end()) return;
  if ((*it)->lcm_subscription != nullptr) lcm_.unsubscribe((*it)->lcm_subscription);
  subscriptions_.erase(it);
}

// Called from LCM's C dispatch: nothing may propagate out of here.
void Bus::dispatch(const lcm::ReceiveBuffer* buffer, const std::string& channel, Subscription* subscription) {
  Bus& bus = *subscription->bus;
  try {
    subscription->handler(channel, buffer->data, static_cast<std::size_t>(buffer->data_size));
  } catch (const std::exception& e) {
    bus.rejects_.record(Rejection{RejectReason::kHandlerError, e.what()}, channel);
  } catch (...) {
    bus.rejects_.record(Rejection{RejectReason::kHandlerError, "unknown exception"}, channel);
  }
}

int Bus::handle_pending(int max_messages) {
  if (!good()) return -1;
  int handled = 0;
  while (handled < max_messages) {
    const int status = lcm_.handleTimeout(0);
    if (status < 0) return handled > 0 ? handled : status;
    if (status == 0) break;
    ++handled;
  }
  return handled;
}

int Bus::fileno() { return good() ? lcm_.getFileno() : -1; }

}  // namespace lmf::runtime
