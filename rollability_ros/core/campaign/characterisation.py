"""Bench characterisation before a campaign: cheap measurements that pin the twin's decisive unknowns.

The protocol is docs/characterisation.md. A characterisation file (YAML, read with the bounded
:func:`~rollability_ros.core.safe_yaml.load`: no key written twice, bounded nesting and aliases; checked strictly: an unknown key, a missing one or a value of the wrong kind is refused in one line naming it) holds::

    format: rollability-characterisation-1
    rollout:                      # the bare robot pushed to about speed_mps, let go; distance rolled to rest
      sigma_m: 0.03               # m, standard deviation of one reading (push and tape repeatability)
      readings:
        - {surface: foam, speed_mps: 1.0, distance_m: 0.31}   # surface: foam | floor (the hard launcher plate)
    slide_angle:                  # tilt of the foam at which a printed coupon starts to slide
      sigma_deg: 1.5              # deg, standard deviation of one reading
      readings_deg: [18.5, 19.0, 20.0]
    tip_angle:                    # tilt of a board at which the bare robot, held by a stop, tips over its wheels
      sigma_deg: 1.0              # deg, standard deviation of one reading
      readings:
        - {side: front, angle_deg: 58.5}   # side: front | back | left | right, the side it tips towards
    profile_mass:                 # each printed profile weighed on a scale
      sigma_kg: 0.0005            # kg, standard deviation of one weighing
      readings:
        - {configuration: A, mass_kg: 0.062}
    gate_shots:                   # the launcher fired with the bare robot, no campaign launch: the speed gate's reading
      readings:
        - {speed_mps: 0.8, measured_speed_mps: 0.79}   # the set speed and the gate's reading, m/s

Each section is optional, but the file needs one. Each reading enters ``rollability calibrate``'s likelihood
through a model of that measurement with Gaussian error of the stated standard deviation:

- ``slide_angle``: analytic. A block on a plane tilted by theta slides once tan(theta) exceeds the static
  friction coefficient, and the twin's printed-part-on-foam coefficient is ``sim.lateral_friction`` x
  ``launch_twin.foam.lateral_friction`` (both engines), so the model's angle is atan of that product.
- ``rollout``: simulated in the twin (:func:`~rollability_ros.core.sim.rollout.rollout_distance_m`): pins the
  foam's rolling friction and the wheels' drag (on the floor, the drag nearly alone).
- ``tip_angle``: the tilt-table test of a vehicle's static stability. The bare robot stands on its wheels on a
  board, a stop strip against its downhill wheels so it cannot roll or slide; the board is raised until the
  uphill wheels lift. That happens when the centre of mass passes over the downhill support edge:
  tan(angle) = e / h, h the centre of mass's height above the board and e its horizontal distance to the
  outermost support point on that side (:func:`tip_angle_deg`, from the robot's hull and centre of mass as the
  trials spawn it, any robot model). It pins the centre of mass's height (``robot.com_offset_z_m``), which the
  launches' verdicts leave wide.
- ``profile_mass``: the twin's mass of the configuration's printed profile (its mesh made as ``profile_print``
  says, times ``profile_mass_scale``: :func:`profile_mass_kg`); pins the profile's mass multiplier.
- ``gate_shots``: the launcher's characterisation (docs/characterisation.md, (c)): the bare robot fired at a set
  speed, the speed gate's reading. Its model is the speed gate's term of the campaign's readings
  (:mod:`~rollability_ros.core.campaign.likelihood_gate`: the twin's reading without scatter, the launch scatter
  of ``launch_twin.speed_sigma_fraction``, the table's error shared by the readings of one set speed), so no
  standard deviation is typed: the shot-to-shot spread is the launcher's, which the twin models. Pins the
  launcher's speed bias (``launch_twin.launcher.speed_bias_fraction``) before the first launch.

The log-likelihood of a characterisation under a set of twin parameters is
:func:`characterisation_log_likelihood`; calibration adds it to the launch outcomes' for every parameter set it
tries, so a file alone (no launches yet) already fits the unknowns it measures.
"""
import dataclasses
import math
import os
import typing

import numpy as np


if typing.TYPE_CHECKING:
    from rollability_ros.core.sim import LaunchTwinSettings

