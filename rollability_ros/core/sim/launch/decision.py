"""The early decision of a launch on the foam (:func:`~rollability_ros.core.sim.launch.loop.step_launch`): the
energy argument of :mod:`~rollability_ros.core.sim.early_decision` with the foam's top as the ground, held only while
the robot cannot reach the pad's edges or the ledge. Engine-neutral: each engine's world supplies its energy
monitor."""
import math
import typing

from rollability_ros.core.sim.early_decision import BasinMap
from rollability_ros.core.sim.launch.settings import FoamSpec, LaunchTwinSettings


class EnergyReading(typing.Protocol):
    """What :func:`decided_on_foam` reads of an engine's energy monitor (the PyBullet trials'
    :class:`~rollability_ros.core.sim.trials.EnergyMonitor`, the MuJoCo trials'
    :class:`~rollability_ros.core.sim.mujoco_trials.MujocoEnergyMonitor`): its barriers, the hull's largest distance
    from the centre of mass (m), and the energy height (m) its last :meth:`decide` read."""

    basins: BasinMap
    radius_m: float
    energy_height_m: float

    def decide(self) -> typing.Optional[bool]:
        """True / False once the outcome is fixed (upright / not), else None."""


def foam_sink_m(settings: LaunchTwinSettings, mass_kg: float) -> float:
    """How far (m) a robot of ``mass_kg`` resting or rocking on the foam may sink into it: 3 m g / stiffness, its
    whole weight on one contact point, tripled for dynamic loads (as :func:`mujoco_trials.penetration_allowance_m`)."""
    return 3 * mass_kg * abs(settings.physics.gravity_mps2) / settings.twin.foam.contact_stiffness_npm

def clear_of_foam_edges(com_xy_m: typing.Sequence[float], radius_m: float, foam: FoamSpec) -> bool:
    """True when a hull of ``radius_m`` about a centre of mass at ``com_xy_m`` cannot reach the foam's edges or the
    ledge's wall (x = 0): the foam's flat top is then the only ground it can meet."""
    x, y = com_xy_m
    return radius_m < x < foam.length_m - radius_m and abs(y) < foam.width_m / 2 - radius_m

#: How long (s) a decided robot is assumed to keep rolling at most (:func:`decided_on_foam`): NOT a bound the
#: energy argument gives (a robot on free wheels loses little energy rolling); bench/verify_early_decision.py
#: --launches is the evidence that no outcome changes.
ROLL_HORIZON_S = 2.0

def hopeless_to_decide(com_xy_m: typing.Sequence[float], speed_mps: float, radius_m: float,
                       settings: LaunchTwinSettings, remaining_s: float) -> bool:
    """True when a robot at ``com_xy_m`` moving at ``speed_mps`` (its base) certainly fails
    :func:`decided_on_foam`'s edge test (the bound on its speed is at least about its speed now): the twins skip
    the energy computation then. Only a saving: skipping a decision never changes an outcome."""
    return not clear_of_foam_edges(com_xy_m, radius_m + speed_mps * min(remaining_s, ROLL_HORIZON_S),
                                   settings.twin.foam)

def decided_on_foam(energy: EnergyReading, com_xy_m: typing.Sequence[float], settings: LaunchTwinSettings,
                    remaining_s: float) -> typing.Optional[bool]:
    """The early decision of a landed robot (True / False / None), given its energy monitor (after ``decide``
    has read the state: ``energy_height_m``), its centre of mass (x, y) and the time left to the cap (s).

    The energy argument fixes the robot's orientation outcome on the foam's flat top, but a decided robot may
    still roll (on its wheels, or sliding) off the foam or back against the ledge, onto ground other than that
    top: the 5 cm drop to the floor or the ledge's wall can still turn it, so the argument no longer holds there
    (before issue 40 a chassis decided upright rolled off the foam's side 1.6 s after landing and the foam-contact
    rule judged it not upright; the rig's rule, :func:`rig_verdict`, counts it wherever it rests, but the drop is
    not in the barriers).
    Energy bounds its speed for ever by ``sqrt(2 g (E - lowest))`` (``lowest``: the lowest resting COM height of
    the decided outcome; the foam's sinking is left out here); the decision stands only if its hull cannot reach
    the foam's edges or the ledge at that speed within :data:`ROLL_HORIZON_S` (or the time left, if shorter)."""
    decision = energy.decide()
    if decision is None:
        return None
    excess_m = max(0.0, energy.energy_height_m - energy.basins.lowest_m(decision))
    travel_m = math.sqrt(2 * abs(settings.physics.gravity_mps2) * excess_m) * min(remaining_s, ROLL_HORIZON_S)
    return decision if clear_of_foam_edges(com_xy_m, energy.radius_m + travel_m, settings.twin.foam) else None
