"""The plausible-world check: the bare robot and every design launched in each of N fixed draws of all unknowns.

A *world* is one draw of everything the robust objective draws per launch (:func:`~rollability_ros.core.sim.
robustness.draw`: foam stiffness, restitution, friction and rolling friction, wheel drag, profile mass, the launcher
base plate's rolling friction, the speed setting's bias, the launcher model, the contact reading, the centre of
mass), held fixed for every launch in it: the lab's rig is one such world, and which one is not known.
World ``w`` of a check with seed ``S`` is drawn from its world seed and launched from its launch seed
(:func:`world_seeds`, independent streams of ``S``); its ``K`` launches run on that launch seed for the bare robot
and every design alike: paired, the same launch conditions (condition ``i mod C``) and the same launch scatter.
An evaluation at fidelity ``world:<world seed>`` (:func:`~rollability_ros.core.sim.objectives.at_fidelity`) is
robust launches whose every launch uses that world's draw, so the same check runs in this process, on a worker
pool and over the graph's sim_evaluator nodes (the selection's check).

Per design (:class:`WorldSummary`), all simulated:

- *wins*: worlds in which the design's point gain (its upright launches minus the bare robot's, out of ``K``
  each) is above 0; a tie is not a win;
- *clear wins*: worlds in which the whole Newcombe 95% interval of that gain lies above 0;
- the *worst world*: the lowest point gain (ties: the lower interval bound, then the earlier world), with its
  interval and the values of its draws;
- the *pooled* gain: all ``N K`` launches against the bare robot's ``N K``, with Newcombe's 95% interval (it
  treats the launches as independent; launches in one world share its draw, so when worlds differ widely the
  interval is somewhat narrower than a world-clustered one).

``rollability sensitivity --worlds N`` runs it and writes ``world_check.csv`` (:data:`WORLD_CHECK_COLUMNS`) and
``world_summary.yaml``; the selection runs a small one and recommends a design only where it wins in at least
``selection.recommend_world_share`` of the worlds (:mod:`~rollability_ros.core.optimization.recommendation`).
"""
import dataclasses
import typing

import numpy as np

from rollability_ros.core.stats import newcombe_interval

if typing.TYPE_CHECKING:
    from rollability_ros.core.profile import Mesh
    from rollability_ros.core.sim.evaluation import EvaluatorSettings, TrialExecutor

#: Spawn key of the check's world and launch seeds within its seed.
_WORLD_STREAM = 0x3041D
#: The id of the bare robot in the rows.
BASELINE = "baseline"
#: The drawn unknowns a launch reads, as the rows name them (fields of robustness.Draw).
WORLD_UNKNOWNS = ("foam_stiffness_factor", "foam_restitution", "foam_lateral_friction", "foam_rolling_friction_m",
                  "wheel_drag_nm", "profile_mass_scale", "ledge_rolling_friction_m", "speed_bias_fraction",
                  "launcher_model", "contact_model", "com_offset_z_m", "robot_restitution", "wheel_rolling_resistance")
#: Columns of ``world_check.csv``: one row per (world, configuration).
WORLD_CHECK_COLUMNS = ("world", "world_seed", "launch_seed", "configuration", "successes", "trials", *WORLD_UNKNOWNS)
#: Short names of the unknowns in the printed worst world.
_SHORT = {"foam_stiffness_factor": "foam stiffness x", "foam_restitution": "foam restitution",
          "foam_lateral_friction": "foam friction", "foam_rolling_friction_m": "foam rolling friction m",
          "wheel_drag_nm": "wheel drag N m", "profile_mass_scale": "profile mass x",
          "ledge_rolling_friction_m": "ledge rolling friction m", "speed_bias_fraction": "speed bias",
          "launcher_model": "launcher", "contact_model": "contact", "com_offset_z_m": "COM offset m",
          "robot_restitution": "robot restitution", "wheel_rolling_resistance": "wheel rolling resistance"}

