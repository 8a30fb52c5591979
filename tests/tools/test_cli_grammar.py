#!/usr/bin/env python3
"""One command-line grammar for exodaqd and every `exodaq` command (issue 16
point 4; docs/operations.md "Command line"), checked from what a user sees:

  grammar   every command's --help: -h/--help, -q/--quiet, -v/--verbose;
            -c is --config, -o is --out, -p is --prefix (the rig's channel
            prefix, tools/exodaq/command.hpp add_prefix_option), -q is --quiet,
            -v is --verbose (both ways, on one option); --json never takes a
            value.
  unknown   an unknown option is named (exit 2, one line "exodaq <command>:
            unknown option '...'"), with the closest valid one when there is
            one, even when a required option is missing too.
  errors    every command's errors are "exodaq <command>: <what>".
  json      --json output: one object, one key per line, numbers without
            rounding noise (fk: palm at [0, 0, -0.297], not -0.29699999999999999
            or -5e-17).
  docs      every option written after `exodaq <command>` or `exodaqd` in
            docs/*.md and README.md exists in that command's --help.

The commands are those `exodaq --help` lists (every EXODAQ_REGISTER_COMMAND)
and exodaqd (daemon/main.cpp). exodaq-board-sim is left out for now: it is
being restructured with the simulators (tests/tools/CMakeLists.txt).

  test_cli_grammar.py MODE --exodaq PATH --exodaqd PATH --source DIR
"""
import argparse
import glob
import os
import re
import subprocess
import sys

CANONICAL = {"-c": "--config", "-o": "--out", "-p": "--prefix", "-q": "--quiet", "-v": "--verbose"}
VALUE_TYPES = re.compile(r"^(TEXT|INT|UINT|FLOAT|NUMBER|FILE|DIR|PATH|[A-Z]+)(\b|:|$)")


def fail(msg):
    print("FAIL: " + msg, file=sys.stderr)
    sys.exit(1)


def run(argv, **kw):
    return subprocess.run(argv, capture_output=True, text=True, timeout=60, **kw)


def commands(exodaq):
    r = run([exodaq, "--help"])
    if r.returncode != 0:
        fail("exodaq --help exited %d" % r.returncode)
    names, inside = [], False
    for line in r.stdout.splitlines():
        if line.startswith("Subcommands:"):
            inside = True
            continue
        if inside:
            m = re.match(r"^  (\S+)\s", line)
            if m:
                names.append(m.group(1))
    if len(names) < 10:
        fail("exodaq --help lists %d commands: %s" % (len(names), names))
    return names


def options(help_text):
    """{name: takes_value} and the list of (names, takes_value) per option."""
    per_option, by_name = [], {}
    for line in help_text.splitlines():
        m = re.match(r"^  (-\S+)(?:\s(\S+))?", line)
        if not m:
            continue
        names = m.group(1).split(",")
        rest = (m.group(2) or "")
        takes_value = bool(VALUE_TYPES.match(rest)) and not rest.islower()
        per_option.append((names, takes_value))
        for n in names:
            by_name[n] = takes_value
    return per_option, by_name


def help_of(argv):
    r = run(argv + ["--help"])
    if r.returncode != 0:
        fail("%s --help exited %d: %s" % (" ".join(argv), r.returncode, r.stderr))
    return r.stdout


def all_helps(a):
    helps = {("exodaq", c): help_of([a.exodaq, c]) for c in commands(a.exodaq)}
    helps[("exodaqd", None)] = help_of([a.exodaqd])
    return helps


def label(key):
    return key[0] if key[1] is None else "exodaq " + key[1]


def check_grammar(a):
    checked = 0
    for key, text in all_helps(a).items():
        per_option, by_name = options(text)
        for need in ("-h", "--help", "-q", "--quiet", "-v", "--verbose"):
            if need not in by_name:
                fail("%s has no %s" % (label(key), need))
        for names, takes_value in per_option:
            shorts = [n for n in names if re.match(r"^-[^-]$", n)]
            longs = [n for n in names if n.startswith("--")]
            for s in shorts:
                if s in CANONICAL and CANONICAL[s] not in longs:
                    fail("%s: %s is %s, not %s" % (label(key), s, ",".join(names), CANONICAL[s]))
            for short, long in CANONICAL.items():
                if long in longs and short not in shorts:
                    fail("%s: %s has no %s" % (label(key), long, short))
            if "--json" in longs and takes_value:
                fail("%s: --json takes a value" % label(key))
            checked += 1
    print("grammar: %d options of %d commands follow -c/-o/-p/-q/-v/--json" % (checked, len(all_helps(a))))


