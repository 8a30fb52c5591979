#!/usr/bin/env python3
"""`exodaq view` in headless Chromium against a real exodaqd on the simulated rig.

  browser_test.py --exodaq BIN --exodaqd BIN --source-dir DIR --out DIR [--lcmtypes DIR]

The daemon, the view and this script's own LCM receiver share a private LCM
URL (a port of their own, ttl=0) and channel prefix. Steps, each asserted on
the page's state (window.exodaqView.state()) and on the canvas's pixels, with
a screenshot into --out:
  1 waiting      the page connects before any daemon runs and says so
  2 live         the drawn posture follows the stream: every sampled drawn
                 frame equals the joint state this script received with the same
                 seq (angles exactly, joint colours from the same flags), its
                 palm equals the daemon's published palm for that seq, the
                 segments keep the model's lengths (L1 = 0.145 m, L2 = 0.152 m),
                 the canvas shows the palm and every joint ring in its colour,
                 and the browser gets display-rate frames, not the 1 kHz stream
  3 no-data      the daemon killed (SIGKILL): "no data" (the time it took is logged)
  4 live again   a new daemon run: live, with the new run id
  5 stopped      the daemon stopped (SIGTERM): "stopped" (the time it took is logged)
  6 disconnected the view server gone: the page says so
Needs Debian's chromium, chromium-driver and python3-selenium (scripts/setup).
"""
import argparse
import math
import os
import random
import re
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.error
import urllib.request

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "support"))
from sim_config import write_sim_config  # noqa: E402
from udp_drops import udp_drops  # noqa: E402

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--window-size=1440,900", "--force-device-scale-factor=1"]
L1, L2 = 0.145, 0.152  # config/models/macaque_exo.yaml d4 and d6; config/calibration/sim.yaml adds 0
HOME_DEG = [45.0, -90.0, 90.0, 0.0, 0.0, 0.0]
JOINT_UNHOMED, JOINT_HELD = 1, 64
WAIT_S = 20  # generous bound on every wait: a loaded 2-core CI machine


class Failure(Exception):
    pass


def check(cond, what):
    if not cond:
        raise Failure(what)


def joint_class(homed, flags):
    """view_scene.cpp joint_class(): the colour class of one joint."""
    if flags & ~(JOINT_UNHOMED | JOINT_HELD):
        return "fault"
    if not homed or flags & JOINT_UNHOMED:
        return "unhomed"
    if flags & JOINT_HELD:
        return "held"
    return "ok"


def hex_rgb(h):
    return [int(h[i:i + 2], 16) for i in (1, 3, 5)]


def dist(a, b):
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)))


class Recorder(threading.Thread):
    """Receives the rig's joint states and palm poses; keeps the raw payloads by (run, seq)."""

    def __init__(self, exodaq_lcm, url, prefix):
        super().__init__(daemon=True)
        self.joint_channel = prefix + "EXO_JOINT_STATE"
        self.palm_channel = prefix + "EXO_PALM_POSE"
        self.rx = exodaq_lcm.Receiver(url, channels=[self.joint_channel, self.palm_channel])
        self.joints, self.palms = {}, {}
        self.newest = {}  # (channel, run_id) -> the newest seq received
        self.lock = threading.Lock()
        self.stop = False

    def run(self):
        while not self.stop:
            got = self.rx.recv(0.2)
            if got is None:
                continue
            channel, data = got
            if len(data) < 40:
                continue
            # fingerprint, utime, mono_ns, then seq and run_id: int64 big-endian.
            seq, run_id = struct.unpack_from(">qq", data, 24)
            with self.lock:
                (self.joints if channel == self.joint_channel else self.palms)[(run_id, seq)] = data
                self.newest[(channel, run_id)] = max(seq, self.newest.get((channel, run_id), -1))

    def get(self, table, run_id, seq, timeout=WAIT_S):
        """The payload of (run_id, seq), or None once this receiver holds a later
        seq of that run on that channel without it: lost on this script's socket
        (UDP on a loaded machine), not the page's doing. Fails when neither comes."""
        channel = self.joint_channel if table is self.joints else self.palm_channel
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self.lock:
                d = table.get((run_id, seq))
                passed = self.newest.get((channel, run_id), -1) > seq
            if d is not None:
                return d
            if passed:
                return None
            time.sleep(0.02)
        raise Failure("seq %d of run %x on %s: neither received nor passed in %d s" % (
            seq, run_id, channel, timeout))