#: ``evaluate(world_seed, launch_seed, launches) -> {configuration: (successes, trials)}``: the bare robot and every
#: design launched ``launches`` times in the one world of ``world_seed``, all on ``launch_seed``.
WorldEvaluator = typing.Callable[[int, int, int], typing.Mapping[str, typing.Tuple[int, int]]]
#: One row of the check (:data:`WORLD_CHECK_COLUMNS`).
WorldRow = typing.Dict[str, "Value"]
#: A cell of a row: a count, a seed, a drawn number or a drawn name (text once read back from the CSV).
Value = typing.Union[str, int, float]
#: ``describe(world seed) -> {unknown: value}``: the world's drawn values.
Describe = typing.Callable[[int], typing.Mapping[str, Value]]


def world_seeds(seed: int, worlds: int) -> typing.List[typing.Tuple[int, int]]:
    """``[(world seed, launch seed)]`` of worlds ``0 .. worlds - 1`` of a check with ``seed``: independent
    streams, so adding worlds keeps the earlier ones."""
    if worlds < 1:
        raise ValueError(f"a world check needs at least 1 world, got {worlds}")
    return [world_seed_pair(seed, w) for w in range(worlds)]


def world_seed_pair(seed: int, world: int) -> typing.Tuple[int, int]:
    """``(world seed, launch seed)`` of world ``world`` (>= 0) of a check with ``seed`` (:func:`world_seeds`)."""
    world_state, launch_state = np.random.SeedSequence(int(seed), spawn_key=(_WORLD_STREAM, world)).generate_state(2)
    return int(world_state), int(launch_state)


def run_world_check(evaluate: WorldEvaluator, worlds: int, launches: int, seed: int,
                    describe: typing.Optional[Describe] = None,
                    on_row: typing.Optional[typing.Callable[[WorldRow], None]] = None) -> typing.List[WorldRow]:
    """The rows (:data:`WORLD_CHECK_COLUMNS`) of a check of ``worlds`` worlds x ``launches`` paired launches from ``seed``.

    ``evaluate`` launches the bare robot and every design in one world (:data:`WorldEvaluator`); ``describe(world
    seed)`` gives the world's drawn values (:func:`world_draws`; empty columns without it); ``on_row`` sees each
    row as it comes."""
    if launches < 1:
        raise ValueError(f"a world check needs at least 1 launch per world, got {launches}")
    if worlds < 1:
        raise ValueError(f"a world check needs at least 1 world, got {worlds}")
    rows = []
    for world in range(worlds):   # each world's seeds as it comes: 10^8 worlds listed first took 26 min and 12 GB
        world_seed, launch_seed = world_seed_pair(seed, world)
        drawn = dict(describe(world_seed)) if describe is not None else {}
        for configuration, (successes, trials) in evaluate(world_seed, launch_seed, launches).items():
            row = {"world": world, "world_seed": world_seed, "launch_seed": launch_seed,
                   "configuration": configuration, "successes": int(successes), "trials": int(trials),
                   **{name: drawn.get(name, "") for name in WORLD_UNKNOWNS}}
            if on_row is not None:
                on_row(row)
            rows.append(row)
    return rows


def world_draws(settings: "EvaluatorSettings") -> Describe:
    """``describe(world seed) -> {unknown: value}``: the drawn values of a world for the launches ``settings``
    (EvaluatorSettings) run at launch fidelity, as :func:`robust_settings_for` draws them for its twin."""
    from rollability_ros.core.sim.evaluation import mesh_job, settings_at_fidelity
    from rollability_ros.core.sim.engines import represents_restitution
    from rollability_ros.core.sim.robustness import draw

    at_launch = settings_at_fidelity(settings, "launch")
    job = mesh_job(None, at_launch)
    if job.launch is None:   # settings_at_fidelity("launch") always has launches
        raise ValueError("the world check needs launch trials")
    twin, robust = job.launch.twin, at_launch.objective.robust

    def describe(world_seed: int) -> typing.Dict[str, Value]:
        drawn = dataclasses.asdict(draw(world_seed, robust, twin.robot.com_offset_z_m, twin.robot.body_height_m))
        if not represents_restitution(twin.physics.engine):   # drawn, not applied (robustness's docstring)
            drawn["robot_restitution"] = f"none ({twin.physics.engine})"
        return {name: drawn[name] for name in WORLD_UNKNOWNS}
    return describe