#: The ``format`` line of a characterisation file.
FORMAT = "rollability-characterisation-1"
#: Surfaces of a roll-out reading (:data:`rollability_ros.core.sim.rollout.SURFACES`, kept here so the parser
#: needs no physics).
ROLLOUT_SURFACES = ("foam", "floor")
#: Sides a tip-angle reading tips towards, as the horizontal direction in the robot's base frame (x forward, y
#: left, the up axis turned onto +z as the stable-pose screen turns it).
TIP_SIDES = {"front": (1.0, 0.0), "back": (-1.0, 0.0), "left": (0.0, 1.0), "right": (0.0, -1.0)}
_SECTIONS = {"format", "rollout", "slide_angle", "tip_angle", "profile_mass", "gate_shots"}
_MEASUREMENTS = ("rollout", "slide_angle", "tip_angle", "profile_mass", "gate_shots")


@dataclasses.dataclass(frozen=True)
class RolloutReading:
    """One roll-out: surface, push speed (m/s) and distance rolled (m)."""

    surface: str
    speed_mps: float
    distance_m: float


@dataclasses.dataclass(frozen=True)
class TipReading:
    """One tilt-table reading: the side the robot tipped towards (:data:`TIP_SIDES`) and the board's angle (deg)."""

    side: str
    angle_deg: float


@dataclasses.dataclass(frozen=True)
class MassReading:
    """One weighing of a configuration's printed profile (kg)."""

    configuration: str
    mass_kg: float


@dataclasses.dataclass(frozen=True)
class GateShot:
    """One launcher shot of the bare robot: the set speed and the speed gate's reading (m/s)."""

    speed_mps: float
    measured_speed_mps: float


@dataclasses.dataclass(frozen=True)
class Characterisation:
    """A characterisation file's readings (module docstring); empty tuples for an absent section."""

    source: str
    rollouts: typing.Tuple[RolloutReading, ...] = ()
    rollout_sigma_m: float = math.nan
    slide_angles_deg: typing.Tuple[float, ...] = ()
    slide_sigma_deg: float = math.nan
    tips: typing.Tuple[TipReading, ...] = ()
    tip_sigma_deg: float = math.nan
    masses: typing.Tuple[MassReading, ...] = ()
    mass_sigma_kg: float = math.nan
    gate_shots: typing.Tuple[GateShot, ...] = ()

    def summary(self) -> str:
        """One line: what the file holds."""
        parts = []
        if self.rollouts:
            parts.append(f"{len(self.rollouts)} roll-out(s) (sd {self.rollout_sigma_m:g} m)")
        if self.slide_angles_deg:
            parts.append(f"{len(self.slide_angles_deg)} slide angle(s) (sd {self.slide_sigma_deg:g} deg)")
        if self.tips:
            parts.append(f"{len(self.tips)} tip angle(s) (sd {self.tip_sigma_deg:g} deg)")
        if self.masses:
            parts.append(f"{len(self.masses)} profile weighing(s) (sd {self.mass_sigma_kg:g} kg)")
        if self.gate_shots:
            speeds = sorted({s.speed_mps for s in self.gate_shots})
            parts.append(f"{len(self.gate_shots)} gate shot(s) at " + ", ".join(f"{v:g}" for v in speeds) + " m/s")
        return f"characterisation {self.source}: " + ", ".join(parts)