class Test:
    def __init__(self, args):
        self.args = args
        self.out = args.out
        shutil.rmtree(self.out, ignore_errors=True)
        os.makedirs(self.out)
        self.tmp = tempfile.mkdtemp(prefix="exodaq-view-test-")
        self.procs = []
        self.driver = None
        self.shots = 0
        tag = "%d_%06d" % (os.getpid(), random.randrange(10 ** 6))
        self.prefix = "TVIEW_%s_" % tag
        # A port of its own: nothing else on this host hears this test's 1 kHz stream.
        self.lcm_url = "udpm://239.255.76.67:%d?ttl=0" % (20000 + (os.getpid() * 7 + random.randrange(97)) % 20000)
        self.config = write_sim_config(self.args.source_dir, self.tmp, self.prefix, url=self.lcm_url)

    def log(self, msg):
        print("[%6.2f] %s" % (time.monotonic() - self.t0, msg), flush=True)

    # ---- processes ---------------------------------------------------------
    def start(self, name, argv):
        log = open(os.path.join(self.out, name + ".log"), "w")
        p = subprocess.Popen(argv, stdout=subprocess.PIPE if name == "view" else log, stderr=log,
                             text=True)
        self.procs.append(p)
        return p

    def start_daemon(self, n):
        p = self.start("exodaqd-%d" % n, [self.args.exodaqd, "--config", self.config])
        self.log("exodaqd run %d started (pid %d)" % (n, p.pid))
        return p

    def start_view(self):
        p = self.start("view", [self.args.exodaq, "view", "--config", self.config, "--port", "0"])
        line = p.stdout.readline()
        self.log("view: " + line.strip())
        m = re.search(r"serving (http://\S+)", line)
        check(m, "exodaq view did not print its URL: %r" % line)
        return p, m.group(1)

    def stop_all(self):
        for p in self.procs:
            if p.poll() is None:
                p.kill()
                p.wait()

    # ---- the browser -------------------------------------------------------
    def start_browser(self):
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
        for path in (CHROMIUM, CHROMEDRIVER):
            check(os.access(path, os.X_OK), "%s missing: run scripts/setup (chromium, chromium-driver)" % path)
        opts = webdriver.ChromeOptions()
        opts.binary_location = CHROMIUM
        for a in CHROMIUM_FLAGS:
            opts.add_argument(a)
        opts.add_argument("--user-data-dir=" + os.path.join(self.tmp, "chromium-profile"))
        log = os.path.join(self.out, "chromedriver.log")
        try:  # Debian 12's selenium 4.8 names it log_path, later ones log_output
            service = Service(CHROMEDRIVER, log_path=log)
        except TypeError:
            service = Service(CHROMEDRIVER, log_output=log)
        self.driver = webdriver.Chrome(service=service, options=opts)
        self.driver.set_script_timeout(10)

    def state(self):
        return self.driver.execute_script("return window.exodaqView.state()")

    def pixel(self, x, y):
        return self.driver.execute_script("return window.exodaqView.pixel(arguments[0], arguments[1])", x, y)

    def screenshot(self, name):
        self.shots += 1
        path = os.path.join(self.out, "%02d-%s.png" % (self.shots, name))
        check(self.driver.save_screenshot(path), "screenshot %s failed" % path)
        self.log("screenshot " + path)

    def wait_display(self, want, timeout=WAIT_S):
        end = time.monotonic() + timeout
        s = None
        while time.monotonic() < end:
            s = self.state()
            if s["display"] == want:
                return s
            time.sleep(0.1)
        raise Failure("page display %r, not %r, after %g s (banner %r)" % (
            s and s["display"], want, timeout, s and s["banner"]))

    # ---- checks ------------------------------------------------------------
    def check_drawn(self, s, rec, exodaq_lcm):
        """One drawn frame against what LCM carried for the same seq. False if not received here."""
        d = s["drawn"]
        run_id = struct.unpack(">q", bytes.fromhex(d["run_id"]))[0]
        data = rec.get(rec.joints, run_id, d["seq"])
        if data is None:
            return False  # lost on this script's socket (UDP): not the page's fault
        js = exodaq_lcm.decode(data)
        check(list(js.position) == d["q"],
              "seq %d: drawn angles %s != published %s" % (d["seq"], d["q"], list(js.position)))
        want = [joint_class(bool(h), f) for h, f in zip(js.homed, js.flags)]
        check(d["class"] == want, "seq %d: joint colours %s, flags say %s" % (d["seq"], d["class"], want))
        pdata = rec.get(rec.palms, run_id, d["seq"])
        if pdata is not None:
            palm = exodaq_lcm.decode(pdata)
            err = dist(d["palm"], palm.position)
            check(err < 1e-9, "seq %d: drawn palm %s is %.3g m from the published %s" % (
                d["seq"], d["palm"], err, list(palm.position)))
            check(dist(d["elbow"], palm.elbow) < 1e-9, "seq %d: drawn elbow off the published" % d["seq"])
        f = d["frames"]
        check(len(f) == 8, "%d frames drawn, the model has 6 joints + base + palm" % len(f))
        check(abs(dist(f[0], f[4]) - L1) < 1e-9, "upper arm drawn %.6f m long, not L1" % dist(f[0], f[4]))
        check(abs(dist(f[4], f[7]) - L2) < 1e-9, "forearm drawn %.6f m long, not L2" % dist(f[4], f[7]))
        check(f[0] == [0, 0, 0], "O0 drawn at %s" % f[0])
        return True

    def check_home(self, s):
        """The sim powers up at the model's home posture and holds it for 0.5 s; joint 1's
        homing sweep comes first and turns the hanging arm about itself: early in a
        run the drawn palm hangs straight down at (0, 0, -(L1 + L2)) (docs/kinematics.md)."""
        d = s["drawn"]
        if d["seq"] >= 1000:
            return False
        for i in range(1, 6):
            check(abs(math.degrees(d["q"][i]) - HOME_DEG[i]) < 0.1,
                  "seq %d: joint %d drawn at %.3f deg, the sim starts at %g" % (
                      d["seq"], i + 1, math.degrees(d["q"][i]), HOME_DEG[i]))
        err = dist(d["palm"], [0.0, 0.0, -(L1 + L2)])
        check(err < 1e-3, "seq %d: palm drawn at %s, %.2f mm from the home posture's (0, 0, -%.3f)" % (
            d["seq"], d["palm"], err * 1e3, L1 + L2))
        return True

    # One script, so no event redraws the canvas between reading the state and its pixels.
    CANVAS_PROBE = """
        const v = window.exodaqView, s = v.state(), d = s.drawn, out = {state: s, palm: {}, rings: []};
        for (const view of ['front', 'side', 'top']) out.palm[view] = v.pixel(...d.palm_px[view]);
        const rings = d.rings.front, [px, py] = d.palm_px.front;
        for (const r of rings) {
          const sx = r.x + r.r, sy = r.y;
          // Another ring's stroke or the palm marker may cover this sample point.
          const covered = rings.some((o) => o !== r && Math.abs(Math.hypot(o.x - sx, o.y - sy) - o.r) < 4) ||
            Math.hypot(px - sx, py - sy) < 10;
          out.rings.push(Object.assign({pixel: covered ? null : v.pixel(sx, sy)}, r));
        }
        out.colours = v.colours;
        return out;"""

    def check_canvas(self):
        """The palm marker and every visible joint ring have their colours on the canvas."""
        probe = self.driver.execute_script(self.CANVAS_PROBE)
        s, colours = probe["state"], probe["colours"]
        d = s["drawn"]
        want_palm = hex_rgb(colours["palm"] if d["style"] == "live" else colours["stale"])
        for view, pixel in probe["palm"].items():
            check(max(abs(a - b) for a, b in zip(pixel[:3], want_palm)) <= 3,
                  "%s view: pixel %s at the palm %s, not the palm colour %s" % (
                      view, pixel, d["palm_px"][view], want_palm))
        checked = 0
        for r in probe["rings"]:
            if r["pixel"] is None:
                continue
            want = hex_rgb(r["colour"])
            check(r["colour"] == colours[d["class"][r["joint"] - 1]] or d["style"] != "live",
                  "joint %d ring drawn %s, its class is %s" % (r["joint"], r["colour"], d["class"][r["joint"] - 1]))
            check(max(abs(a - b) for a, b in zip(r["pixel"][:3], want)) <= 40,
                  "joint %d ring: pixel %s at (%.1f, %.1f), not its colour %s" % (
                      r["joint"], r["pixel"], r["x"] + r["r"], r["y"], want))
            checked += 1
        return checked

    # ---- the steps ---------------------------------------------------------
    def run(self):
        self.t0 = time.monotonic()
        import exodaq_lcm
        exodaq_lcm.import_types(self.args.lcmtypes)
        self.log("LCM %s, prefix %s, out %s" % (self.lcm_url, self.prefix, self.out))
        view, url = self.start_view()
        rec = Recorder(exodaq_lcm, self.lcm_url, self.prefix)
        rec.start()
        self.start_browser()

        # 1: connected, nothing to draw yet.
        self.driver.get(url)
        s = self.wait_display("waiting")
        check(s["connection"] == "open", "connection %r" % s["connection"])
        check(s["drawn"] is None, "drew a frame without a daemon")
        check("WAITING" in s["banner"] and self.prefix + "EXO_JOINT_STATE" in s["banner"], "banner %r" % s["banner"])
        check(s["model"]["name"] == "macaque_exo" and s["model"]["calibrated"], "model %s" % s["model"])
        self.screenshot("waiting")
        resources = self.driver.execute_script(
            "return performance.getEntriesByType('resource').map(e => e.name)")
        foreign = [r for r in resources + [self.driver.current_url] if not r.startswith(url)]
        check(not foreign, "the page loaded from elsewhere: %s" % foreign)

        # 2: live, following the stream.
        daemon = self.start_daemon(1)
        s = self.wait_display("live")
        self.log("live: seq %s, classes %s" % (s["drawn"]["seq"], s["drawn"]["class"]))
        run1 = s["drawn"]["run_id"]
        homes = self.check_home(s)
        matched = sampled = rings = 0
        classes = set()
        q_min = [math.inf] * 6
        q_max = [-math.inf] * 6
        first = None
        # 8 s of the rig's time (seq), and at least 25 samples of the page,
        # however long a loaded machine takes (WAIT_S per sample at most).
        give_up = time.monotonic() + 10 * WAIT_S
        while first is None or sampled < 25 or s["drawn"]["seq"] - first[0] < 8000:
            check(time.monotonic() < give_up, "the drawn seq went from %s to %s in %d s" % (
                first and first[0], s["drawn"]["seq"], 10 * WAIT_S))
            s = self.state()
            check(s["display"] == "live", "display %r while the daemon runs (banner %r)" % (s["display"], s["banner"]))
            d = s["drawn"]
            sampled += 1
            matched += self.check_drawn(s, rec, exodaq_lcm)
            if sampled in (1, 25):
                rings += self.check_canvas()
                self.screenshot("live-%d" % sampled)
            classes.update(d["class"])
            for i, q in enumerate(d["q"]):
                q_min[i], q_max[i] = min(q_min[i], q), max(q_max[i], q)
            if first is None:
                first = (d["seq"], s["counts"]["frame"], time.monotonic())
            time.sleep(0.15)
        last = (s["drawn"]["seq"], s["counts"]["frame"], time.monotonic())
        self.log("%d drawn frames sampled, %d matched by seq, %d rings checked, classes %s" % (
            sampled, matched, rings, sorted(classes)))
        # Every sampled frame this script's receiver did not lose was checked.
        check(matched > 0, "none of %d sampled frames found in this script's LCM record" % sampled)
        check(rings >= 2, "only %d joint rings could be checked on the canvas" % rings)
        moved = max(b - a for a, b in zip(q_min, q_max))
        check(moved > 0.05, "the drawn arm did not move (largest joint range %.4f rad)" % moved)
        # The sim's config says clock.require_sync: ignore: never shouted (issue 16.9).
        clock = self.driver.execute_script("return document.getElementById('clock').textContent")
        check(clock != "NOT SYNCHRONISED", "clock badge %r under require_sync: ignore" % clock)
        # The backend line: the sim's state and its non-zero counters (source_status_t).
        backend = self.driver.execute_script(
            "return document.getElementById('backend').textContent")
        check(backend.startswith("simulated board, aligned clock, board cycles "),
              "backend line %r" % backend)
        # Decimation: the page gets display-rate frames, each many 1 kHz cycles apart.
        frames = last[1] - first[1]
        check(frames > 0, "no frame reached the page in 8 s of the rig's time")
        seq_per_frame = (last[0] - first[0]) / frames
        check(seq_per_frame >= 10, "%.1f cycles per page frame: the 1 kHz stream reaches the browser" % seq_per_frame)
        self.log("%.1f cycles per page frame (display rate %s Hz)" % (seq_per_frame, s["view"]["display_hz"]))
        check(s["status"] and s["status"]["rig"] == "sim-macaque", "status %s" % s["status"])
        check(s["trail_points"] > 10, "palm trail of %d points" % s["trail_points"])

        # 3: the daemon dies: no data.
        daemon.send_signal(signal.SIGKILL)
        daemon.wait()
        t = time.monotonic()
        s = self.wait_display("no-data")
        self.log("no-data after %.2f s: %s" % (time.monotonic() - t, s["banner"]))
        check("NO DATA" in s["banner"], "banner %r" % s["banner"])
        check(s["drawn"]["style"] == "stale", "the arm still drawn as live")
        self.check_canvas()
        self.screenshot("no-data")

        # 4: a new run.
        daemon = self.start_daemon(2)
        s = self.wait_display("live")
        check(s["drawn"]["run_id"] != run1, "run id did not change: %s" % run1)
        homes += self.check_home(s)
        self.check_drawn(s, rec, exodaq_lcm)
        self.log("home posture checked in %d of 2 runs" % homes)
        self.screenshot("live-again")

        # 5: the daemon stops: stopped. The view learns it from one datagram,
        # the final status: if the view's own socket dropped datagrams while the
        # daemon stopped (the kernel counts them; the view asks for no larger
        # buffer than the default), that one may be among them, and the page
        # can only say "no data"; otherwise it must say "stopped".
        time.sleep(1.0)
        dropped_before = udp_drops(view.pid)
        daemon.send_signal(signal.SIGTERM)
        check(daemon.wait(timeout=WAIT_S) == 0, "exodaqd exited %s on SIGTERM" % daemon.returncode)
        t = time.monotonic()
        try:
            s = self.wait_display("stopped")
            stopped = True
        except Failure:
            dropped = udp_drops(view.pid) - dropped_before
            if dropped == 0:
                raise
            self.log("not judged: the view's socket dropped %d datagrams while the daemon "
                     "stopped, its final status may be one of them" % dropped)
            stopped = False
        if stopped:
            self.log("stopped after %.2f s: %s (view socket drops %d in the run)" % (
                time.monotonic() - t, s["banner"], udp_drops(view.pid)))
            check("STOPPED" in s["banner"], "banner %r" % s["banner"])
            check(s["status"]["state"] == "STOPPING", "last status %s" % s["status"]["state"])
            self.check_canvas()
            self.screenshot("stopped")

        # The server's answers besides the page.
        state_json = urllib.request.urlopen(url + "state.json", timeout=5).read().decode()
        check(not stopped or '"state":"stopped"' in state_json, "state.json: %s" % state_json[:200])
        try:
            urllib.request.urlopen(url + "no-such-page", timeout=5)
            raise Failure("no 404 for an unknown path")
        except urllib.error.HTTPError as e:
            check(e.code == 404, "HTTP %d for an unknown path" % e.code)

        # 6: the view server goes away.
        view.send_signal(signal.SIGTERM)
        check(view.wait(timeout=WAIT_S) == 0, "exodaq view exited %s on SIGTERM" % view.returncode)
        s = self.wait_display("disconnected")
        check("DISCONNECTED" in s["banner"], "banner %r" % s["banner"])
        self.screenshot("disconnected")
        rec.stop = True

    def close(self):
        if self.driver is not None:
            try:
                self.driver.quit()
            except Exception:  # noqa: BLE001 - best effort at the end
                pass
        self.stop_all()
        shutil.rmtree(self.tmp, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--exodaq", required=True)
    ap.add_argument("--exodaqd", required=True)
    ap.add_argument("--source-dir", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--lcmtypes", default=None)
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(args.source_dir, "tools", "python"))
    try:
        import selenium  # noqa: F401
    except ImportError:
        print("FAIL: python3-selenium missing for %s: run scripts/setup" % sys.executable, file=sys.stderr)
        return 1
    test = Test(args)
    try:
        test.run()
    except Failure as e:
        print("FAIL: %s" % e, file=sys.stderr)
        try:
            test.screenshot("failure")
        except Exception:  # noqa: BLE001 - the browser may be the failure
            pass
        return 1
    finally:
        test.close()
    print("view browser test passed; screenshots and logs in %s" % args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