def local_world_evaluator(profiles: typing.Mapping[str, typing.Optional["Mesh"]], settings: "EvaluatorSettings",
                          executor: typing.Optional["TrialExecutor"] = None) -> WorldEvaluator:
    """A :data:`WorldEvaluator` in this process (or on ``executor``): ``profiles`` ``{label: mesh, None for the
    bare robot}`` launched at fidelity ``world:<seed>`` of ``settings`` (its launch engine)."""
    from rollability_ros.core.sim.evaluation import evaluate_mesh, settings_at_fidelity
    from rollability_ros.core.sim.objectives import world_fidelity

    def evaluate(world_seed: int, launch_seed: int, launches: int) -> typing.Dict[str, typing.Tuple[int, int]]:
        in_world = settings_at_fidelity(settings, world_fidelity(world_seed))
        results = {label: evaluate_mesh(mesh, launches, launch_seed, in_world, executor)
                   for label, mesh in profiles.items()}
        return {label: (result.successes, result.trials) for label, result in results.items()}
    return evaluate


@dataclasses.dataclass(frozen=True)
class WorldGain:
    """A design's gain over the bare robot in one world: counts on the same launches and the world's draws."""

    world: int
    world_seed: int
    successes: int
    trials: int
    baseline_successes: int
    baseline_trials: int
    draws: typing.Mapping[str, Value] = dataclasses.field(default_factory=dict)

    @property
    def interval(self) -> typing.Tuple[float, float, float]:
        """``(gain, low, high)``: the success rates' difference and Newcombe's 95% interval."""
        return newcombe_interval(self.successes, self.trials, self.baseline_successes, self.baseline_trials)

    def draws_text(self) -> str:
        """The world's drawn values, named (empty when not recorded)."""
        named = [f"{_SHORT[name]} {_value_text(self.draws[name])}" for name in WORLD_UNKNOWNS
                 if str(self.draws.get(name, "")) != ""]
        return ", ".join(named)


def _value_text(value: typing.Any) -> str:
    try:
        return f"{float(value):.3g}"
    except (TypeError, ValueError):
        return str(value)


@dataclasses.dataclass(frozen=True)
class WorldSummary:
    """A design against the bare robot over every world of a check (module docstring: wins, worst, pooled)."""

    configuration: str
    gains: typing.Tuple[WorldGain, ...]

    @property
    def worlds(self) -> int:
        """Worlds in the check."""
        return len(self.gains)

    @property
    def wins(self) -> int:
        """Worlds in which the design's point gain is above 0 (a tie is not a win)."""
        return sum(g.interval[0] > 0 for g in self.gains)

    @property
    def clear_wins(self) -> int:
        """Worlds in which the gain's whole 95% interval lies above 0."""
        return sum(g.interval[1] > 0 for g in self.gains)

    @property
    def share_won(self) -> float:
        """Share of the worlds won, [0, 1]."""
        return self.wins / self.worlds

    @property
    def share_clear(self) -> float:
        """Share of the worlds with the gain's interval above 0, [0, 1]."""
        return self.clear_wins / self.worlds

    @property
    def worst(self) -> WorldGain:
        """The world with the lowest point gain (then the lowest lower bound, then the earliest world)."""
        return min(self.gains, key=lambda g: (g.interval[0], g.interval[1], g.world))

    @property
    def pooled(self) -> typing.Tuple[float, float, float]:
        """``(gain, low, high)`` over all the check's launches pooled, Newcombe 95%."""
        return newcombe_interval(sum(g.successes for g in self.gains), sum(g.trials for g in self.gains),
                                 sum(g.baseline_successes for g in self.gains),
                                 sum(g.baseline_trials for g in self.gains))

    def text(self) -> str:
        """One line: wins, clear wins, the worst world with its draws and the pooled gain."""
        worst, (gain, low, high) = self.worst, self.pooled
        w_gain, w_low, w_high = worst.interval
        launches = sum(g.trials for g in self.gains)
        draws = worst.draws_text()
        return (f"{self.configuration:<8} wins {self.wins}/{self.worlds} worlds ({self.share_won:.0%}), interval "
                f"above 0 in {self.clear_wins}/{self.worlds} ({self.share_clear:.0%}); worst world {worst.world}: "
                f"{w_gain:+.2f} [{w_low:+.2f}, {w_high:+.2f}] ({worst.successes}/{worst.trials} vs "
                f"{worst.baseline_successes}/{worst.baseline_trials}" + (f"; {draws}" if draws else "") +
                f"); pooled {gain:+.2f} [{low:+.2f}, {high:+.2f}] over {launches} launches")

    def as_dict(self) -> typing.Dict[str, object]:
        """Plain numbers for ``world_summary.yaml`` and the selection's records."""
        worst, (gain, low, high) = self.worst, self.pooled
        w_gain, w_low, w_high = worst.interval
        return {"worlds": self.worlds, "wins": self.wins, "share_won": self.share_won,
                "clear_wins": self.clear_wins, "share_clear": self.share_clear,
                "worst_world": {"world": worst.world, "world_seed": worst.world_seed, "gain": w_gain,
                                "newcombe_95": [w_low, w_high], "successes": worst.successes,
                                "trials": worst.trials, "baseline_successes": worst.baseline_successes,
                                "baseline_trials": worst.baseline_trials,
                                "draws": {k: _plain(v) for k, v in worst.draws.items()}},
                "pooled": {"gain": gain, "newcombe_95": [low, high],
                           "successes": sum(g.successes for g in self.gains),
                           "trials": sum(g.trials for g in self.gains),
                           "baseline_successes": sum(g.baseline_successes for g in self.gains),
                           "baseline_trials": sum(g.baseline_trials for g in self.gains)}}