def _number(value: typing.Any, where: str, low: float, high: float, low_open: bool = False) -> float:
    """``value`` as a finite float within [low, high] (``(low, high]`` with ``low_open``); ``ValueError`` naming
    ``where`` otherwise (a bool is not a number)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{where} must be a finite number, got {value!r}")
    if value > high or value < low or (low_open and value == low):
        bracket = "(" if low_open else "["
        raise ValueError(f"{where} must be in {bracket}{low:g}, {high:g}], got {value!r}")
    return float(value)


def _mapping(value: typing.Any, where: str, keys: typing.Set[str]) -> typing.Mapping[str, typing.Any]:
    """``value`` as a mapping with exactly ``keys``; ``ValueError`` naming ``where`` and the key otherwise."""
    if not isinstance(value, dict):
        raise ValueError(f"{where} must be a mapping, got {type(value).__name__}")
    unknown = sorted(set(map(str, value)) - keys)
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r} (known: {', '.join(sorted(keys))})")
    missing = sorted(keys - set(value))
    if missing:
        raise ValueError(f"{where}: missing key {missing[0]!r}")
    return value


def _readings(value: typing.Any, where: str) -> typing.List[typing.Any]:
    """A non-empty list; ``ValueError`` naming ``where`` otherwise."""
    if not isinstance(value, list) or not value:
        raise ValueError(f"{where} must be a non-empty list")
    return value


def _listed(section: typing.Any, name: str, sigma_key: str, sigma_high: float, keys: typing.Tuple[str, str],
            labels: typing.Optional[typing.Iterable[str]], value_high: float,
            make: typing.Callable[[str, float], typing.Any]) -> typing.Tuple[float, typing.Tuple[typing.Any, ...]]:
    """A section of a standard deviation ``sigma_key`` in (0, ``sigma_high``] and ``readings``, each a mapping of
    a label ``keys[0]`` (one of ``labels``, or any non-empty text when None) and a value ``keys[1]`` in (0,
    ``value_high``]: the standard deviation and ``make(label, value)`` of each reading."""
    mapping = _mapping(section, name, {sigma_key, "readings"})
    sigma = _number(mapping[sigma_key], f"{name}.{sigma_key}", 0.0, sigma_high, True)
    out = []
    for i, item in enumerate(_readings(mapping["readings"], f"{name}.readings")):
        where = f"{name}.readings[{i}]"
        item = _mapping(item, where, set(keys))
        label = item[keys[0]]
        known = list(labels) if labels is not None else None
        if not isinstance(label, str) or not label or (known is not None and label not in known):
            expected = f"one of {', '.join(known)}" if known is not None else "a design label"
            raise ValueError(f"{where}.{keys[0]} must be {expected}, got {label!r}")
        out.append(make(label, _number(item[keys[1]], f"{where}.{keys[1]}", 0.0, value_high, True)))
    return sigma, tuple(out)


def _gate_shots(section: typing.Any) -> typing.Tuple[GateShot, ...]:
    """The ``gate_shots`` section's readings: each a set speed in (0, 5] m/s and a gate reading in (0, 10] m/s."""
    shots = _mapping(section, "gate_shots", {"readings"})
    out = []
    for i, item in enumerate(_readings(shots["readings"], "gate_shots.readings")):
        where = f"gate_shots.readings[{i}]"
        item = _mapping(item, where, {"speed_mps", "measured_speed_mps"})
        out.append(GateShot(_number(item["speed_mps"], f"{where}.speed_mps", 0.0, 5.0, True),
                            _number(item["measured_speed_mps"], f"{where}.measured_speed_mps", 0.0, 10.0, True)))
    return tuple(out)


def parse_characterisation(document: object, source: str) -> Characterisation:
    """The :class:`Characterisation` of a loaded YAML ``document``; ``ValueError`` naming ``source`` and the
    first problem."""
    try:
        if not isinstance(document, dict):
            raise ValueError(f"must be a mapping with format and any of {', '.join(_MEASUREMENTS)}")
        unknown = sorted(set(map(str, document)) - _SECTIONS)
        if unknown:
            raise ValueError(f"unknown section {unknown[0]!r} (known: {', '.join(sorted(_SECTIONS))})")
        if document.get("format") != FORMAT:
            raise ValueError(f"format must be {FORMAT!r}, got {document.get('format')!r}")
        if not set(_MEASUREMENTS) & set(document):
            raise ValueError(f"holds no measurements: give any of {', '.join(_MEASUREMENTS)}")
        fields: typing.Dict[str, typing.Any] = {}
        if "rollout" in document:
            rollout = _mapping(document["rollout"], "rollout", {"sigma_m", "readings"})
            fields["rollout_sigma_m"] = _number(rollout["sigma_m"], "rollout.sigma_m", 0.0, 10.0, low_open=True)
            readings = []
            for i, item in enumerate(_readings(rollout["readings"], "rollout.readings")):
                where = f"rollout.readings[{i}]"
                item = _mapping(item, where, {"surface", "speed_mps", "distance_m"})
                if item["surface"] not in ROLLOUT_SURFACES:
                    raise ValueError(f"{where}.surface must be one of {', '.join(ROLLOUT_SURFACES)}, got "
                                     f"{item['surface']!r}")
                readings.append(RolloutReading(str(item["surface"]),
                                               _number(item["speed_mps"], f"{where}.speed_mps", 0.0, 5.0, True),
                                               _number(item["distance_m"], f"{where}.distance_m", 0.0, 50.0)))
            fields["rollouts"] = tuple(readings)
        if "slide_angle" in document:
            slide = _mapping(document["slide_angle"], "slide_angle", {"sigma_deg", "readings_deg"})
            fields["slide_sigma_deg"] = _number(slide["sigma_deg"], "slide_angle.sigma_deg", 0.0, 45.0, True)
            fields["slide_angles_deg"] = tuple(
                _number(v, f"slide_angle.readings_deg[{i}]", 0.0, 89.0, True)
                for i, v in enumerate(_readings(slide["readings_deg"], "slide_angle.readings_deg")))
        if "tip_angle" in document:
            fields["tip_sigma_deg"], fields["tips"] = _listed(document["tip_angle"], "tip_angle", "sigma_deg", 45.0,
                                                              ("side", "angle_deg"), TIP_SIDES, 89.0, TipReading)
        if "profile_mass" in document:
            fields["mass_sigma_kg"], fields["masses"] = _listed(document["profile_mass"], "profile_mass", "sigma_kg",
                                                                10.0, ("configuration", "mass_kg"), None, 100.0,
                                                                MassReading)
        if "gate_shots" in document:
            fields["gate_shots"] = _gate_shots(document["gate_shots"])
        return Characterisation(source=source, **fields)
    except ValueError as error:
        raise ValueError(f"{source}: {error}") from None


