"""config/sim.yaml rewritten for one test run: the Python tests' one copy of
what tests/support/sim_daemon.cpp (test::write_sim_config) does for C++.

Paths become absolute (the copy lives in the test's own folder), the channel
prefix is the test's own (other tests and daemons may share the multicast
group), and optionally the LCM URL too. Each edit must match exactly once: when
config/sim.yaml changes, a test fails here instead of running on paths it did
not mean.
"""
import os
import re


def _replace_once(text, pattern, replacement, what):
    text, n = re.subn(pattern, replacement, text, flags=re.M)
    if n != 1:
        raise RuntimeError("config/sim.yaml: %d matches for %s, expected 1" % (n, what))
    return text


def write_sim_config(source_dir, work, prefix, url=None, name="exodaqd.yaml"):
    """Writes the copy into `work`/`name` and returns its path."""
    cfg = os.path.join(os.path.abspath(source_dir), "config") + "/"
    text = open(os.path.join(cfg, "sim.yaml")).read()
    text = _replace_once(text, r"^model: ", "model: " + cfg, "'model:'")
    text = _replace_once(text, r"^calibration: ", "calibration: " + cfg, "'calibration:'")
    text = _replace_once(text, r"task: tasks/", "task: " + cfg + "tasks/", "'task: tasks/'")
    text = _replace_once(text, r'prefix: ""', 'prefix: "%s"' % prefix, "'prefix: \"\"'")
    if url is not None:
        text = _replace_once(text, r'^(\s*url:\s*)"[^"]*"', r'\g<1>"%s"' % url, "the lcm url")
    # sim.yaml asks for SCHED_FIFO 50; without privilege ask for none, to keep the log quiet.
    if os.geteuid() != 0:
        text = _replace_once(text, r"priority: 50 ", "priority: 0 ", "'priority: 50 '")
    path = os.path.join(work, name)
    with open(path, "w") as f:
        f.write(text)
    return path
