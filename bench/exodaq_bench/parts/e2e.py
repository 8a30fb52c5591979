"""Part `e2e`: exodaqd -> bench_lcm_sub (palm_pose_t) and, in the same run, a bare
publisher bench_lcm_pub -> bench_lcm_sub (same type and size); exodaqd's and the
publisher's CPU, RSS and context switches meanwhile (from /proc). One run per policy."""
import os
import re
import subprocess
import time

from ..common import FIFO_PRIORITY, cmdline, log, median, policy_name, priority, read_ints, rel, summary_us
from ..daemon import URL, Sub, daemon_argv, overruns, unique_prefix, write_config
from ..procfs import ResourceProbe

PERIOD_NS = 1_000_000
MESSAGE_BYTES = 142  # palm_pose_t


def lat_block(values_ns, expected):
    s = summary_us(values_ns)
    s["received"] = len(values_ns)
    s["expected"] = expected
    s["loss"] = round(1.0 - len(values_ns) / expected, 6) if expected else None
    return s


def probe_both(pd, pp, duration):
    """Resources of the daemon and the publisher after a warm-up, until just before the end."""
    probe_d, probe_r = ResourceProbe(pd.pid), ResourceProbe(pp.pid)
    warm = min(5.0, duration / 4)
    time.sleep(warm)
    probe_d.start()
    probe_r.start()
    end = time.monotonic() + duration - warm - 0.5
    while time.monotonic() < end and pd.poll() is None:
        probe_d.poll()
        probe_r.poll()
        time.sleep(min(1.0, max(0.01, end - time.monotonic())))
    return probe_d.stop(), probe_r.stop()


def run_processes(ctx, policy, d):
    """Starts the subscribers, then exodaqd (with the deadline probe) and the bare
    publisher together; returns what the figures are computed from."""
    prefix = unique_prefix("E")
    config = write_config(ctx.src, os.path.join(d, "exodaqd.yaml"), prefix, 1000, priority(policy), False)
    sub_d = Sub(ctx.bin["bench_lcm_sub"], prefix + "EXO_PALM_POSE", os.path.join(d, "daemon_sub.txt"),
                ctx.duration + 6, prefix + "EXO_STATUS", os.path.join(d, "daemon_status.txt"))
    sub_r = Sub(ctx.bin["bench_lcm_sub"], prefix + "REF", os.path.join(d, "ref_sub.txt"), ctx.duration + 6)
    env = dict(os.environ, LD_PRELOAD=ctx.bin["bench_deadline_probe"],
               EXODAQ_BENCH_DEADLINE_FILE=os.path.join(d, "first_deadline.txt"),
               EXODAQ_BENCH_SPANS_FILE=os.path.join(d, "loop_spans.txt"))
    dm = daemon_argv(ctx.bin["exodaqd"], config, ctx.duration + 1, os.path.join(d, "lateness.txt"))
    pub = [ctx.bin["bench_lcm_pub"], "--url", URL, "--channel", prefix + "REF", "--rate", "1000",
           "--duration", f"{ctx.duration:.1f}"]
    if policy == "fifo":
        pub = ["chrt", "-f", str(FIFO_PRIORITY)] + pub
    log(f"e2e {policy}: {cmdline(dm)}  ||  {cmdline(pub)}")
    with open(os.path.join(d, "exodaqd.err"), "w") as e, open(os.path.join(d, "pub.err"), "w") as pe:
        pd = subprocess.Popen(dm, stdout=e, stderr=subprocess.STDOUT, env=env)
        pp = subprocess.Popen(pub, stdout=pe, stderr=subprocess.STDOUT)
        res_d, res_r = probe_both(pd, pp, ctx.duration)
        pp.wait(ctx.duration + 30)
        pd.wait(ctx.duration + 30)
    sub_d.wait()
    sub_r.wait()
    commands = [cmdline(["LD_PRELOAD=" + rel(ctx.bin["bench_deadline_probe"]), rel(dm[0])] + dm[1:2]
                        + ["<sim.yaml, priority %d>" % priority(policy)] + dm[3:-1] + ["FILE"]),
                cmdline([rel(x) if "bench_lcm_pub" in x else x for x in pub]),
                cmdline([rel(x) if "bench_lcm_sub" in x else x for x in sub_d.argv])]
    return sub_d, sub_r, res_d, res_r, commands


def first_deadline(d):
    path = os.path.join(d, "first_deadline.txt")
    return read_ints(path)[0] if os.path.exists(path) else None


def histogram_quantile(bins, q):
    """The bin (ns) below which a fraction q of the counts lie; bins: [(bin_ns, count)] sorted."""
    total = sum(c for _, c in bins)
    need, seen = q * total, 0
    for b, c in bins:
        seen += c
        if seen >= need:
            return b
    return bins[-1][0] if bins else None


