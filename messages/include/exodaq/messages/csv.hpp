#pragma once
// The one CSV schema of exodaq (docs/messages.md "CSV"): what `exodaq echo`
// prints, `exodaq export` writes, `exodaq plot` draws from and `exodaq
// calibrate` reads. Every row starts with the message header, `utime_us,
// mono_ns, seq, run_id`; each column is named once, with its unit in the
// name; per-joint columns carry the joint's name (`shoulder_abduction_rad`).
// Values are exact: integers in decimal, doubles in the shortest text that
// reads back to the same double (never "-0"), booleans 0/1, the run id as
// run_id_text(), strings as they are (RFC 4180 quoting).
#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/messages/message.hpp"
#include "exodaq/wire_constants.hpp"

namespace exodaq::messages::csv {

inline constexpr int kJoints = wire::kJointCount;
using JointNames = std::array<std::string, kJoints>;

// Joint names made into column stems: letters, digits and '_' kept, anything
// else '_'; an empty or repeated name becomes joint<N> (1-based).
JointNames joint_columns(const std::string (&names)[kJoints]);
// joint1 .. joint6, for a header before any message has been seen.
JointNames numbered_joints();

// Suffixes of the per-joint columns of joint_state_t.
inline constexpr std::string_view kPositionSuffix = "_rad";
inline constexpr std::string_view kVelocitySuffix = "_vel_rad_s";
inline constexpr std::string_view kCountSuffix = "_count";
inline constexpr std::string_view kHomedSuffix = "_homed";
inline constexpr std::string_view kFlagsSuffix = "_flags";

// The columns of one message kind (`joints` names joint_state_t's and
// status_t's per-joint columns; the others ignore it).
std::vector<std::string> header(Kind k, const JointNames& joints);
// The joint names a message's columns use (joint_state_t.name,
// status_t.joint_name; numbered for the others).
JointNames joints_of(const Message& m);
// One message's values in header() order, appended to `out`.
void append_values(const Message& m, std::vector<std::string>& out);
// Whether a column of header(k, …) holds text (a string field or a run id:
// JSON writes it as a string) rather than a number.
bool is_text_column(Kind k, std::string_view column);

// One cycle (exodaq export): the header, joint_state_t's columns, then
// palm_pose_t's (empty when the cycle has no palm message).
std::vector<std::string> cycle_header(const JointNames& joints);
void append_cycle(const joint_state_t& joints, const palm_pose_t* palm,
                  std::vector<std::string>& out);

// Exact shortest round-trip text of a double ("0.1", "1e-06", "nan", "inf");
// -0 is written "0".
std::string number(double v);
// RFC 4180: quotes a value that holds a comma, quote or line break.
std::string escape(std::string_view v);
// A whole line, without the line break.
std::string line(const std::vector<std::string>& values);
// How split() treats spaces around a value. kKeep: values as written (what
// line() wrote). kTrim: spaces and tabs around an unquoted value are dropped
// and a quote opens a quoted value only at its start (motion-capture exports
// and hand-written calibration inputs write "1, 2, 3").
enum class Spaces { kKeep, kTrim };
// Splits one line (no line break) into its values, undoing escape(); false
// when a quoted value is not closed.
bool split(std::string_view line, std::vector<std::string>& out, Spaces spaces = Spaces::kKeep);

}  // namespace exodaq::messages::csv
