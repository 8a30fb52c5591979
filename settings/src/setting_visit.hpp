#pragma once
// The declarations of setting_list.hpp as data, and visits of a
// configuration's settings in their declared order: what the parser,
// --print-config, the reload classes and the docs table iterate.
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/settings/service_config.hpp"
#include "exodaq/settings/setting_list.hpp"

namespace exodaq::settings::detail {

// One row of setting_list.hpp, less its field.
struct Declaration {
  std::string_view key;
  Unit unit;
  Rule rule;
  Reload reload;
  std::string_view doc;
};

#define EXODAQ_SETTING_VISIT(type, field, key, def, unit, rule, reload, doc) \
  visit(Declaration{key, unit, rule, reload, doc}, s.field);

// visit(const Declaration&, field&) for each row of one list, on the struct
// holding its fields (ServiceConfig for the top level and kinematics).
template <class S, class F>
void visit_top(S& s, F&& visit) {
  EXODAQ_TOP_SETTINGS(EXODAQ_SETTING_VISIT)
}
template <class S, class F>
void visit_loop(S& s, F&& visit) {
  EXODAQ_LOOP_SETTINGS(EXODAQ_SETTING_VISIT)
}
template <class S, class F>
void visit_encoders(S& s, F&& visit) {
  EXODAQ_ENCODER_SETTINGS(EXODAQ_SETTING_VISIT)
}
template <class S, class F>
void visit_joint(S& s, F&& visit) {
  EXODAQ_JOINT_SETTINGS(EXODAQ_SETTING_VISIT)
}
template <class S, class F>
void visit_kinematics(S& s, F&& visit) {
  EXODAQ_KINEMATICS_SETTINGS(EXODAQ_SETTING_VISIT)
}
template <class S, class F>
void visit_lcm(S& s, F&& visit) {
  EXODAQ_LCM_SETTINGS(EXODAQ_SETTING_VISIT)
}
template <class S, class F>
void visit_clock(S& s, F&& visit) {
  EXODAQ_CLOCK_SETTINGS(EXODAQ_SETTING_VISIT)
}
template <class S, class F>
void visit_logging(S& s, F&& visit) {
  EXODAQ_LOGGING_SETTINGS(EXODAQ_SETTING_VISIT)
}

#undef EXODAQ_SETTING_VISIT

// Where the joint entries sit, and the section name each takes.
inline constexpr std::string_view kJointsSection = "encoders.joints";
inline std::string joint_section(std::size_t i) {
  return std::string(kJointsSection) + "[" + std::to_string(i) + "]";
}

// visit(section, declaration, field&) for every declared setting of `c`, in
// --print-config's order (section "" is the top level; a joint's is
// "encoders.joints[i]").
template <class C, class F>
void visit_settings(C& c, F&& visit) {
  const auto in = [&visit](std::string section) {
    return [&visit, section](const Declaration& d, auto& v) { visit(section, d, v); };
  };
  visit_top(c, in(""));
  visit_loop(c.loop, in("loop"));
  visit_encoders(c.encoders, in("encoders"));
  for (std::size_t i = 0; i < c.encoders.joints.size(); ++i) {
    visit_joint(c.encoders.joints[i], in(joint_section(i)));
  }
  visit_kinematics(c, in("kinematics"));
  visit_lcm(c.lcm, in("lcm"));
  visit_clock(c.clock, in("clock"));
  visit_logging(c.logging, in("logging"));
}

// The choices of a rule ("a|b" -> {a, b}).
std::vector<std::string> choices_of(const Rule& r);
// A field's value as text (numbers in their shortest exact form, in the
// key's unit; an enum by its choice's name).
std::string value_text(const Declaration& d, bool v);
std::string value_text(const Declaration& d, int v);
std::string value_text(const Declaration& d, std::int64_t v);
std::string value_text(const Declaration& d, double v);
std::string value_text(const Declaration& d, const std::string& v);
std::string value_text(const Declaration& d, RequireSync v);

}  // namespace exodaq::settings::detail
