#include "exodaq/drivers/replay_source.hpp"

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "recording.hpp"

namespace exodaq::drivers {

ReplaySource::ReplaySource(const ReplaySettings& settings, const SourceContext& context)
    : settings_(settings), context_(context) {
  if (settings_.format != "auto" && settings_.format != "lcm" && settings_.format != "candump") {
    throw std::runtime_error("replay: unknown format '" + settings_.format +
                             "' (auto, lcm or candump)");
  }
  if (settings_.path.empty()) throw std::runtime_error("replay: no input file given");
  if (settings_.channel.empty()) {
    settings_.channel = std::string(msg::base_channel(msg::Kind::kEncoderRaw));
  }
}

ReplayFormat ReplaySource::detect_format(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("replay: cannot open '" + path + "': " + std::strerror(errno));
  std::array<unsigned char, 4> magic{};
  in.read(reinterpret_cast<char*>(magic.data()), 4);
  if (in.gcount() == 4) {
    const std::uint32_t m = (std::uint32_t{magic[0]} << 24) | (std::uint32_t{magic[1]} << 16) |
                            (std::uint32_t{magic[2]} << 8) | std::uint32_t{magic[3]};
    if (m == msg::kLcmLogMagic) return ReplayFormat::kLcm;
  }
  in.clear();
  in.seekg(0);
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos) continue;
    if (line[first] == '(') return ReplayFormat::kCandump;
    break;
  }
  throw std::runtime_error("replay: '" + path +
                           "' is neither an LCM log (lcm-logger) nor a candump -l log; "
                           "give --format to say which it is");
}

void ReplaySource::start() {
  if (!recording_) {
    const ReplayFormat format = settings_.format == "lcm"       ? ReplayFormat::kLcm
                                : settings_.format == "candump" ? ReplayFormat::kCandump
                                                                : detect_format(settings_.path);
    auto rec = std::make_unique<replay::Recording>();
    rec->summary.format = format;
    if (format == ReplayFormat::kLcm) {
      replay::load_lcm(settings_, context_, *rec);
    } else {
      replay::load_candump(settings_.path, *rec);
    }
    if (rec->entries.empty()) {
      throw std::runtime_error("replay: '" + settings_.path + "' holds no encoder sample");
    }
    rec->summary.samples = static_cast<std::int64_t>(rec->entries.size());
    rec->summary.duration_s = static_cast<double>(rec->entries.back().sample.mono_ns -
                                                  rec->entries.front().sample.mono_ns) *
                              1e-9;
    recording_ = std::move(rec);
  }
  next_ = 0;
  last_seq_ = -1;
  stats_ = recording_->stats;
}

ReadStatus ReplaySource::read(const CycleTime& /*time*/, EncoderSample& out) noexcept {
  const auto& entries = recording_->entries;
  if (next_ >= entries.size()) return ReadStatus::kEndOfStream;
  const replay::Entry& e = entries[next_++];
  out = e.sample;
  last_seq_ = e.seq;
  return out.present ? ReadStatus::kSample : ReadStatus::kNoSample;
}

std::int64_t ReplaySource::next_sample_mono_ns() const noexcept {
  const auto& entries = recording_->entries;
  return next_ < entries.size() ? entries[next_].sample.mono_ns : -1;
}

const ReplayLoadSummary& ReplaySource::summary() const noexcept {
  static const ReplayLoadSummary kNone{};
  return recording_ ? recording_->summary : kNone;
}

const std::vector<ReplayIssue>& ReplaySource::issues() const noexcept {
  static const std::vector<ReplayIssue> kNone;
  return recording_ ? recording_->issues : kNone;
}

std::int64_t ReplaySource::sample_count() const noexcept {
  return recording_ ? static_cast<std::int64_t>(recording_->entries.size()) : 0;
}

ReplaySource::~ReplaySource() = default;

}  // namespace exodaq::drivers