def load_characterisation(path: typing.Union[str, os.PathLike]) -> Characterisation:
    """Read and check a characterisation file (module docstring); ``ValueError`` in one line naming the file and
    the problem (unreadable, not YAML, a key written twice, or a bad entry). Loaded with
    :func:`~rollability_ros.core.safe_yaml.load` (plain data: nothing in it executes; a section or key written
    twice is refused, where YAML would keep the last one's readings and drop the first's silently)."""
    import yaml

    from rollability_ros.core import safe_yaml

    source = os.fspath(path)
    try:
        with open(source, encoding="utf-8") as stream:
            document = safe_yaml.load(stream)
    except (OSError, UnicodeDecodeError) as error:
        raise ValueError(f"{source}: cannot read the characterisation file ({error})") from None
    except safe_yaml.YamlLimitError as error:
        raise ValueError(f"{source}: {error}") from None
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise ValueError(f"{source}: not valid YAML{where}") from None
    return parse_characterisation(document, source)


def slide_angle_deg(twin: "LaunchTwinSettings") -> float:
    """The twin's slide angle (deg) of a printed coupon on the foam: atan(``sim.lateral_friction`` x
    ``launch_twin.foam.lateral_friction``) of the typed twin ``twin`` (module docstring)."""
    return math.degrees(math.atan(twin.physics.lateral_friction * twin.twin.foam.lateral_friction))


def tip_angle_deg(twin: "LaunchTwinSettings", side: str) -> float:
    """The tilt-table angle (deg) at which the typed twin's bare robot, standing on its wheels with a stop at its
    downhill wheels, tips towards ``side`` (:data:`TIP_SIDES`): atan(e / h), h the centre of mass's height above
    the lowest hull points (the support: the wheels' bottoms) and e its horizontal distance to the outermost of
    them on that side (module docstring). The robot's hull and centre of mass are the stable-pose screen's
    (``robot_hull``: PyBullet's collision shapes and link masses, any robot model)."""
    return tip_angles_deg(twin, (side,))[0]


def tip_angles_deg(twin: "LaunchTwinSettings", sides: typing.Sequence[str]) -> typing.List[float]:
    """:func:`tip_angle_deg` towards each of ``sides``, from one hull of the robot."""
    from rollability_ros.core.sim import robot_hull

    unknown = [side for side in sides if side not in TIP_SIDES]
    if unknown:
        raise ValueError(f"side must be one of {', '.join(TIP_SIDES)}, got {unknown[0]!r}")
    body = robot_hull(twin.robot_model(), None)
    vertices = np.asarray(body.hull.vertices)
    bottom = vertices[:, 2].min()
    support = vertices[vertices[:, 2] <= bottom + SUPPORT_TOLERANCE_M]
    height = float(body.com_m[2] - bottom)
    angles = []
    for side in sides:
        direction = np.asarray(TIP_SIDES[side])
        reach = float((support[:, :2] @ direction).max() - body.com_m[:2] @ direction)
        if reach <= 0.0:
            raise ValueError(f"the robot's centre of mass lies outside its support towards {side}: it does not stand")
        angles.append(math.degrees(math.atan2(reach, height)))
    return angles


