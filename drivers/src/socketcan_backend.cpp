#include "exodaq/drivers/socketcan_backend.hpp"

#include <sstream>

#include "exodaq/common/yaml_reader.hpp"

namespace exodaq::drivers {

namespace {

void parse_limits(exodaq::MapReader& s, SocketCanSettings& out) {
  out.rcvbuf_bytes = static_cast<int>(s.integer_or("rcvbuf_bytes", out.rcvbuf_bytes));
  if (out.rcvbuf_bytes < 4096)
    s.fail_key("rcvbuf_bytes", "source.socketcan.rcvbuf_bytes must be >= 4096");
  out.read_deadline_us = s.number_or("read_deadline_us", out.read_deadline_us);
  if (out.read_deadline_us <= 0.0 || out.read_deadline_us > 900.0) {
    s.fail_key("read_deadline_us", "source.socketcan.read_deadline_us must be in (0, 900]");
  }
  out.reopen_interval_ms = s.number_or("reopen_interval_ms", out.reopen_interval_ms);
  if (out.reopen_interval_ms < 10.0 || out.reopen_interval_ms > 60'000.0) {
    s.fail_key("reopen_interval_ms",
               "source.socketcan.reopen_interval_ms must be between 10 and 60000");
  }
}

std::shared_ptr<const BackendSettings> parse_socketcan(exodaq::MapReader* s,
                                                       exodaq::MapReader& /*src*/,
                                                       bool /*selected*/) {
  auto out = std::make_shared<SocketCanSettings>();
  if (s == nullptr) return out;
  out->interface = s->string_or("interface", out->interface);
  if (out->interface.empty() || out->interface.size() > 15) {
    s->fail_key("interface",
                "source.socketcan.interface must be a network interface name (1-15 characters)");
  }
  out->sync_master = s->boolean_or("sync_master", out->sync_master);
  out->board = static_cast<int>(s->integer_or("board", out->board));
  if (out->board < 0 || out->board > 7) s->fail_key("board", "source.socketcan.board must be 0..7");
  parse_limits(*s, *out);
  s->finish();
  return out;
}

std::unique_ptr<EncoderSource> make_socketcan(const BackendSettings& settings,
                                              const SourceContext& ctx) {
  const SocketCanSourceConfig config =
      socketcan_config_from(dynamic_cast<const SocketCanSettings&>(settings), ctx);
  return std::make_unique<SocketCanSource>(config, make_socketcan_port(config.port));
}

std::unique_ptr<FrameAssembler> socketcan_assembler(const BackendSettings* settings,
                                                    const SourceContext& /*context*/) {
  BoardDecoderConfig c;
  if (const auto* s = dynamic_cast<const SocketCanSettings*>(settings)) {
    c.ids.board = static_cast<std::uint32_t>(s->board);
  }
  return make_board_frame_assembler(c);
}

}  // namespace

std::string SocketCanSettings::describe() const {
  std::ostringstream s;
  s << "{interface: " << interface << ", sync_master: " << (sync_master ? "true" : "false")
    << ", board: " << board << ", rcvbuf_bytes: " << rcvbuf_bytes
    << ", read_deadline_us: " << read_deadline_us << ", reopen_interval_ms: " << reopen_interval_ms
    << "}";
  return s.str();
}

const Backend& socketcan_backend() {
  static const Backend b{"socketcan", parse_socketcan, make_socketcan, socketcan_assembler};
  return b;
}

int socketcan_board(const SourceOptions& options) noexcept {
  const auto* s = options.section_as<SocketCanSettings>("socketcan");
  return s != nullptr ? s->board : 0;
}

SocketCanSourceConfig socketcan_config_from(const SocketCanSettings& settings,
                                            const SourceContext& /*context*/) {
  SocketCanSourceConfig c;
  c.decoder.ids.board = static_cast<std::uint32_t>(settings.board);
  c.port.interface = settings.interface;
  c.port.filters = can::port_filters(c.decoder.ids, !settings.sync_master);
  c.port.rcvbuf_bytes = settings.rcvbuf_bytes;
  c.sync_master = settings.sync_master;
  c.read_deadline_ns = static_cast<std::int64_t>(settings.read_deadline_us * 1000.0);
  c.reopen_interval_ns = static_cast<std::int64_t>(settings.reopen_interval_ms * 1e6);
  return c;
}

}  // namespace exodaq::drivers
