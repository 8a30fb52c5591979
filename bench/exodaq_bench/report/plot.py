"""performance.png: the scaling part's CPU and cycle work against loop rate and subscribers."""
from .. import targets
from .parts import measured_when


def cpu_target_line(res):
    """The CPU target at 1 kHz in % of one core, from the e2e run of the scaling policy
    (the target is relative to the bare publisher), or None."""
    policy = res["scaling"]["policy"]
    for e in (res.get("e2e") or {}).values():
        ref = (e.get("reference_resources") or {}).get("cpu_percent")
        if e["policy"] == policy and ref:
            return targets.BY_ID["cpu"].target.limit * ref
    return None


def panel(ax, points, key_x, xlabel, with_p50):
    xs = [p[key_x] for p in points]
    ax.plot(xs, [p["cpu_percent"] or 0 for p in points], "o-", label="CPU % of one core")
    ax.plot(xs, [p["work_p99_us"] or 0 for p in points], "s--", label="cycle work p99 (µs)")
    if with_p50:
        ax.plot(xs, [p["work_p50_us"] or 0 for p in points], "^:", label="cycle work p50 (µs)")
    ax.set_xscale("log", base=2)
    ax.set_xticks(xs, [str(x) for x in xs])
    ax.set_xlabel(xlabel)
    ax.grid(alpha=0.3)


def plot(res, png):
    """Writes png; False when this python has no matplotlib."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    sc = res["scaling"]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    panel(a1, sc["rate"], "rate_hz", "loop rate (Hz), 1 subscriber", True)
    a1.set_ylabel("CPU % of one core  /  µs")
    line = cpu_target_line(res)
    if line is not None:
        a1.axhline(line, color="grey", lw=0.8, ls="-.",
                   label=f"CPU target at 1 kHz ({targets.text('cpu')}: {line:.1f} %)")
    a1.legend(fontsize=8)
    panel(a2, sc["subscribers"], "subscribers", "subscriber processes, 1 kHz", False)
    a2.legend(fontsize=8)
    commit, date = measured_when(res, "scaling")
    fig.suptitle(f"exodaqd scaling ({sc['policy']}), {commit}, {date}, {res['machine']['nproc']}-CPU shared machine",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)
    return True
