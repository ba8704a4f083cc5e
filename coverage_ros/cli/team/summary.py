"""What a team run gives a user: ``summary.json``'s derived figures and the table printed at
the end (pure: no ROS).

In lock-step (``--lockstep``) every figure of ``summary.json`` is the same for the same command
and seed, except the wall-clock ones named in :data:`WALL_CLOCK_KEYS`.
"""

from __future__ import annotations

import math

CONVERGED_BAND = 0.02  # H within 2 % of its final value counts as converged
#: summary.json keys measured on the wall clock (they differ run to run, lock-step or not).
WALL_CLOCK_KEYS = ("wall_time", "rtf", "processes")


def converged_at(samples: list[tuple[float, float]], H_final: float,
                 ready_at: float | None) -> float | None:
    """First sim time [s, since ``ready_at``] from which the ``(t, H)`` samples stayed within
    CONVERGED_BAND of ``H_final``; None if there is none."""
    if not samples or not math.isfinite(H_final):
        return None
    t_conv = None
    for t, h in reversed(samples):
        if not abs(h - H_final) <= CONVERGED_BAND * H_final:
            break
        t_conv = t
    return None if t_conv is None else round(t_conv - (ready_at or 0.0), 3)


def deterministic_part(summary: dict) -> dict:
    """``summary`` without its wall-clock figures (what lock-step runs reproduce exactly)."""
    return {k: v for k, v in summary.items() if k not in WALL_CLOCK_KEYS}


def summary_table(summary: dict) -> str:
    """A short human-readable table of a summary."""
    m = summary["metrics"]

    def xy(p) -> str:
        return "-" if p is None else f"({p[0]:.2f}, {p[1]:.2f})"

    def num(v, digits: int = 3) -> str:
        return "-" if v is None else f"{v:.{digits}g}"

    lines = [f"{'robot':>5} {'start (x, y)':>16} {'final (x, y)':>16} {'path [m]':>9} "
             f"{'collisions':>10}"]
    for r in summary["robots"]:
        final = "lost" if r.get("lost_at") is not None else xy(r["final"])
        lines.append(f"{r['id']:>5} {xy(r['start']):>16} {final:>16} {r['path_length']:>9.2f} "
                     f"{r['collisions']:>10d}")
    drop = 100.0 * (1.0 - m["H"] / m["H_start"]) if m["H_start"] else math.nan
    conv_at = "-" if m["converged_at"] is None else f"{m['converged_at']:.1f} s"
    lines.append(f"H {num(m['H'], 4)} (start {num(m['H_start'], 4)}, {drop:.0f} % lower), "
                 f"I {num(m['mass_deviation_I'])}, coverage {100 * m['coverage_ratio']:.0f} %, "
                 f"min separation {num(m['min_separation'])} m, converged at {conv_at}")
    ex = summary.get("exploration")
    if ex is not None:
        at = ", ".join(f"{k}: {'-' if v is None else f'{v:g} s'}"
                       for k, v in ex["explored_at"].items())
        lines.append(f"explored {100 * ex['explored_fraction']:.1f} % (reached {at}); false "
                     f"free {100 * ex['false_free']:.2f} %")
    lines.append(f"real-time factor {summary['rtf']:.2f} over the run; sim time "
                 f"{summary['sim_time']:.1f} s in {summary['wall_time']:.1f} s wall with start-up "
                 "and shutdown")
    return "\n".join(lines)
