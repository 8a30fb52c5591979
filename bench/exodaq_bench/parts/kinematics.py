"""Part `kinematics`: exodaq vs KDL on the seed-000 chain (bench/kinematics/bench_kinematics),
CPU time, medians of 10 repetitions.

Every benchmark of bench_kinematics is picked up by its name: BM_<Name>_Exodaq and
BM_<Name>_Kdl give <name>_exodaq_ns, <name>_kdl_ns and <name>_ratio (exodaq / KDL);
a BM_<Name>_Exodaq without a KDL counterpart gives <name>_ns (<name> in snake_case:
BM_PalmFk_Exodaq -> palm_fk_exodaq_ns). A new pair needs no change here: only its
target in targets.py."""
import re

from ..common import cmdline, log, ratio, rel
from . import gbench


def snake(name):
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def figures(cpu_ns):
    """{run_name: CPU ns} -> performance.json figures, by the naming rule above."""
    libs = {}
    for run, ns in cpu_ns.items():
        m = re.fullmatch(r"BM_(\w+)_(Exodaq|Kdl)", run)
        if m:
            libs.setdefault(snake(m.group(1)), {})[m.group(2).lower()] = round(ns, 1)
    r = {}
    for name, by_lib in libs.items():
        if "kdl" not in by_lib:
            r[f"{name}_ns"] = by_lib["exodaq"]
            continue
        r[f"{name}_exodaq_ns"] = by_lib.get("exodaq")
        r[f"{name}_kdl_ns"] = by_lib["kdl"]
        r[f"{name}_ratio"] = ratio(by_lib.get("exodaq"), by_lib["kdl"])
    return r


def measure(ctx):
    argv = [ctx.bin["bench_kinematics"], "--benchmark_format=json"]
    argv += gbench.repetition_flags(ctx.quick, 10)
    log("kinematics: " + cmdline(argv))
    g = gbench.run(argv)
    r = figures({name: x["cpu_time"] for name, x in g.items()})
    r["command"] = cmdline([rel(argv[0])] + argv[1:])
    r["also"] = "bench/kinematics/kdl_ratio.sh BUILD_DIR 10"
    return r
