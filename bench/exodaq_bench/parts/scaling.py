"""Part `scaling`: exodaqd at several loop rates (1 subscriber) and with several
subscriber processes (1 kHz): CPU, context switches, cycle work, lateness, e2e."""
import os
import subprocess

from ..common import log, median, policy_name, priority, read_ints, summary_us
from ..daemon import Sub, daemon_argv, unique_prefix, write_config
from ..procfs import ResourceProbe, sample_resources

RATES_HZ = (250, 1000, 2000, 4000)
SUBSCRIBERS = (1, 4, 16)  # at 1000 Hz; the 1-subscriber point is the rate series' own


def start_subscribers(ctx, prefix, nsubs, d, duration):
    """nsubs subscribers of EXO_PALM_POSE; the first also records status_t."""
    return [Sub(ctx.bin["bench_lcm_sub"], prefix + "EXO_PALM_POSE", os.path.join(d, f"sub{i}.txt"),
                duration + 5, prefix + "EXO_STATUS" if i == 0 else None,
                os.path.join(d, "status.txt") if i == 0 else None)
            for i in range(nsubs)]


def run_point(ctx, rate, nsubs, policy):
    duration = ctx.scale_duration
    d = os.path.join(ctx.tmp, f"scale_{rate}_{nsubs}")
    os.makedirs(d, exist_ok=True)
    prefix = unique_prefix("S")
    config = write_config(ctx.src, os.path.join(d, "exodaqd.yaml"), prefix, rate, priority(policy), False)
    subs = start_subscribers(ctx, prefix, nsubs, d, duration)
    late, deadline_file = os.path.join(d, "lateness.txt"), os.path.join(d, "first_deadline.txt")
    env = dict(os.environ, LD_PRELOAD=ctx.bin["bench_deadline_probe"], EXODAQ_BENCH_DEADLINE_FILE=deadline_file)
    with open(os.path.join(d, "exodaqd.err"), "w") as e:
        pd = subprocess.Popen(daemon_argv(ctx.bin["exodaqd"], config, duration, late),
                              stdout=e, stderr=subprocess.STDOUT, env=env)
        res = sample_resources(pd, ResourceProbe(pd.pid), min(5.0, duration / 4), 0.5, duration) or {}
        pd.wait(duration + 30)
    for s in subs:
        s.wait()
    expected = len(read_ints(late)) if os.path.exists(late) else int(duration * rate)
    d0 = read_ints(deadline_file)[0] if os.path.exists(deadline_file) else None
    period = int(round(1e9 / rate))
    e2e = summary_us([r[1] - (d0 + r[0] * period) for r in subs[0].samples()]) if d0 else {}
    st = subs[0].status()[2:]  # the first windows include start-up
    of_status = lambda col: round(median([s[col] for s in st]), 2) if st else None
    return {
        "rate_hz": rate,
        "subscribers": nsubs,
        "cpu_percent": res.get("cpu_percent"),
        "ctx_per_s": res.get("ctx_per_s"),
        "rss_mib": res.get("rss_mib"),
        "work_p50_us": of_status(1),
        "work_p99_us": of_status(2),
        "lateness_p99_us": of_status(5),
        "e2e_from_deadline_p50_us": e2e.get("p50_us"),
        "e2e_from_deadline_p99_us": e2e.get("p99_us"),
        "min_received_fraction": round(min(len(s.samples()) for s in subs) / expected, 4) if expected else None,
    }


def measure(ctx):
    policy = ctx.policies[-1]  # SCHED_FIFO when allowed
    rates = []
    for rate in RATES_HZ:
        log(f"scaling: {rate} Hz, 1 subscriber, {ctx.scale_duration:.0f} s")
        rates.append(run_point(ctx, rate, 1, policy))
    subs = [p for p in rates if p["rate_hz"] == 1000]
    for n in SUBSCRIBERS[1:]:
        log(f"scaling: 1000 Hz, {n} subscribers, {ctx.scale_duration:.0f} s")
        subs.append(run_point(ctx, 1000, n, policy))
    return {
        "policy": policy_name(policy),
        "duration_s": ctx.scale_duration,
        "rate": rates,
        "subscribers": subs,
        "command": "bench/run (part scaling): LD_PRELOAD=bench_deadline_probe.so exodaqd --config "
                   f"<sim.yaml with loop.rate_hz R, priority {priority(policy)}> "
                   f"--duration {ctx.scale_duration:.0f} --lateness-log FILE, N x bench_lcm_sub on EXO_PALM_POSE",
    }
