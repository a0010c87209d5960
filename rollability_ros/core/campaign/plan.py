"""The launch campaign (paper 2.2.6): experiment matrix, trial order, operator changes, resume and progress.

The runner loop that talks to the rig lives in a node; this module holds the pure logic it needs. Trials are
ordered configuration, then height, then angle, then speed, then repetition, so the slowest manual changes
(swapping the profile mesh, moving the ledge) happen least often. A trial's ``trial_id`` is derived from its
condition alone, so a resumed campaign recognises the trials whose outcome is already stored however the
plan was ordered or shuffled. Stdlib only (runs on the robot computer).
"""
import dataclasses
import random
import statistics
import typing

# the matrix itself is a shared value type at the core's bottom (the robust objective reads it too); its names stay
# importable from here
from rollability_ros.core.campaign_matrix import LEVELS, CampaignSpec, load_campaign_spec  # noqa: F401
from rollability_ros.core.records import LaunchCondition, trial_id_for

if typing.TYPE_CHECKING:  # annotations only
    from rollability_ros.core.store import Store


@dataclasses.dataclass(frozen=True)
class PlannedTrial:
    """One trial of the plan: its position (0-based), stable id and condition."""

    index: int
    trial_id: str
    condition: LaunchCondition


def _block_key(condition, block_level):
    """The levels up to and including ``block_level``: trials sharing it form one shuffle block."""
    depth = LEVELS.index(block_level) + 1
    return tuple(getattr(condition, level) for level in LEVELS[:depth])


def plan_trials(spec: CampaignSpec) -> typing.List[PlannedTrial]:
    """Every trial of ``spec`` in run order, each with a unique, condition-derived ``trial_id``.

    With ``spec.random_order`` the trials inside each block (same levels up to ``spec.random_block``) are
    shuffled with ``spec.random_seed``; blocks keep their order, so the manual changes between blocks stay few.
    """
    conditions = [LaunchCondition(c, h, s, a, r)
                  for c in spec.configurations for h in spec.heights_m for a in spec.angles_deg
                  for s in spec.speeds_mps for r in range(spec.repetitions)]
    if spec.random_order:
        rng = random.Random(spec.random_seed)
        blocks: typing.Dict[tuple, typing.List[LaunchCondition]] = {}
        for condition in conditions:
            blocks.setdefault(_block_key(condition, spec.random_block), []).append(condition)
        conditions = []
        for block in blocks.values():  # dicts keep insertion order: blocks stay in matrix order
            rng.shuffle(block)
            conditions.extend(block)
    plan = [PlannedTrial(i, trial_id_for(c), c) for i, c in enumerate(conditions)]
    if len({t.trial_id for t in plan}) != len(plan):
        raise ValueError("trial ids are not unique: matrix values that differ only below 6 significant digits")
    return plan


def changed_levels(previous: typing.Optional[LaunchCondition], following: LaunchCondition) -> typing.List[str]:
    """Names of the matrix levels (``LEVELS``) that differ between two conditions; all of them if no previous."""
    if previous is None:
        return list(LEVELS)
    return [level for level in LEVELS if getattr(previous, level) != getattr(following, level)]


def changes_between(previous: typing.Union[LaunchCondition, PlannedTrial, None],
                    following: typing.Union[LaunchCondition, PlannedTrial],
                    pressure_psi_by_speed: typing.Optional[typing.Mapping[float, float]] = None) -> typing.List[str]:
    """What the operator must change on the rig before ``following``, one instruction per changed level.

    Parameters
    ----------
    previous, following : LaunchCondition or PlannedTrial
        Consecutive trials; ``previous`` None for the first trial (everything must be set up).
    pressure_psi_by_speed : dict, optional
        ``{speed m/s: regulator pressure psi}`` from the rig config, to name the pressure to set.
    """
    before = previous.condition if isinstance(previous, PlannedTrial) else previous
    after = following.condition if isinstance(following, PlannedTrial) else following
    pressures = pressure_psi_by_speed or {}
    instructions = []
    for level in changed_levels(before, after):
        instruction = f"{_INSTRUCTIONS[level]} {_level_text(after, level)}"
        if level == "speed_mps" and after.speed_mps in pressures:
            instruction += f" (regulator {pressures[after.speed_mps]:g} psi)"
        if before is not None:
            instruction += f" (was {_level_text(before, level)})"
        instructions.append(instruction)
    return instructions


_INSTRUCTIONS = {"configuration": "mount configuration", "height_m": "set the ledge height to",
                 "angle_deg": "set the launch angle to", "speed_mps": "set the launch speed to"}


def _level_text(condition, level):
    value = getattr(condition, level)
    return {"configuration": lambda: value, "height_m": lambda: f"{value:.2f} m",
            "angle_deg": lambda: f"{value:+g} deg", "speed_mps": lambda: f"{value:g} m/s"}[level]()


def remaining_trials(plan: typing.Sequence[PlannedTrial], store: "Store", run_id: str) -> typing.List[PlannedTrial]:
    """The planned trials of ``run_id`` whose outcome is not in ``store`` (a trial is done once stored)."""
    done = store.trial_ids(run_id)
    return [trial for trial in plan if trial.trial_id not in done]


class CampaignProgress:
    """Trials done / remaining and the estimated time left, from trial durations measured in this session.

    Parameters
    ----------
    total : int
        Trials in the plan.
    done : int
        Trials already stored when the session starts (a resumed campaign).
    window : int
        The ETA uses the median of the last ``window`` durations (robust to an operator's coffee break).
    """

    def __init__(self, total: int, done: int = 0, window: int = 20) -> None:
        if not 0 <= done <= total:
            raise ValueError(f"need 0 <= done <= total, got {done} of {total}")
        if window < 1:
            raise ValueError(f"window must be >= 1, got {window}")
        self.total = total
        self.done = done
        self.window = window
        self._durations_s: typing.List[float] = []

    def trial_done(self, duration_s: float) -> None:
        """Count one more stored trial that took ``duration_s`` (s, from command to stored outcome)."""
        if duration_s < 0:
            raise ValueError(f"duration_s must be >= 0, got {duration_s}")
        if self.done >= self.total:
            raise ValueError(f"all {self.total} trials are already done")
        self.done += 1
        self._durations_s.append(float(duration_s))

    @property
    def remaining(self) -> int:
        """Trials still to run."""
        return self.total - self.done

    @property
    def eta_s(self) -> typing.Optional[float]:
        """Estimated seconds left, or None before the first measured trial."""
        if not self._durations_s:
            return None if self.remaining else 0.0
        return statistics.median(self._durations_s[-self.window:]) * self.remaining

    def text(self) -> str:
        """One status line, e.g. ``"37/400 done, 363 remaining, about 1 h 02 min left"``."""
        eta = self.eta_s
        if eta is None:
            left = "time left unknown"
        else:
            minutes = int(round(eta / 60.0))
            left = f"about {minutes // 60} h {minutes % 60:02d} min left" if minutes >= 60 else \
                f"about {minutes} min left" if minutes else f"about {eta:.0f} s left"
        return f"{self.done}/{self.total} done, {self.remaining} remaining, {left}"
