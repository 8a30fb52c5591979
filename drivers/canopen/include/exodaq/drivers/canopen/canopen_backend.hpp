#pragma once
// The `canopen` backend: CiA 406 encoder nodes on a Linux CAN interface, the
// daemon their CANopen manager (canopen_source.hpp). Its section
// `source.canopen` (docs/operations.md, "CANopen encoders"):
//   interface: can0            1-15 characters
//   sync: producer             producer: the daemon sends SYNC; consumer: another device does
//   sync_overflow: 0           0 (SYNC without counter) or 2..240
//   read_deadline_us: 400      (0, 90000]: wait for the TPDOs after SYNC (at most 9/10 of a period)
//   reopen_interval_ms: 1000   [10, 60000]
//   rcvbuf_bytes: 1048576      >= 4096
//   boot_timeout_ms: 1000      [10, 60000]
//   heartbeat_timeout_ms: 150  0 (not monitored) or [10, 60000]
//   joints:                    exactly one per channel, joint j → channel j
//     - {node: 1..127, reference: absolute|index, pdo: 1..4, cob_id, object,
//        sub_index, bits: 16|24|32, total_range, reference_object,
//        reference_sub_index, vendor_id, product_code, configure}
#include "exodaq/drivers/backend.hpp"
#include "exodaq/drivers/canopen/canopen_source.hpp"

namespace exodaq::drivers::canopen {

// source.canopen, parsed and validated: the source's configuration as it runs.
struct CanopenSettings final : BackendSettings {
  CanopenSourceConfig config{};
  std::string describe() const override;
};

const Backend& canopen_backend();

}  // namespace exodaq::drivers::canopen