def profile_mass_kg(twin: "LaunchTwinSettings", configuration: str) -> float:
    """The twin's mass (kg) of ``configuration``'s printed profile: its mesh (``launch_twin.designs``) made as the
    robot's ``profile_print`` says, times its ``profile_mass_scale``. ``ValueError`` for the baseline (no
    profile to weigh) or an unknown configuration."""
    from rollability_ros.core.profile import profile_mesh_for

    mesh = profile_mesh_for(configuration, twin.twin.designs)
    if mesh is None:
        raise ValueError(f"{configuration} has no printed profile to weigh")
    return float(twin.profile_body(mesh).mass_kg)


#: Hull points within this height of the lowest count as the support a tip-angle reading pivots over (m).
SUPPORT_TOLERANCE_M = 1e-4


def _gaussian(observed: float, predicted: float, sigma: float) -> float:
    """log N(observed | predicted, sigma^2)."""
    return -0.5 * ((observed - predicted) / sigma) ** 2 - math.log(sigma * math.sqrt(2.0 * math.pi))


def characterisation_log_likelihood(characterisation: Characterisation, twin: "LaunchTwinSettings") -> float:
    """log P(readings | the typed twin ``twin``): the sum over readings of each measurement model's Gaussian
    (module docstring). Roll-outs are simulated once per distinct (surface, speed)."""
    total = sum(_gaussian(angle, slide_angle_deg(twin), characterisation.slide_sigma_deg)
                for angle in characterisation.slide_angles_deg)
    sides = sorted({t.side for t in characterisation.tips})
    tipped = dict(zip(sides, tip_angles_deg(twin, sides))) if sides else {}
    total += sum(_gaussian(t.angle_deg, tipped[t.side], characterisation.tip_sigma_deg) for t in characterisation.tips)
    weighed = {c: profile_mass_kg(twin, c) for c in {m.configuration for m in characterisation.masses}}
    total += sum(_gaussian(m.mass_kg, weighed[m.configuration], characterisation.mass_sigma_kg)
                 for m in characterisation.masses)
    if characterisation.rollouts:
        from rollability_ros.core.sim import rollout_distance_m

        predicted = {key: rollout_distance_m(twin, key[1], key[0])
                     for key in {(r.surface, r.speed_mps) for r in characterisation.rollouts}}
        total += sum(_gaussian(r.distance_m, predicted[(r.surface, r.speed_mps)], characterisation.rollout_sigma_m)
                     for r in characterisation.rollouts)
    if characterisation.gate_shots:
        total += gate_shots_log_likelihood(characterisation.gate_shots, twin)
    return float(total)


#: The speed bias step of :func:`gate_shots_log_likelihood`'s slope (a central difference), as a fraction of speed.
SLOPE_STEP = 0.01


def gate_shots_log_likelihood(shots: typing.Sequence[GateShot], twin: "LaunchTwinSettings") -> float:
    """log P(the gate shots' readings | the typed twin ``twin``): the speed gate's model simulated at ``twin``
    (likelihood_gate's: the reading without scatter G, its spread G' (1 + b) ``speed_sigma_fraction``, G' by a
    difference of :data:`SLOPE_STEP` in the speed bias towards zero, the table's error shared per set speed), the
    direct fit's counterpart of the tabulated term the learnt likelihood uses."""
    from rollability_ros.core.campaign import gate_reading as gate
    from rollability_ros.core.sim import twin_value, twin_with_values

    bias = float(twin_value(twin, gate.BIAS_KEY))
    readings: typing.Dict[float, typing.List[float]] = {}
    for shot in shots:
        readings.setdefault(float(shot.speed_mps), []).append(float(shot.measured_speed_mps))
    groups = sorted(readings)
    mean, sd = [], []
    step = SLOPE_STEP if bias >= 0.0 else -SLOPE_STEP   # towards zero: inside the bias's declared range
    for speed in groups:
        mean.append(gate.gate_reading_mps(twin, gate.BARE_ROBOT, speed))
        toward = gate.gate_reading_mps(twin_with_values(twin, {gate.BIAS_KEY: bias - step}), gate.BARE_ROBOT, speed)
        sd.append(max(abs(mean[-1] - toward) / SLOPE_STEP * (1.0 + bias) * twin.twin.speed_sigma_fraction, 1e-6))
    return float(gate.readings_log_density(np.array([mean]), np.array([sd]), [readings[v] for v in groups])[0])
