#include "exodaq/messages/subscriber.hpp"

#include <lcm/lcm-cpp.hpp>

#include <stdexcept>

namespace exodaq::messages {

struct Subscriber::Sub {
  Subscriber* owner = nullptr;
  std::optional<Kind> kind;
  Handler handler;
};

Subscriber::Subscriber(const std::string& url) : lcm_(std::make_unique<lcm::LCM>(url)) {
  if (!lcm_->good()) {
    throw std::runtime_error("cannot open LCM at '" + url +
                             "' (bad URL, or no multicast route: see docs/messages.md)");
  }
}

Subscriber::~Subscriber() = default;

void Subscriber::subscribe(const std::string& channel, std::optional<Kind> kind, Handler handler) {
  subs_.push_back(Sub{this, kind, std::move(handler)});
  lcm_->subscribeFunction(regex_escape(channel), &Subscriber::on_raw, &subs_.back());
}

void Subscriber::on_raw(const lcm::ReceiveBuffer* rbuf, const std::string& channel, Sub* sub) {
  const auto k = sub->kind ? sub->kind : kind_of_payload(rbuf->data, rbuf->data_size);
  std::optional<Message> msg;
  if (k) msg = decode(*k, rbuf->data, rbuf->data_size);
  if (!msg) {
    ++sub->owner->undecodable_;
    return;
  }
  if (const auto parts = split_channel(channel)) {
    Subscriber& owner = *sub->owner;
    if (auto mix = owner.runs_.observe(parts->prefix, stamp_of(*msg).run_id);
        mix && owner.mix_handler_) {
      owner.mix_handler_(*mix);
    }
  }
  sub->handler(Received{channel, std::move(*msg), rbuf->recv_utime});
}

int Subscriber::handle(int timeout_ms) {
  return lcm_->handleTimeout(timeout_ms);
}

int Subscriber::fileno() {
  return lcm_->getFileno();
}

}  // namespace exodaq::messages
