"""The parts of the suite, in the order they run and appear in performance.json.
Each module's measure(ctx) runs its benchmark and returns a JSON-ready dict."""
from . import cycle, e2e, kinematics, lateness, replay, scaling

PARTS = {
    "cycle": cycle.measure,
    "kinematics": kinematics.measure,
    "lateness": lateness.measure,
    "e2e": e2e.measure,
    "scaling": scaling.measure,
    "replay": replay.measure,
}