def _plain(value: typing.Any) -> typing.Any:
    """A float for a number (also one read back as text), else the text."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return str(value)


def summarize_worlds(rows: typing.Iterable[typing.Mapping[str, Value]],
                     baseline: str = BASELINE) -> typing.List[WorldSummary]:
    """One :class:`WorldSummary` per design (first-seen order) from the check's rows (as :func:`run_world_check`
    returns them, or read back from ``world_check.csv``: numbers as text are converted); ``ValueError`` naming a
    world without the bare robot or with unequal launch counts (not paired)."""
    rows = list(rows)
    bare = {int(float(r["world"])): r for r in rows if r["configuration"] == baseline}
    gains: typing.Dict[str, typing.List[WorldGain]] = {}
    for row in rows:
        if row["configuration"] == baseline:
            continue
        world = int(float(row["world"]))
        reference = bare.get(world)
        if reference is None:
            raise ValueError(f"world {world} has no bare-robot row ({baseline!r})")
        successes, trials = int(float(row["successes"])), int(float(row["trials"]))
        bare_successes, bare_trials = int(float(reference["successes"])), int(float(reference["trials"]))
        if trials != bare_trials or trials < 1:
            raise ValueError(f"world {world}: {row['configuration']} has {trials} launches and the bare robot "
                             f"{bare_trials}: the check pairs equal launches")
        gains.setdefault(str(row["configuration"]), []).append(WorldGain(
            world, int(float(row["world_seed"])), successes, trials, bare_successes, bare_trials,
            {k: row.get(k, "") for k in WORLD_UNKNOWNS}))
    return [WorldSummary(label, tuple(own)) for label, own in gains.items()]


def world_check_lines(summaries: typing.Sequence[WorldSummary], engine: str = "") -> typing.List[str]:
    """The check as text lines (empty without designs): what a win is, then one line per design."""
    if not summaries:
        return []
    on = f" on {engine}" if engine else ""
    return [f"plausible-world check (simulated{on}): {summaries[0].worlds} worlds (one draw of every unknown each) x "
            f"{summaries[0].gains[0].trials} paired launches; a design wins a world when its upright launches exceed the bare "
            f"robot's there (point gain > 0; a tie is not a win); Newcombe 95% intervals"] + \
        ["  " + summary.text() for summary in summaries]
