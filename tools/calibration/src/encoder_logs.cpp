// Encoder angles from the project's own recordings: `exodaq export` CSVs and
// LCM logs (joint_state_t), both in the CSV schema's terms (docs/messages.md).
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <memory>
#include <set>
#include <string_view>

#include "encoder_logs.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/csv.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "sample_stores.hpp"

namespace exodaq::calibration {

using detail::EncoderStore;
using exodaq::ConfigError;

namespace {

// Joint flags that make a sample unusable: all but HELD (a value held for
// one cycle) and UNHOMED (the homed mask says it).
constexpr std::int32_t kFaultFlags =
    ~(std::int32_t{joint_state_t::JOINT_HELD} | std::int32_t{joint_state_t::JOINT_UNHOMED});

const std::array<double, kJoints>& offsets_or_fail(const EncoderReadOptions& o,
                                                   const std::string& name, int line) {
  if (!o.recorded_offsets_rad) {
    throw ConfigError(name, line,
                      "holds calibrated joint angles (theta = offset + theta_R): name the "
                      "calibration they were computed with (-c CONFIG or "
                      "--recorded-calibration FILE)");
  }
  return *o.recorded_offsets_rad;
}

// One sample from calibrated angles, homed flags and joint flags.
EncoderSample to_sample(std::int64_t utime, const double* position, const bool* homed,
                        const std::int32_t* flags, std::int32_t sample_flags,
                        const std::array<double, kJoints>& offsets) {
  EncoderSample s;
  s.utime_us = utime;
  s.homed_mask = 0;
  s.fault_mask = 0;
  for (int j = 0; j < kJoints; ++j) {
    s.theta_r[j] = position[j] - offsets[j];
    if (homed[j]) s.homed_mask |= static_cast<std::uint8_t>(1U << j);
    if ((flags[j] & kFaultFlags) != 0) s.fault_mask |= static_cast<std::uint8_t>(1U << j);
  }
  if ((sample_flags & joint_state_t::SAMPLE_MISSING) != 0) s.fault_mask = kAllJoints;
  return s;
}

double to_double(const std::string& v, const std::string& name, int line, const std::string& col) {
  char* end = nullptr;
  const double d = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0' || !std::isfinite(d)) {
    throw ConfigError(name, line, "column '" + col + "': '" + v + "' is not a finite number");
  }
  return d;
}

std::int64_t to_int(const std::string& v, const std::string& name, int line,
                    const std::string& col) {
  char* end = nullptr;
  errno = 0;
  const long long i = std::strtoll(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0' || errno == ERANGE) {
    throw ConfigError(name, line, "column '" + col + "': '" + v + "' is not an integer");
  }
  return i;
}

// "" when `s` may follow the last sample (utime `last`), else why not.
std::string order_problem(const EncoderStore& store, const EncoderSample& s) {
  if (store.empty() || s.utime_us > store.last_utime()) return "";
  return "utime_us " + std::to_string(s.utime_us) + " does not increase (previous " +
         std::to_string(store.last_utime()) + ")";
}

// A LogError's text without its leading "<file>: ".
std::string without_file(const std::string& what, const std::string& path) {
  return what.rfind(path + ": ", 0) == 0 ? what.substr(path.size() + 2) : what;
}

// Column indexes of the export dialect.
struct ExportColumns {
  std::size_t utime = 0;
  std::array<std::size_t, kJoints> position{}, homed{}, flags{};
  std::size_t sample_flags = SIZE_MAX;
};

ExportColumns export_columns(const std::vector<std::string>& fields, int line,
                             const std::string& name) {
  std::map<std::string, std::size_t> col;
  for (std::size_t i = 0; i < fields.size(); ++i) col[fields[i]] = i;
  const auto need = [&](const std::string& c) {
    const auto it = col.find(c);
    if (it == col.end()) throw ConfigError(name, line, "missing column '" + c + "'");
    return it->second;
  };
  ExportColumns c;
  c.utime = need("utime_us");
  std::vector<std::string> joints;
  const std::string pos(messages::csv::kPositionSuffix);
  const std::string vel(messages::csv::kVelocitySuffix);
  for (const auto& f : fields) {
    const bool is_pos =
        f.size() > pos.size() && f.compare(f.size() - pos.size(), pos.size(), pos) == 0;
    const bool is_vel =
        f.size() > vel.size() && f.compare(f.size() - vel.size(), vel.size(), vel) == 0;
    if (is_pos && !is_vel) joints.push_back(f.substr(0, f.size() - pos.size()));
  }
  if (joints.size() != kJoints) {
    throw ConfigError(name, line,
                      "expected six '<joint>_rad' columns, found " + std::to_string(joints.size()));
  }
  for (int j = 0; j < kJoints; ++j) {
    c.position[j] = need(joints[j] + pos);
    c.homed[j] = need(joints[j] + std::string(messages::csv::kHomedSuffix));
    c.flags[j] = need(joints[j] + std::string(messages::csv::kFlagsSuffix));
  }
  if (col.count("sample_flags")) c.sample_flags = col["sample_flags"];
  return c;
}

}  // namespace

