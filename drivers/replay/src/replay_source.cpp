#include "exodaq/drivers/replay_source.hpp"

#include <pthread.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <thread>

#include "entry_ring.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "recording.hpp"

namespace exodaq::drivers {

namespace replay {

namespace {

// The first pass: counts the samples and notes their first and last instants.
class CountingSink final : public EntrySink {
 public:
  bool put(const Entry& e) override {
    if (count_ == 0) first_mono_ns_ = e.sample.mono_ns;
    last_mono_ns_ = e.sample.mono_ns;
    ++count_;
    return true;
  }
  std::int64_t count() const noexcept { return count_; }
  // In double: a damaged file's instants may lie further apart than int64 holds.
  double duration_s() const noexcept {
    return (static_cast<double>(last_mono_ns_) - static_cast<double>(first_mono_ns_)) * 1e-9;
  }

 private:
  std::int64_t count_ = 0;
  std::int64_t first_mono_ns_ = 0;
  std::int64_t last_mono_ns_ = 0;
};

// The second pass: into the ring, no further than the first pass counted (a
// file still growing replays as it was at start()).
class RingSink final : public EntrySink {
 public:
  RingSink(EntryRing& ring, std::int64_t limit) : ring_(ring), limit_(limit) {}
  bool put(const Entry& e) override {
    if (count_ >= limit_ || !ring_.push(e)) return false;
    ++count_;
    return true;
  }
  std::int64_t count() const noexcept { return count_; }

 private:
  EntryRing& ring_;
  std::int64_t limit_;
  std::int64_t count_ = 0;
};

// `counted`: nullptr for the first pass, its results for the second.
void read_pass(const ReplaySettings& settings, const SourceContext& context, ReplayFormat format,
               const Pass* counted, Pass& out, EntrySink& sink) {
  if (format == ReplayFormat::kLcm) {
    read_lcm(settings, context, counted, out, sink);
  } else {
    std::unique_ptr<FrameAssembler> assembler;
    if (context.frame_assembler) assembler = context.frame_assembler(settings.protocol);
    if (!assembler && settings.protocol != "socketcan") {
      throw std::runtime_error("replay: no " + settings.protocol +
                               " configuration to read the candump log '" + settings.path +
                               "' with (source." + settings.protocol + ")");
    }
    if (!assembler) assembler = make_board_frame_assembler(BoardDecoderConfig{});
    read_candump(settings.path, *assembler, out, sink);
  }
}

}  // namespace

// The first pass's results and the second pass, running on its own thread.
struct State {
  State(const ReplaySettings& s, const SourceContext& c, std::size_t capacity)
      : settings(s), context(c), ring(capacity) {}

  const ReplaySettings settings;
  const SourceContext context;
  Pass first;
  EntryRing ring;
  std::thread reader;
  bool streaming = false;    // the reader was started and not stopped since
  std::string stream_error;  // written by the reader before ring.finish()
  bool stream_error_reported = false;

