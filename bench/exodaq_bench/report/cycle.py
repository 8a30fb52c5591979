"""The report's "Cycle work" section."""
from .. import targets
from .fmt import rt_e2e


def table(c, e2e):
    row = lambda label, p50, p99: f"| {label} | {p50:.0f} ns | | {p99:.0f} ns | | | |"
    L = ["| | p50 | p90 | p99 | p99.9 | max | mean |", "|---|---|---|---|---|---|---|",
         f"| every cycle ({c['cycles']}) | {c['p50_ns']:.0f} ns | {c['p90_ns']:.0f} ns | **{c['p99_ns']:.0f} ns** "
         f"| {c['p999_ns']:.0f} ns | {c['max_ns']:.0f} ns | {c['mean_ns']:.0f} ns |",
         row("cycles without status", c["without_status_p50_ns"], c["without_status_p99_ns"]),
         row(f"cycles that also build status_t (1 in {c['status_every_cycles']})",
             c["status_cycle_p50_ns"], c["status_cycle_p99_ns"]),
         row("of which: sim source read (a real rig reads SocketCAN instead)",
             c["sim_source_read_p50_ns"], c["sim_source_read_p99_ns"]),
         row(f"paced at 1 kHz on real deadlines, ring drained inline ({c['paced_cycles']})",
             c["paced_p50_ns"], c["paced_p99_ns"]),
         row(f"paced at 1 kHz, publisher thread running ({c['paced_cycles']})",
             c["paced_publisher_thread_p50_ns"], c["paced_publisher_thread_p99_ns"])]
    if e2e and e2e.get("in_loop_work_p50_us") is not None:
        L.append(row(f"inside exodaqd ({e2e['policy']}, e2e run below; wake-up → end of cycle, status_t, "
                     "median of 100 ms windows)", e2e["in_loop_work_p50_us"] * 1000, e2e["in_loop_work_p99_us"] * 1000))
    return L + [""]


def section(res):
    c = res.get("cycle")
    if not c:
        return []
    L = ["## Cycle work\n",
         "`Acquisition::run_cycle()` driven without threads (`prepare_for_manual_cycles()`), on the",
         "real `sim` source built from `config/sim.yaml` exactly as exodaqd builds it, after a warm-up",
         f"until every joint is homed and the service is `running` ({'yes' if c['homed_and_running'] else 'NO'} "
         "here).\n",
         "One cycle = sim source read (simulate the rig, encode its CAN frames, decode them with the",
         "real `BoardDecoder`) → unwrap → homing/offsets → FK → Jacobian → manipulability → encode",
         f"joint_state, palm_pose, encoder_raw (and status every {c['status_every_cycles']}th cycle) into the "
         "publisher's ring.\n",
         "The ring is drained into a counting sink between timed cycles: handing bytes to LCM is not",
         f"the harness's work. The harness runs under {c.get('harness_policy', 'SCHED_OTHER')}, like the loop "
         "thread. Each cycle is",
         f"timed with `clock_gettime(CLOCK_MONOTONIC)` (a pair costs {c['clock_gettime_pair_ns']:.0f} ns here, "
         "included).\n"]
    L += table(c, rt_e2e(res))
    L += ["The first rows run cycles back to back: caches, TLB and branch predictors stay warm, and",
          "committing a message to the ring is an atomic store, with one uncontended `sem_post` per",
          "cycle. The loop does not run like that: it sleeps a millisecond between cycles (cold caches:",
          "the *paced* row).\n",
          "With the publisher thread running, `sem_post` on the semaphore it sleeps on is a `futex`",
          "wake-up system call (on this VM a wake-up across CPUs costs an IPI, i.e. a VM exit): the",
          f"*publisher thread* row. All three are held to the same target, p99 {targets.text('in_loop_work_p99')}; "
          "the in-daemon p99",
          "is the one the loop actually pays.\n",
          f"Google Benchmark `BM_Cycle` (median of 5 repetitions): {c['gbench_cycle_cpu_ns']:.0f} ns CPU, "
          f"{c['gbench_cycle_real_ns']:.0f} ns wall per cycle",
          f"(`BM_SimSourceRead`: {c['gbench_sim_source_read_cpu_ns']:.0f} ns CPU). The max and the mean are "
          "dominated by the few cycles",
          "during which the thread was preempted by the concurrent builds (wall-clock timing); p50/p99 are",
          "the figures to read. Reference: the 1 ms period — the cycle uses well under 1 % of it.\n"]
    return L + allocations(c)


def allocations(c):
    return [f"**Allocations:** {c['allocations']} heap allocations (operator new + malloc, counted per thread by",
            f"`tests/support/alloc_counter.cpp`) on the loop thread over the {c['cycles']} timed cycles, "
            f"{c['allocations_process']} in",
            "the whole process; `BM_Cycle` counts the same (`allocs_per_cycle`). With the threads running",
            "(loop, publisher, clock monitor), `tests/core/test_acquisition.cpp`",
            "`Acquisition.ThreadedLoopAllocatesNothingAfterStartUp` checks 0 allocations in the whole",
            "process over 10 000 cycles after start-up; that test and this count are the heap-allocation",
            "figure for the resources below (the daemon binary itself is not instrumented).\n",
            "Commands:\n", "```"] + \
           [cmd + " --json FILE" if "--harness" in cmd else cmd for cmd in c["commands"]] + ["```\n"]