EncoderSeries detail::parse_export_csv(LineReader& in, const std::vector<std::string>& head,
                                       int head_line, const EncoderReadOptions& o) {
  const std::string& name = in.name();
  const ExportColumns c = export_columns(head, head_line, name);
  const auto& offsets = offsets_or_fail(o, name, head_line);
  EncoderSeries out;
  out.source = name;
  EncoderStore store(kMaxEncoderSamples, static_cast<std::size_t>(in.size() / 200));
  std::string line;
  std::vector<std::string> f;
  while (next_row(in, line, f)) {
    const int n = in.line();
    if (f.size() != head.size()) wrong_field_count(name, n, head.size(), f.size());
    double position[kJoints];
    bool homed[kJoints];
    std::int32_t flags[kJoints];
    for (int j = 0; j < kJoints; ++j) {
      position[j] = to_double(f[c.position[j]], name, n, head[c.position[j]]);
      homed[j] = to_int(f[c.homed[j]], name, n, head[c.homed[j]]) != 0;
      flags[j] = static_cast<std::int32_t>(to_int(f[c.flags[j]], name, n, head[c.flags[j]]));
    }
    const std::int32_t sample_flags =
        c.sample_flags == SIZE_MAX
            ? 0
            : static_cast<std::int32_t>(to_int(f[c.sample_flags], name, n, "sample_flags"));
    const std::int64_t utime = to_int(f[c.utime], name, n, "utime_us");
    const EncoderSample s = to_sample(utime, position, homed, flags, sample_flags, offsets);
    if (!store.empty() && s.utime_us <= store.last_utime()) {
      throw ConfigError(name, n,
                        "utime_us " + std::to_string(s.utime_us) + " does not increase (previous " +
                            std::to_string(store.last_utime()) + ")");
    }
    store.push(s);
  }
  out.thinned = store.thinned();
  out.samples = store.take();
  if (out.samples.size() < 2) throw ConfigError(name, 0, "fewer than two encoder samples");
  out.notes.push_back(name + ": calibrated angles less the offsets of " + o.recorded_calibration);
  return out;
}

EncoderSeries read_joint_state_log(const std::string& path, const EncoderReadOptions& o) {
  std::string prefix;
  try {
    std::set<std::string> prefixes;
    for (const auto& [channel, n] : messages::scan_channels(path)) {
      const auto parts = messages::split_channel(channel);
      if (parts && parts->kind == messages::Kind::kJointState) prefixes.insert(parts->prefix);
    }
    if (o.prefix) {
      if (prefixes.count(*o.prefix) == 0) {
        throw ConfigError(
            path, 0,
            "no channel " + messages::channel_name(*o.prefix, messages::Kind::kJointState));
      }
      prefix = *o.prefix;
    } else if (prefixes.size() != 1) {
      throw ConfigError(path, 0,
                        prefixes.empty() ? "an LCM log without joint states (no "
                                           "*EXO_JOINT_STATE channel; with -c CONFIG its raw "
                                           "channel is re-processed)"
                                         : "holds several rigs: choose one with --prefix");
    } else {
      prefix = *prefixes.begin();
    }
  } catch (const messages::LogError& e) {
    throw ConfigError(path, 0, without_file(e.what(), path));
  }
  const auto& offsets = offsets_or_fail(o, path, 0);
  const std::string channel = messages::channel_name(prefix, messages::Kind::kJointState);
  EncoderSeries out;
  out.source = path;
  std::unique_ptr<messages::LogReader> reader;
  try {
    reader = std::make_unique<messages::LogReader>(path);
  } catch (const messages::LogError& e) {
    throw ConfigError(path, 0, without_file(e.what(), path));
  }
  messages::LogReader& log = *reader;
  messages::LogEvent ev;
  joint_state_t js;
  std::int64_t undecodable = 0;
  EncoderStore store;
  while (log.next(ev)) {
    if (ev.channel != channel) continue;
    if (!messages::decode_into(js, ev.data, ev.size)) {
      ++undecodable;
      continue;
    }
    if (messages::is_startup_message({js.utime, js.mono_ns, js.seq, js.run_id})) continue;
    bool homed[kJoints];
    for (int j = 0; j < kJoints; ++j) homed[j] = js.homed[j] != 0;
    const EncoderSample s =
        to_sample(js.utime, js.position, homed, js.flags, js.sample_flags, offsets);
    if (const std::string p = order_problem(store, s); !p.empty()) {
      throw ConfigError(path, 0, "event " + std::to_string(ev.number) + ": " + p);
    }
    store.push(s);
  }
  out.thinned = store.thinned();
  out.samples = store.take();
  if (out.samples.size() < 2) {
    throw ConfigError(path, 0, "fewer than two joint_state_t messages on " + channel);
  }
  out.notes.push_back(path + ": " + std::to_string(out.samples.size()) + " joint states on " +
                      channel + ", less the offsets of " + o.recorded_calibration);
  if (undecodable > 0) {
    out.notes.push_back(path + ": " + std::to_string(undecodable) + " events on " + channel +
                        " do not decode as joint_state_t (skipped)");
  }
  if (!log.damage().empty()) out.notes.push_back(log.damage_text());
  return out;
}

EncoderSeries read_encoder_log(const std::string& path, const EncoderReadOptions& o) {
  files::InputInfo info;
  unsigned char magic[4] = {0, 0, 0, 0};
  try {
    const int fd = files::open_input(path, -1, &info);
    const ssize_t n = ::read(fd, magic, sizeof magic);
    ::close(fd);
    (void)n;
  } catch (const files::FileError& e) {
    throw ConfigError(path, 0, e.reason());
  }
  const std::uint32_t m = (std::uint32_t{magic[0]} << 24) | (std::uint32_t{magic[1]} << 16) |
                          (std::uint32_t{magic[2]} << 8) | std::uint32_t{magic[3]};
  if (info.size >= 4 && m == messages::kLcmLogMagic) return read_joint_state_log(path, o);
  return EncoderCsvReader().read(path, o);
}

}  // namespace exodaq::calibration