  void start_stream();
  void stop_stream() noexcept;
  void run_stream() noexcept;
};

void State::start_stream() {
  stop_stream();
  ring.reset();
  stream_error.clear();
  stream_error_reported = false;
  reader = std::thread([this] { run_stream(); });
  streaming = true;
  // Read ahead before the first cycle: a paced loop starts with a full ring.
  ring.wait_filled();
}

void State::stop_stream() noexcept {
  ring.cancel();
  if (reader.joinable()) reader.join();
  streaming = false;
}

void State::run_stream() noexcept {
  pthread_setname_np(pthread_self(), "exodaq-replay");
  try {
    RingSink sink(ring, first.summary.samples);
    Pass second;
    read_pass(settings, context, first.summary.format, &first, second, sink);
    if (sink.count() < first.summary.samples && !ring.cancelled()) {
      stream_error = "'" + settings.path +
                     "' changed during the replay: " + std::to_string(sink.count()) + " of its " +
                     std::to_string(first.summary.samples) + " samples were read";
    }
  } catch (const std::exception& e) {
    stream_error = e.what();
  }
  ring.finish();
}

}  // namespace replay

ReplaySource::ReplaySource(const ReplaySettings& settings, const SourceContext& context,
                           std::size_t buffer_samples)
    : settings_(settings), context_(context), buffer_samples_(buffer_samples) {
  if (settings_.format != "auto" && settings_.format != "lcm" && settings_.format != "candump") {
    throw std::runtime_error("replay: unknown format '" + settings_.format +
                             "' (auto, lcm or candump)");
  }
  if (settings_.path.empty()) throw std::runtime_error("replay: no input file given");
  if (settings_.channel.empty()) {
    settings_.channel = std::string(messages::base_channel(messages::Kind::kEncoderRaw));
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
    if (m == messages::kLcmLogMagic) return ReplayFormat::kLcm;
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

void ReplaySource::load() {
  const ReplayFormat format = settings_.format == "lcm"       ? ReplayFormat::kLcm
                              : settings_.format == "candump" ? ReplayFormat::kCandump
                                                              : detect_format(settings_.path);
  auto state = std::make_unique<replay::State>(settings_, context_, buffer_samples_);
  replay::Pass& first = state->first;
  first.summary.format = format;
  replay::CountingSink counter;
  replay::read_pass(settings_, context_, format, nullptr, first, counter);
  if (counter.count() == 0) {
    throw std::runtime_error("replay: '" + settings_.path + "' holds no encoder sample");
  }
  first.summary.samples = counter.count();
  first.summary.duration_s = counter.duration_s();
  first.issues.reserve(first.issues.size() + 1);  // room for a read error of the second pass
  state_ = std::move(state);
}

void ReplaySource::start() {
  if (!state_) {
    load();
  } else if (state_->streaming && position_ == 0) {
    return;  // nothing read yet: already at the start
  }
  state_->start_stream();
  position_ = 0;
  last_seq_ = -1;
  stats_ = state_->first.stats;
}

void ReplaySource::stop() noexcept {
  if (state_) state_->stop_stream();
}

ReadStatus ReplaySource::read(const CycleTime& /*time*/, EncoderSample& out) noexcept {
  if (!state_) return ReadStatus::kEndOfStream;
  replay::EntryRing& ring = state_->ring;
  const replay::Entry* e = ring.peek(batch());
  if (e == nullptr) {
    report_stream_error();
    return ReadStatus::kEndOfStream;
  }
  out = e->sample;
  last_seq_ = e->seq;
  ring.pop();
  ++position_;
  return out.present ? ReadStatus::kSample : ReadStatus::kNoSample;
}

// A read error in the second pass (or a file that changed) joins the issues
// when the stream ends: moved into the slot reserved at load, no allocation.
void ReplaySource::report_stream_error() noexcept {
  replay::State& s = *state_;
  if (s.stream_error.empty() || s.stream_error_reported || !s.ring.finished()) return;
  s.stream_error_reported = true;
  if (s.first.issues.size() < s.first.issues.capacity()) {
    s.first.issues.push_back({position_, std::move(s.stream_error)});
  }
}

std::int64_t ReplaySource::next_sample_mono_ns() const noexcept {
  if (!state_) return -1;
  const replay::Entry* e = state_->ring.peek(batch());
  return e != nullptr ? e->sample.mono_ns : -1;
}

std::size_t ReplaySource::batch() const noexcept {
  // Paced, the loop waits for one sample (a ring that ran dry is the disk
  // falling behind); flat out, for half a ring, so that a reader and a loop
  // sharing one core take turns by the thousand, not by the sample.
  return settings_.speed > 0.0 ? 1 : state_->ring.capacity() / 2;
}

const JointResumeSet* ReplaySource::resume_state() const noexcept {
  if (!state_ || state_->first.summary.resumed_at_seq < 0) return nullptr;
  return &state_->first.resume;
}

const ReplayLoadSummary& ReplaySource::summary() const noexcept {
  static const ReplayLoadSummary kNone{};
  return state_ ? state_->first.summary : kNone;
}

const std::vector<ReplayIssue>& ReplaySource::issues() const noexcept {
  static const std::vector<ReplayIssue> kNone;
  return state_ ? state_->first.issues : kNone;
}

std::int64_t ReplaySource::sample_count() const noexcept {
  return state_ ? state_->first.summary.samples : 0;
}

void ReplaySource::diagnose(SourceDiagnostics& out) const noexcept {
  // Only what the recording decides: a replay's output is the same at any
  // speed on any machine (the read-ahead ring's waits are exodaq replay's
  // last line).
  out.add("samples_delivered", position_);
  out.add("samples_recorded", sample_count());
  out.set_state(position_ < sample_count() ? "playing" : "at the end");
}

std::size_t ReplaySource::buffer_capacity() const noexcept {
  return state_ ? state_->ring.capacity() : 0;
}

std::int64_t ReplaySource::buffer_waits() const noexcept {
  return state_ ? state_->ring.consumer_waits() : 0;
}

ReplaySource::~ReplaySource() {
  stop();
}

}  // namespace exodaq::drivers
