#include "runtime/bus.hpp"

#include <algorithm>
#include <exception>
#include <iostream>
#include <span>
#include <sstream>
#include <stdexcept>

namespace lmf::runtime {

struct Bus::Subscription {
  Bus* bus = nullptr;
  int id = 0;
  std::string pattern;
  RawHandler handler;
  lcm::Subscription* lcm_subscription = nullptr;
};

Bus::Bus(const std::string& url, std::optional<auth::Config> auth)
    : url_(url), lcm_(std::make_shared<lcm::LCM>(url)) {
  configure_auth(std::move(auth));
}

Bus::Bus(Bus& network, std::optional<auth::Config> auth) : url_(network.url_), lcm_(network.lcm_) {
  configure_auth(std::move(auth));
}

void Bus::configure_auth(std::optional<auth::Config> auth) {
  if (!auth) return;
  auth->validate();
  first_seq_ = auth::wall_clock_first_seq();
  signer_ = std::make_unique<auth::Signer>(auth->identity, *auth->keys->find(auth->identity), first_seq_);
  verifier_ = std::make_unique<auth::Verifier>(auth->keys, auth->replay_window);
}

Bus::~Bus() {
  for (const auto& s : subscriptions_) {
    if (s->lcm_subscription != nullptr) lcm_->unsubscribe(s->lcm_subscription);
  }
  if (signer_) {
    std::ostringstream line;  // one write: processes sharing a terminal do not interleave
    line << signer_->principal() << ": authentication: " << verifier_->verified() << " messages verified, "
         << signer_->next_seq() - first_seq_ << " signed";
    std::int64_t rejected = 0;
    std::ostringstream reasons;
    for (const auto& [name, count] : rejects_.nonzero()) {
      if (name.rfind("auth_", 0) != 0) continue;
      reasons << (rejected == 0 ? " (" : ", ") << name << " " << count;
      rejected += count;
    }
    line << ", " << rejected << " rejected" << (rejected > 0 ? reasons.str() + ")" : std::string()) << '\n';
    std::cerr << line.str() << std::flush;
  }
}

bool Bus::publish_raw(const std::string& channel, const std::vector<std::uint8_t>& bytes) {
  const std::vector<std::uint8_t>* message = &bytes;
  if (signer_) {
    signer_->sign(channel, bytes, signed_);
    message = &signed_;
  }
  int copies = 1;
  if (loss_) {
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    if (uniform(loss_rng_) < loss_->drop) {
      ++publishes_dropped_;
      return true;  // lost on the way: the sender cannot tell
    }
    if (uniform(loss_rng_) < loss_->duplicate) {
      ++publishes_duplicated_;
      copies = 2;
    }
  }
  for (int k = 0; k < copies; ++k) {
    if (!good() || lcm_->publish(channel, message->data(), static_cast<unsigned int>(message->size())) != 0) {
      ++publish_failures_;
      return false;
    }
  }
  return true;
}

void SimulatedLoss::validate() const {
  if (!(drop >= 0.0 && drop < 1.0)) throw std::invalid_argument("simulated loss: drop must be in [0, 1)");
  if (!(duplicate >= 0.0 && duplicate < 1.0)) throw std::invalid_argument("simulated loss: duplicate must be in [0, 1)");
}

void Bus::simulate_loss(const SimulatedLoss& loss) {
  loss.validate();
  loss_ = loss;
  loss_rng_.seed(loss.seed);
}

int Bus::subscribe(const std::string& channel, RawHandler handler) {
  auto subscription = std::make_unique<Subscription>();
  subscription->bus = this;
  subscription->id = next_id_++;
  subscription->pattern = channel;
  subscription->handler = std::move(handler);
  subscription->lcm_subscription = lcm_->subscribeFunction(channel, &Bus::dispatch, subscription.get());
  const int id = subscription->id;
  subscriptions_.push_back(std::move(subscription));
  return id;
}

void Bus::unsubscribe(int subscription_id) {
  const auto it = std::find_if(subscriptions_.begin(), subscriptions_.end(),
                               [subscription_id](const auto& s) { return s->id == subscription_id; });
  if (it == subscriptions_.end()) return;
  if ((*it)->lcm_subscription != nullptr) lcm_->unsubscribe((*it)->lcm_subscription);
  subscriptions_.erase(it);
}

// Called from LCM's C dispatch: nothing may propagate out of here.
void Bus::dispatch(const lcm::ReceiveBuffer* buffer, const std::string& channel, Subscription* subscription) {
  Bus& bus = *subscription->bus;
  try {
    const std::span<const std::uint8_t> message(static_cast<const std::uint8_t*>(buffer->data),
                                                static_cast<std::size_t>(buffer->data_size));
    std::size_t size = message.size();
    if (bus.verifier_) {
      // Before any decoding: nothing unauthenticated reaches a handler.
      const auto payload = bus.verifier_->verify(channel, message);
      if (!payload) {
        bus.rejects_.record(payload.rejection(), channel);
        return;
      }
      size = payload.value().size();
    } else {
      size = auth::unverified_payload_size(message.data(), message.size());
    }
    bus.as_received_ = message;
    subscription->handler(channel, buffer->data, size);
    bus.as_received_ = {};
  } catch (const std::exception& e) {
    bus.as_received_ = {};
    bus.rejects_.record(Rejection{RejectReason::kHandlerError, e.what()}, channel);
  } catch (...) {
    bus.as_received_ = {};
    bus.rejects_.record(Rejection{RejectReason::kHandlerError, "unknown exception"}, channel);
  }
}

int Bus::handle_pending(int max_messages) {
  if (!good()) return -1;
  int handled = 0;
  while (handled < max_messages) {
    const int status = lcm_->handleTimeout(0);
    if (status < 0) return handled > 0 ? handled : status;
    if (status == 0) break;
    ++handled;
  }
  return handled;
}

void Bus::refuse_through(const auth::HighWater& high_water) {
  if (verifier_) verifier_->refuse_through(high_water);
}

int Bus::fileno() { return good() ? lcm_->getFileno() : -1; }

}  // namespace lmf::runtime
