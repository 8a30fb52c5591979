#pragma once
// Which live rig a listening command (exodaq echo, exodaq status) listens to:
// -c/--config FILE, -p/--prefix P and -u/--url URL. The daemon's service
// config supplies the LCM URL, the prefix and the clock policy; --prefix and
// --url given on the command line win over it.
#include <CLI/CLI.hpp>

#include <memory>
#include <optional>
#include <string>

#include "command.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/settings/service_config.hpp"

namespace exodaq::tools {

struct LiveRig {
  std::string config;
  std::string prefix;
  bool prefix_given = false;
  std::string url = messages::kDefaultUrl;
  bool url_given = false;
  std::optional<settings::RequireSync> clock_policy;  // from --config
};

// Adds -c/--config, -p/--prefix and -u/--url to `app`, storing into `rig`
// (which must outlive the parse: a member of the command's shared options).
inline void add_live_rig_options(CLI::App& app, LiveRig& rig) {
  app.add_option("-c,--config", rig.config,
                 "the daemon's service config: LCM URL, prefix and clock policy from it");
  add_prefix_option(app, rig.prefix, "default: the config's, else none")
      ->each([&rig](const std::string&) { rig.prefix_given = true; });
  app.add_option("--url,-u", rig.url, "LCM URL")
      ->capture_default_str()
      ->each([&rig](const std::string&) { rig.url_given = true; });
}

// Fills in from --config what the command line left out.
inline void resolve_live_rig(LiveRig& rig) {
  if (rig.config.empty()) return;
  const settings::ServiceConfig cfg = settings::load_service_config(rig.config);
  if (!rig.url_given) rig.url = cfg.lcm.url;
  if (!rig.prefix_given) rig.prefix = cfg.lcm.prefix;
  rig.clock_policy = cfg.clock.require_sync;
}

}  // namespace exodaq::tools
