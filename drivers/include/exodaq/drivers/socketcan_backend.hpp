#pragma once
// The `socketcan` backend: the encoder board on a Linux CAN interface.
#include <string>

#include "exodaq/drivers/backend.hpp"
#include "exodaq/drivers/socketcan_source.hpp"

namespace exodaq::drivers {

// source.socketcan
struct SocketCanSettings final : BackendSettings {
  std::string interface = "can0";
  bool sync_master = true;           // send SYNC every cycle; false: follow a free-running board
  int board = 0;                     // board number: shifts every board-sent ID by board * 0x20
  int rcvbuf_bytes = 1 << 20;        // SO_RCVBUF(FORCE), sized for bursts
  double read_deadline_us = 400;     // how long a cycle waits for its count frames after SYNC
  double reopen_interval_ms = 1000;  // interface lost: re-open attempts at most this often
  std::string describe() const override;
};

const Backend& socketcan_backend();

// The board number the config's socketcan section names (0 without one).
int socketcan_board(const SourceOptions& options) noexcept;

SocketCanSourceConfig socketcan_config_from(const SocketCanSettings& settings,
                                            const SourceContext& context);

}  // namespace exodaq::drivers