def check_unknown(a):
    cases = 0
    for c in commands(a.exodaq):
        r = run([a.exodaq, c, "--definitely-not-an-option"])
        want = ("exodaq %s: unknown option '--definitely-not-an-option' "
                "(exodaq %s --help lists the options)\n" % (c, c))
        if r.returncode != 2 or r.stderr != want:
            fail("exodaq %s --definitely-not-an-option: exit %d, stderr %r (want %r)"
                 % (c, r.returncode, r.stderr, want))
        r = run([a.exodaq, c, "--quite"])
        if r.returncode != 2 or "unknown option '--quite'; did you mean '--quiet'?" not in r.stderr:
            fail("exodaq %s --quite: exit %d, %r" % (c, r.returncode, r.stderr))
        cases += 2
    # The reproduction: export's old --csv, with the required input missing too.
    r = run([a.exodaq, "export", "--csv", "x.csv"])
    if r.returncode != 2 or not r.stderr.startswith("exodaq export: unknown option '--csv'"):
        fail("exodaq export --csv x.csv: %r" % r.stderr)
    r = run([a.exodaq, "replay", "--confg", "x.yaml"])
    if "unknown option '--confg'; did you mean '--config'?" not in r.stderr:
        fail("exodaq replay --confg: %r" % r.stderr)
    r = run([a.exodaq, "fk", "-qx"])  # clustered short flags, one unknown
    if r.returncode != 2 or not r.stderr.startswith("exodaq fk: unknown option '-x'"):
        fail("exodaq fk -qx: %r" % r.stderr)
    r = run([a.exodaq, "exprot"])
    if r.returncode != 2 or "unknown command 'exprot'; did you mean 'export'?" not in r.stderr:
        fail("exodaq exprot: %r" % r.stderr)
    r = run([a.exodaqd, "--confg", "x.yaml"])
    if r.returncode != 2 or r.stderr != ("exodaqd: unknown option '--confg'; did you mean "
                                         "'--config'? (exodaqd --help lists the options)\n"):
        fail("exodaqd --confg: exit %d, %r" % (r.returncode, r.stderr))
    print("unknown: %d commands name an unknown option and suggest the closest" % (cases // 2))


def check_errors(a):
    missing = "/nonexistent/exodaq-test"
    src = a.source
    bad = {
        "calibrate": ["--encoders", missing, "--markers", missing, "--bounds", missing, "-o", "x"],
        "echo": ["-c", missing],
        "example-session": ["/tmp/exodaq-grammar-never", "-c", missing],
        "export": [missing],
        "fk": ["--model", missing, "--joints-deg", "0,0,0,0,0,0"],
        "ik": ["--model", missing, "--palm-position", "0,0,0", "--palm-quaternion", "1,0,0,0"],
        "plot": [missing, "-o", "/tmp/exodaq-grammar-never"],
        "record": ["-c", missing, "-o", "/tmp/exodaq-grammar-never.lcm"],
        "replay": [missing, "-c", src + "/config/sim.yaml", "-o", "/tmp/exodaq-grammar-never.lcm"],
        "shoulder-cor": ["--markers", missing, "--torso", "1,2,3", "--humerus", "4,5,6",
                         "--torso-axis", "1,2", "--humerus-axis", "4,5"],
        "status": ["-c", missing],
        "view": ["-c", missing, "--port", "0"],
    }
    for c in commands(a.exodaq):
        if c not in bad:
            fail("no bad invocation for exodaq %s in test_cli_grammar.py" % c)
        r = run([a.exodaq, c] + bad[c])
        lines = r.stderr.splitlines()
        if r.returncode == 0 or not lines:
            fail("exodaq %s %s: exit %d, stderr %r" % (c, bad[c], r.returncode, r.stderr))
        for line in lines:
            if not line.startswith("exodaq %s: " % c):
                fail("exodaq %s: error line %r does not start with 'exodaq %s: '" % (c, line, c))
        if missing not in r.stderr or "No such file or directory" not in r.stderr:
            fail("exodaq %s: the error does not name the file and the reason: %r" % (c, r.stderr))
    r = run([a.exodaqd, "-c", missing, "--check-config"])
    if r.returncode == 0 or not r.stderr.startswith("exodaqd: "):
        fail("exodaqd -c missing: %r" % r.stderr)
    if os.path.exists("/tmp/exodaq-grammar-never") or os.path.exists("/tmp/exodaq-grammar-never.lcm"):
        fail("a command that failed on its input created its output")
    print("errors: every command's error lines start 'exodaq <command>: ' and name file and reason")


def check_json(a):
    import json
    r = run([a.exodaq, "fk", "--joints-deg", "45,-90,90,0,0,0", "--json"])
    if r.returncode != 0:
        fail("fk --json: %s" % r.stderr)
    obj = json.loads(r.stdout)
    if obj["palm_position_m"] != [0, 0, -0.297] or obj["elbow_position_m"] != [0, 0, -0.145]:
        fail("fk --json: palm %s, elbow %s" % (obj["palm_position_m"], obj["elbow_position_m"]))
    if "e-1" in r.stdout or "9999999" in r.stdout or "-0," in r.stdout or "-0]" in r.stdout:
        fail("fk --json prints rounding noise:\n" + r.stdout)
    lines = r.stdout.rstrip("\n").split("\n")
    if lines[0] != "{" or lines[-1] != "}" or \
            any(not re.match(r'^  "[a-z_]+": .*[^,]?$', l) for l in lines[1:-1]):
        fail("fk --json is not one key per line:\n" + r.stdout)
    r = run([a.exodaq, "ik", "--palm-position", "0,0,-0.297", "--palm-quaternion",
             "0,0.382683,0.92388,0", "--json"])
    obj = json.loads(r.stdout)
    if not obj["solutions"]:
        fail("ik --json: no solutions:\n" + r.stdout)
    print("json: fk and ik print one object, one key per line, without rounding noise")


def invocations(text, names):
    """(command, [options]) for each `exodaq <command> ...` / `exodaqd ...` in text."""
    text = re.sub(r"\\\n\s*", " ", text)  # shell line continuations
    found = []
    for m in re.finditer(r"(?:^|[\s`/(])exodaq(d)?(?=[\s`])", text, re.M):
        # Only where a command starts (not `systemctl status exodaqd`,
        # `journalctl -u exodaqd`, `scripts/build exodaqd exodaq`).
        before = text[:m.start() + 1].rsplit("\n", 1)[-1]
        before = re.sub(r"[\w./-]*$", "", before)  # a path: build/tools/
        if not re.search(r"(^|`|\$ |&& |; |\| |sudo |\()\s*$", before):
            continue
        rest = text[m.end():].split("\n", 1)[0]
        cmd = None
        if m.group(1) is None:
            w = re.match(r"\s+([a-z][a-z-]*)", rest)
            if not w or w.group(1) not in names:
                continue
            cmd = w.group(1)
            rest = rest[w.end():]
        # The invocation ends at the end of its code span, a pipe, ; && or a comment.
        depth, end = 0, len(rest)
        for i, ch in enumerate(rest):
            if ch in "[(":
                depth += 1
            elif ch in "])":
                depth -= 1
            elif ch == "`" or (depth <= 0 and (ch in "|;" or rest[i:i + 2] == "&&" or
                                              (ch == "#" and (i == 0 or rest[i - 1] == " ")))):
                end = i
                break
        opts = []
        for tok in rest[:end].split():
            tok = tok.strip("[](),.")
            if re.match(r"^--?[A-Za-z][A-Za-z0-9-]*", tok):
                opts.append(re.match(r"^--?[A-Za-z][A-Za-z0-9-]*", tok).group(0))
        found.append((cmd, opts))
    return found


def check_docs(a):
    names = commands(a.exodaq)
    helps = all_helps(a)
    files = sorted(glob.glob(os.path.join(a.source, "docs", "*.md"))) + \
        [os.path.join(a.source, "README.md")]
    total, with_options = 0, 0
    problems = []
    for path in files:
        text = open(path, encoding="utf-8").read()
        for cmd, opts in invocations(text, names):
            total += 1
            with_options += 1 if opts else 0
            key = ("exodaqd", None) if cmd is None else ("exodaq", cmd)
            _, by_name = options(helps[key])
            for o in opts:
                if o not in by_name:
                    problems.append("%s: `%s` has no option %s" % (
                        os.path.relpath(path, a.source), label(key), o))
    if problems:
        fail("documented options that do not exist:\n  " + "\n  ".join(sorted(set(problems))))
    if with_options < 30:
        fail("only %d documented invocations with options found in %d files: the parser is "
             "broken" % (with_options, len(files)))
    print("docs: %d invocations (%d with options) in %d files, every option exists"
          % (total, with_options, len(files)))


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["grammar", "unknown", "errors", "json", "docs"])
    ap.add_argument("--exodaq", required=True)
    ap.add_argument("--exodaqd", required=True)
    ap.add_argument("--source", required=True)
    a = ap.parse_args(argv)
    {"grammar": check_grammar, "unknown": check_unknown, "errors": check_errors,
     "json": check_json, "docs": check_docs}[a.mode](a)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
