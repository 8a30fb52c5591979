#pragma once
// A cycle's result as LCM messages: palm_pose_t, joint_state_t and (when
// configured) encoder_raw_t with homing_t once a second and on every change
// of a joint's homing reference, encoded straight into the publisher's slots.
// Every string is set at construction; encoding allocates nothing.
#include <array>
#include <cstdint>
#include <string>
#include <tuple>

#include "exodaq/core/pipeline.hpp"
#include "exodaq/core/publisher.hpp"
#include "exodaq/drivers/encoder_sample.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/homing_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"

namespace exodaq::core {

// Encodes `message` into a publisher slot for its type's channel and commits
// it; a full ring drops it (the publisher counts the drop).
template <typename Msg>
void publish_encoded(Publisher& publisher, const Msg& message, std::int64_t utime_us) noexcept {
  OutgoingMessage* slot = publisher.acquire();
  if (slot == nullptr) return;
  const int n = message.encode(slot->bytes.data(), 0, static_cast<int>(slot->bytes.size()));
  if (n < 0) return;  // cannot happen with checked sizes; the slot is simply not committed
  slot->channel = messages::KindOf<Msg>::value;
  slot->size = static_cast<std::uint32_t>(n);
  slot->utime_us = utime_us;
  slot->seq = message.seq;
  publisher.commit();
}

class MessageEncoder {
 public:
  // `period_ns`: the loop period (homing_t goes out once per second of cycles).
  MessageEncoder(const std::array<std::string, kJointCount>& joint_names, std::int64_t run_id,
                 bool publish_raw, std::int64_t period_ns = 1'000'000);

  // Start-up: encodes each of its messages once into scratch memory (lcm-gen's
  // hashes are initialised on first use). Throws if one does not fit a slot.
  void warm_up() const;

  // The palm pose first (what a BMI decoder waits for), then the joints, then
  // the raw sample; wakes the publisher once.
  void publish(const CycleResult& result, const drivers::EncoderSample& sample,
               Publisher& publisher) noexcept;

  // homing_t when a joint's reference changed in this cycle or a second of
  // cycles has passed (with the raw stream only); before publish(), which wakes
  // the publisher.
  void publish_homing(const CycleResult& result, const Pipeline& pipeline,
                      Publisher& publisher) noexcept;

 private:
  bool publish_raw_;
  // One message of each type it publishes, filled in place every cycle; the
  // constructor and warm_up() treat them all alike.
  std::tuple<joint_state_t, palm_pose_t, encoder_raw_t, homing_t> messages_{};
  std::int64_t homing_every_ = 1000;  // cycles
  std::array<HomingReference, kJointCount> last_reference_{};
};

}  // namespace exodaq::core
