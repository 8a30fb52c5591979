#!/usr/bin/env python3
"""`exodaq view` as a command, without a browser or a daemon.

  cli_test.py EXODAQ SOURCE_DIR

Bad input gets one clear line (`exodaq view: what`) and exit 2, a port in use
exit 1; a good start prints the URL, serves the page byte for byte as it is in
tools/view/web/ (built into the binary), /state.json, and stops by itself with
--duration.
"""
import json
import os
import socket
import subprocess
import sys
import urllib.request

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL: " + what, file=sys.stderr)


def run(exodaq, *args):
    p = subprocess.run([exodaq, "view"] + list(args), capture_output=True, text=True, timeout=30)
    return p.returncode, p.stdout, p.stderr


def main():
    exodaq, src = sys.argv[1], sys.argv[2]

    rc, _, err = run(exodaq, "--config", "/nonexistent/exodaqd.yaml")
    check(rc == 2 and err == "exodaq view: /nonexistent/exodaqd.yaml: cannot open: No such file or directory\n",
          "missing config: rc %d, %r" % (rc, err))
    sim = os.path.join(src, "config", "sim.yaml")
    rc, _, err = run(exodaq, "--model", sim)
    check(rc == 2 and err == "exodaq view: %s:4: missing field 'name' in model\n" % sim,
          "a service config given as a model: rc %d, %r" % (rc, err))
    rc, _, err = run(exodaq, "--bind", "localhost")
    check(rc == 1 and "exodaq view: cannot listen on localhost port 8077: 'localhost' is not a numeric" in err,
          "bind to a name: rc %d, %r" % (rc, err))
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        rc, _, err = run(exodaq, "--config", sim, "--port", str(port), "--duration", "5")
        check(rc == 1 and err == "exodaq view: cannot listen on 127.0.0.1 port %d: Address already in use\n" % port,
              "port in use: rc %d, %r" % (rc, err))

    model = os.path.join(src, "config", "models", "macaque_exo.yaml")
    p = subprocess.Popen([exodaq, "view", "--model", model, "--port", "0", "--duration", "3"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    check(line.startswith("exodaq view: serving http://127.0.0.1:"), "first line %r" % line)
    url = line.split()[3]
    web = os.path.join(src, "tools", "view", "web")
    for path, name, ctype in (("", "index.html", "text/html"), ("view.js", "view.js", "text/javascript"),
                              ("view.css", "view.css", "text/css")):
        with urllib.request.urlopen(url + path, timeout=5) as r:
            body = r.read()
            check(r.headers["Content-Type"].startswith(ctype), "%s: %s" % (name, r.headers["Content-Type"]))
        with open(os.path.join(web, name), "rb") as f:
            check(body == f.read(), "/%s is not tools/view/web/%s byte for byte" % (path, name))
    with urllib.request.urlopen(url + "state.json", timeout=5) as r:
        state = json.loads(r.read())
    check(state["model"]["name"] == "macaque_exo" and not state["model"]["calibrated"],
          "model %s" % state["model"])
    check(abs(state["model"]["reach_m"] - 0.297) < 1e-12, "reach %s" % state["model"]["reach_m"])
    check(state["view"]["url"] == "udpm://239.255.76.67:7667?ttl=0", "url %s" % state["view"]["url"])
    check(state["stream"]["state"] == "waiting" and state["frame"] is None, "stream %s" % state["stream"])
    rc = p.wait(timeout=30)
    check(rc == 0, "--duration 3: exit %d, %s" % (rc, p.stderr.read()))

    print("%d check(s) failed" % len(failures) if failures else "view CLI test passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