def loop_spans(d):
    """Where each cycle of the loop thread went (the probe's histograms, 100 ns bins):
    the cycle (wake-up to the next sleep), sendmsg (publishing from the loop), sem_post
    (waking the publisher thread), the rest (the cycle's own work)."""
    path = os.path.join(d, "loop_spans.txt")
    if not os.path.exists(path):
        return None
    hist = {}
    with open(path) as f:
        for line in f:
            name, b, c = line.split()
            hist.setdefault(name, []).append((int(b), int(c)))
    out = {}
    for name, bins in hist.items():
        bins.sort()
        n = sum(c for _, c in bins)
        out[name] = {"n": n, "mean_us": round(sum((b + 50) * c for b, c in bins) / n / 1000, 2),
                     **{f"p{k}_us": round(histogram_quantile(bins, q) / 1000, 1)
                        for k, q in (("50", 0.5), ("90", 0.9), ("99", 0.99))}}
    return out


def daemon_messages_per_cycle(d):
    """Messages exodaqd published per cycle, from its final log line."""
    with open(os.path.join(d, "exodaqd.err")) as f:
        m = re.findall(r"stopped after (\d+) cycles .*?(\d+) messages published", f.read())
    cycles, messages = (int(x) for x in m[-1]) if m else (0, 0)
    return round(messages / cycles, 3) if cycles else None


def cpu_us_per_message(resources, messages_per_s):
    """CPU time per message published, µs (whole process over the probe window)."""
    if not resources or not messages_per_s:
        return None
    return round(resources["cpu_percent"] / 100 * 1e6 / messages_per_s, 2)


def published(d, duration):
    with open(os.path.join(d, "pub.err")) as f:
        sent = re.findall(r"(\d+) sent", f.read())
    return int(sent[-1]) if sent else int(duration * 1000)


def run_one(ctx, policy):
    d = os.path.join(ctx.tmp, f"e2e_{policy}")
    os.makedirs(d, exist_ok=True)
    sub_d, sub_r, res_d, res_r, commands = run_processes(ctx, policy, d)
    d0 = first_deadline(d)
    rows, ref = sub_d.samples(), sub_r.samples()
    late = os.path.join(d, "lateness.txt")
    cycles_run = len(read_ints(late)) if os.path.exists(late) else None
    sent = published(d, ctx.duration)
    offsets = sorted((d0 + r[0] * PERIOD_NS) - r[2] for r in rows) if d0 else []
    r = {
        "policy": policy_name(policy),
        "priority": priority(policy),
        "duration_s": ctx.duration,
        "daemon_from_deadline": lat_block([r[1] - (d0 + r[0] * PERIOD_NS) for r in rows] if d0 else [], cycles_run),
        "daemon_from_mono_ns": lat_block([r[1] - r[2] for r in rows], cycles_run),
        "sim_sample_to_deadline_offset_us": round(median(offsets) / 1000, 1) if offsets else None,
        "daemon_overruns": overruns(os.path.join(d, "exodaqd.err")),
        "reference_from_send": lat_block([x[1] - x[2] for x in ref], sent),
        "reference_from_deadline": lat_block([x[1] - x[3] for x in ref], sent),
        "message_bytes": MESSAGE_BYTES,
        "loop_spans": loop_spans(d),
        "resources": res_d,
        "reference_resources": res_r,
        "commands": commands,
    }
    r.update(derived(r, sub_d.status()[2:]))  # the first status windows include start-up
    per_cycle = daemon_messages_per_cycle(d)
    r["daemon_messages_per_cycle"] = per_cycle
    r["cpu_us_per_message"] = cpu_us_per_message(res_d, per_cycle and per_cycle * 1e9 / PERIOD_NS)
    r["reference_cpu_us_per_message"] = cpu_us_per_message(res_r, 1e9 / PERIOD_NS)
    return r


def derived(r, status):
    dl, rs, rd = r["daemon_from_deadline"], r["reference_from_send"], r["reference_from_deadline"]
    return {
        "added_p50_us": round(dl["p50_us"] - rs["p50_us"], 2) if dl["n"] and rs["n"] else None,
        # Judged (issue 17): both from their own loop deadline, each then including its wake-up.
        "added_p50_vs_reference_deadline_us": round(dl["p50_us"] - rd["p50_us"], 2) if dl["n"] and rd["n"] else None,
        "in_loop_work_p50_us": round(median([s[1] for s in status]), 2) if status else None,
        "in_loop_work_p99_us": round(median([s[2] for s in status]), 2) if status else None,
    }


def measure(ctx):
    return {p: run_one(ctx, p) for p in ctx.policies}
