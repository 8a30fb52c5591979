// `exodaq status`: waits for one EXO_STATUS message and prints it for people
// (or, with --json, as one JSON object in the CSV schema's names), with the
// source's own counters from the EXO_SOURCE_STATUS of the same window. Exit 0
// when a status arrived, 1 when none did within --timeout.
#include <algorithm>
#include <cstdio>
#include <ctime>
#include <optional>
#include <string>
#include <vector>

#include "clock_text.hpp"
#include "command.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/csv.hpp"
#include "exodaq/messages/flag_names.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/settings/service_config.hpp"
#include "json_out.hpp"
#include "live_rig.hpp"

namespace exodaq::tools {
namespace {

struct StatusOptions {
  LiveRig rig;
  double timeout = 3.0;  // s; status comes at 10 Hz
  bool json = false;
};

std::string utc_time(int64_t utime) {
  const std::time_t t = static_cast<std::time_t>(utime / 1'000'000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S", &tm);
  char out[96];
  std::snprintf(out, sizeof out, "%s.%06lld UTC", buf,
                static_cast<long long>(((utime % 1'000'000) + 1'000'000) % 1'000'000));
  return out;
}

void print_status(const std::string& channel, const status_t& s, int64_t recv_utime,
                  const StatusOptions& o) {
  auto ll = [](int64_t v) { return static_cast<long long>(v); };
  std::printf("%s  rig '%s'  source %s  run %s\n", channel.c_str(), s.rig.c_str(), s.source.c_str(),
              messages::run_id_text(s.run_id).c_str());
  std::printf("state    %s  \"%s\"\n", std::string(messages::state_name(s.state)).c_str(),
              s.message.c_str());
  if (s.foreign_run_id != 0) {
    std::printf(
        "FOREIGN  another run %s publishes on these channels: samples flagged FOREIGN_RUN\n",
        messages::run_id_text(s.foreign_run_id).c_str());
  }
  std::printf("time     %s  (received %.3f s later)  seq %lld  cycles %lld\n",
              utc_time(s.utime).c_str(), static_cast<double>(recv_utime - s.utime) * 1e-6,
              ll(s.seq), ll(s.cycles));
  std::printf("loop     window %d cycles  overruns %lld  publish failures %lld\n", s.window_cycles,
              ll(s.overruns), ll(s.publish_failures));
  std::printf("         %-9s %10s %10s %10s\n", "us", "p50", "p99", "max");
  std::printf("         %-9s %10.1f %10.1f %10.1f\n", "period", s.period_p50_us, s.period_p99_us,
              s.period_max_us);
  std::printf("         %-9s %10.1f %10.1f %10.1f\n", "lateness", s.lateness_p50_us,
              s.lateness_p99_us, s.lateness_max_us);
  std::printf("         %-9s %10.1f %10.1f %10.1f\n", "work", s.work_p50_us, s.work_p99_us,
              s.work_max_us);
  std::printf("source   bus %s  board errors 0x%x  frames %lld  bad %lld  missing %lld\n",
              std::string(messages::bus_state_name(s.bus_state)).c_str(),
              static_cast<unsigned>(s.board_errors), ll(s.frames), ll(s.bad_frames),
              ll(s.missing_samples));
  std::printf(
      "         seq gaps %lld  duplicates %lld  out of order %lld  bus errors %lld  rx "
      "overflows %lld\n",
      ll(s.seq_gaps), ll(s.duplicates), ll(s.out_of_order), ll(s.bus_errors), ll(s.rx_overflows));
  std::printf(
      "clock    %s  est error %s  max error %s  offset %.1f us  utime correction %.1f us  steps "
      "%lld\n",
      clock_state_text(s, o.rig.clock_policy).c_str(),
      clock_error_text(s.clock_est_error_us).c_str(),
      clock_error_text(s.clock_max_error_us).c_str(), s.clock_offset_us, s.utime_correction_us,
      ll(s.clock_steps));
  // Empty after a reload that left restart-only settings unapplied: no file
  // describes the settings in effect (docs/messages.md).
  std::printf("config   %s  sha256 %s  reloads %d\n", s.config_path.c_str(),
              s.config_sha256.empty() ? "- (restart pending: not every setting in effect)"
                                      : s.config_sha256.c_str(),
              s.reloads);
  std::printf("calib    %s  sha256 %s\n         %s\n", s.calibration_path.c_str(),
              s.calibration_sha256.c_str(), s.calibration_provenance.c_str());
  std::printf("%-20s %-9s %8s %8s %8s %8s  %s\n", "joint", "homing", "glitch", "lost", "stale",
              "range", "flags (window)");
  for (int i = 0; i < wire::kJointCount; ++i) {
    std::printf("%-20s %-9s %8lld %8lld %8lld %8lld  %s\n", s.joint_name[i].c_str(),
                std::string(messages::homing_name(s.homing[i])).c_str(), ll(s.glitches[i]),
                ll(s.lost_count_events[i]), ll(s.stale_events[i]), ll(s.out_of_range_events[i]),
                messages::joint_flag_names(s.joint_flags[i]).c_str());
  }
}

// The backend's state and counters, two counters to a line; "-" when no
// source_status_t of this window arrived (a daemon older than the message).
void print_source(const source_status_t* m) {
  if (m == nullptr) {
    std::printf("backend  - (no %s message with this seq)\n",
                std::string(messages::base_channel(messages::Kind::kSourceStatus)).c_str());
    return;
  }
  std::printf("backend  %s\n", m->state.c_str());
  const std::size_t n = messages::counters_in(*m);
  for (std::size_t i = 0; i < n; ++i) {
    std::printf("%s%-22s %12lld", i % 2 == 0 ? "         " : "   ", m->counter_name[i].c_str(),
                static_cast<long long>(m->counter_value[i]));
    if (i % 2 == 1 || i + 1 == n) std::printf("\n");
  }
}

// The JSON value of a status column whose number stands for something (a
// state, a name, a flag set, an unknown), or nothing: the number as it is.
std::optional<std::string> named_json_value(const status_t& s, const std::string& column,
                                            const messages::csv::JointNames& joints) {
  const auto name = [](std::string_view n) { return json_string(std::string(n)); };
  if (column == "state") return name(messages::state_name(s.state));
  if (column == "bus_state") return name(messages::bus_state_name(s.bus_state));
  if (column == "clock_synchronised") return json_bool(s.clock_synchronised != 0);
  // The kernel's "no estimate" (clock_text.hpp) is no number.
  if (column == "clock_est_error_us") return clock_error_json(s.clock_est_error_us);
  if (column == "clock_max_error_us") return clock_error_json(s.clock_max_error_us);
  if (column == "foreign_run_id" && s.foreign_run_id == 0) return "null";
  for (std::size_t i = 0; i < joints.size(); ++i) {
    if (column == joints[i] + "_homing") return name(messages::homing_name(s.homing[i]));
    if (column == joints[i] + std::string(messages::csv::kFlagsSuffix)) {
      return json_strings(messages::joint_flag_list(s.joint_flags[i]));
    }
  }
  return std::nullopt;
}

// One JSON object: the channel, then every column of the CSV schema under
// its name: numbers as numbers, text as strings, states and flags by name,
// booleans as booleans, unknown and none as null (docs/messages.md, "JSON").
void print_json(const std::string& channel, const status_t& s, const source_status_t* source) {
  const messages::Message m{s};
  const auto joints = messages::csv::joints_of(m);
  const auto names = messages::csv::header(messages::Kind::kStatus, joints);
  std::vector<std::string> values;
  messages::csv::append_values(m, values);
  std::string out = "{\n  \"channel\": " + json_string(channel);
  for (std::size_t i = 0; i < names.size(); ++i) {
    std::string value;
    if (auto named = named_json_value(s, names[i], joints)) {
      value = std::move(*named);
    } else if (messages::csv::is_text_column(messages::Kind::kStatus, names[i])) {
      value = json_string(values[i]);
    } else {
      value = json_value(values[i]);
    }
    out += ",\n  " + json_string(names[i]) + ": " + value;
  }
  // The source's own state and counters (source_status_t), null when none came.
  out += ",\n  \"source_status\": ";
  if (source == nullptr) {
    out += "null";
  } else {
    out += "{\"state\": " + json_string(source->state) + ", \"counters\": {";
    for (std::size_t i = 0; i < messages::counters_in(*source); ++i) {
      out += (i ? ", " : "") + json_string(source->counter_name[i]) + ": " +
             std::to_string(source->counter_value[i]);
    }
    out += "}}";
  }
  std::printf("%s\n}\n", out.c_str());
}

// After the first status: how long to listen on for another run id (2.5 status periods at 10 Hz).
constexpr int64_t kMixWatchNs = 250'000'000;

int run_status(StatusOptions opt) {
  resolve_live_rig(opt.rig);
  const std::string channel = messages::channel_name(opt.rig.prefix, messages::Kind::kStatus);
  messages::Subscriber subscriber(opt.rig.url);
  std::optional<messages::Received> got;
  subscriber.subscribe(channel, messages::Kind::kStatus, [&](const messages::Received& r) {
    if (!got) got = r;
  });
  // The source_status_t of the same window follows its status_t at once.
  std::optional<source_status_t> source;
  subscriber.subscribe(messages::channel_name(opt.rig.prefix, messages::Kind::kSourceStatus),
                       messages::Kind::kSourceStatus, [&](const messages::Received& r) {
                         const auto& m = std::get<source_status_t>(r.msg);
                         if (!got || source) return;
                         const auto& s = std::get<status_t>(got->msg);
                         if (m.run_id == s.run_id && m.seq == s.seq) source = m;
                       });
  subscriber.on_mixed_runs(
      [](const messages::RunMix& mix) { print_error("WARNING: " + messages::describe(mix)); });
  int64_t end = mono_now_ns() + static_cast<int64_t>(opt.timeout * 1e9);
  bool listened_on = false;
  for (;;) {
    if (got && !listened_on) {
      // A few status periods more: another daemon on this channel shows up as a second run id.
      end = std::min(end, mono_now_ns() + kMixWatchNs);
      listened_on = true;
    }
    const int64_t left = end - mono_now_ns();
    if (left <= 0) break;
    const int r = subscriber.handle(static_cast<int>(std::max<int64_t>(1, left / 1'000'000)));
    if (r < 0) {
      print_error("LCM receive failed");
      return kExitFailure;
    }
  }
  if (!got) {
    print_error("no " + channel + " message on " + opt.rig.url + " within " +
                messages::csv::number(opt.timeout) +
                " s (is exodaqd running, with this prefix and URL?)");
    return kExitFailure;
  }
  const auto& status = std::get<status_t>(got->msg);
  const source_status_t* matching = source ? &*source : nullptr;
  if (opt.json) {
    print_json(got->channel, status, matching);
  } else {
    print_status(got->channel, status, got->recv_utime, opt);
    print_source(matching);
  }
  return kExitOk;
}

std::function<int()> setup_status(CLI::App& app) {
  auto opt = std::make_shared<StatusOptions>();
  add_live_rig_options(app, opt->rig);
  app.add_flag("--json", opt->json, "print the status as one JSON object");
  app.add_option("--timeout,-t", opt->timeout, "seconds to wait for a status message")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  return [opt] { return run_status(*opt); };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(status, "status",
                        "wait for one EXO_STATUS message and print the service's health (exit 1 "
                        "if none arrives)",
                        ::exodaq::tools::setup_status);
