"""The sensitivity table as gains: each design minus the bare chassis at every level of every unknown factor.

Disturbance trials or launches on the twin (``rollability sensitivity --launches``: each launch unknown at both
ends of its range).

Rows come from :func:`rollability_ros.core.sim.sensitivity.sensitivity_rows` (or its ``sensitivity.csv``);
every (factor, level) evaluates the bare chassis and each design on the same trials (common random numbers), so
a design's gain is its success rate minus the bare chassis's there, with Newcombe's 95% interval. ``rollability
sensitivity`` prints them; the report shows them when ``sensitivity.csv`` lies next to the designs.
"""
import typing

from rollability_ros.core.stats import newcombe_interval


#: Columns of :func:`gain_rows` (``sensitivity_gains.csv``).
GAIN_COLUMNS = ("factor", "level", "configuration", "successes", "trials", "baseline_successes", "baseline_trials",
                "gain", "gain_low", "gain_high")


def gain_rows(rows: typing.Sequence[dict], baseline: str = "baseline") -> typing.List[dict]:
    """Each profile's fitness minus the bare chassis's at the same factor level (the same trials, common random
    numbers), with Newcombe's 95% interval: one row per (factor, level, profile) with :data:`GAIN_COLUMNS`. Rows
    as :func:`sensitivity_rows` returns them, or read back from its CSV (numbers as text are converted)."""
    bare = {(r["factor"], str(r["level"])): r for r in rows if r["configuration"] == baseline}
    gains = []
    for row in rows:
        reference = bare.get((row["factor"], str(row["level"])))
        if row["configuration"] == baseline or reference is None:
            continue
        counts = [int(float(v)) for v in (row["successes"], row["trials"], reference["successes"],
                                          reference["trials"])]
        difference, low, high = newcombe_interval(*counts)
        gains.append({"factor": row["factor"], "level": row["level"], "configuration": row["configuration"],
                      "successes": counts[0], "trials": counts[1], "baseline_successes": counts[2],
                      "baseline_trials": counts[3], "gain": difference, "gain_low": low, "gain_high": high})
    return gains


def gain_lines(rows: typing.Sequence[dict], baseline: str = "baseline") -> typing.List[str]:
    """The sensitivity table as text lines: per factor level, each profile minus the bare chassis (Newcombe 95%),
    the robust row marked; empty without a bare chassis."""
    gains = gain_rows(rows, baseline)
    if not gains:
        return []
    # the launch study's robust row says "all unknowns drawn" (core/sim/sensitivity.launch_sensitivity_rows)
    launches = any(str(r["level"]) == "all unknowns drawn" for r in rows)
    measure = "launches on the twin" if launches else "disturbance trials"
    lines = [f"sensitivity (simulated {measure}): each design minus the bare chassis per unknown factor "
             "(same trials; Newcombe 95%)"]
    for gain in gains:
        mark = "**" if gain["factor"] == "robust" else "  "
        lines.append(f"{mark}{gain['factor']:<24} {str(gain['level']):<18} {gain['configuration']:<6} "
                     f"{gain['successes']:>3}/{gain['trials']:<3} vs {gain['baseline_successes']:>3}/"
                     f"{gain['baseline_trials']:<3} {gain['gain']:+.2f} [{gain['gain_low']:+.2f}, "
                     f"{gain['gain_high']:+.2f}]")
    return lines

