"""The experiment matrix of a launch campaign: :class:`CampaignSpec` (configurations x heights x speeds x angles,
repetitions, order) and :func:`load_campaign_spec`.

A shared value type at the core's bottom: the campaign plans its trials from it (``campaign/plan``) and the robust
objective scores a design over the same conditions (``sim/objectives``), so neither layer imports the other for
it. Stdlib only (runs on the robot computer).
"""
import dataclasses
import itertools
import typing

from rollability_ros.core.config import check_path_component, edge_parse, from_mapping, load_parameters, section
from rollability_ros.core.records import LaunchCondition

__all__ = ["LEVELS", "CampaignSpec", "load_campaign_spec"]

#: The matrix levels in the order that minimises manual changes; LaunchCondition field names.
LEVELS = ("configuration", "height_m", "angle_deg", "speed_mps")


def _format_number(value, sign=""):
    return format(float(value), sign + ".6g")


@dataclasses.dataclass
class CampaignSpec:
    """The experiment matrix of ``config/campaign.yaml`` (namespace ``campaign``); paper defaults: 400 trials."""

    run_id: str = dataclasses.field(default="paper-campaign", metadata={
        "description": "store key of this campaign; starting again with the same id resumes it"})
    configurations: typing.List[str] = dataclasses.field(default_factory=lambda: ["baseline", "A", "B", "C"], metadata={
        "description": "configuration ids to launch (profile meshes, e.g. baseline, A, B, C), mounted in this order"})
    heights_m: typing.List[float] = dataclasses.field(default_factory=lambda: [0.75, 1.30], metadata={
        "description": "ledge heights above the impact surface, one level each, m"})
    speeds_mps: typing.List[float] = dataclasses.field(default_factory=lambda: [0.8, 1.5], metadata={
        "description": "target launch speeds at the ledge, one level each, m/s"})
    angles_deg: typing.List[float] = dataclasses.field(default_factory=lambda: [-60.0, -30.0, 0.0, 30.0, 60.0], metadata={
        "description": "launch angles of the campaign's conditions, deg (sign convention in config/rig.yaml)"})
    repetitions: int = dataclasses.field(default=5, metadata={
        "description": "launches per grouped condition; the majority of them decides the condition (count)",
        "range": (1, 1000)})
    random_order: bool = dataclasses.field(default=False, metadata={
        "description": "true: shuffle the trials inside each block (seeded, reproducible); false: the plan's fixed "
                       "order"})
    random_block: str = dataclasses.field(default="height_m", metadata={
        "description": "shuffle unit: trials sharing the levels up to this factor stay together (configuration | "
                       "height_m | angle_deg | speed_mps)"})
    random_seed: int = dataclasses.field(default=0, metadata={
        "description": "seed of the trial-order shuffle (integer, >= 0)", "range": (0, 2147483647)})

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first unusable setting."""
        check_path_component(self.run_id, "campaign.run_id")   # a store key that also names study folders
        for name in ("configurations", "heights_m", "speeds_mps", "angles_deg"):
            values = getattr(self, name)
            if not values:
                raise ValueError(f"{name} must list at least one value")
            keys = [v if name == "configurations" else _format_number(v) for v in values]
            if len(set(keys)) != len(keys):
                raise ValueError(f"{name} has duplicate values: {values}")
        for configuration in self.configurations:
            if not configuration or any(c.isspace() or c == "/" for c in configuration):
                raise ValueError(f"configuration ids must be non-empty without spaces or '/', got {configuration!r}")
        if self.random_block not in LEVELS:
            raise ValueError(f"random_block must be one of {', '.join(LEVELS)}, got {self.random_block!r}")
        for height, speed, angle in itertools.product(self.heights_m, self.speeds_mps, self.angles_deg):
            LaunchCondition(self.configurations[0], height, speed, angle).validate()

    @property
    def trial_count(self) -> int:
        """Number of trials in the matrix."""
        return (len(self.configurations) * len(self.heights_m) * len(self.speeds_mps) * len(self.angles_deg)
                * self.repetitions)


@edge_parse
def load_campaign_spec(paths: typing.Sequence[str] = ("campaign",), node_name: str = "/**") -> CampaignSpec:
    """Read :class:`CampaignSpec` from parameter files (bare names are shipped ``config/`` files)."""
    return from_mapping(CampaignSpec, section(load_parameters(paths, node_name), "campaign"), "campaign")
