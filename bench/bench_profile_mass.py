"""What a profile weighs as printed, against the old solid block: the masses docs/optimization.md "Profile mass" quotes.

    python bench/bench_profile_mass.py [--config robot] [--repeats 20]

For simple shapes on the chassis's grid (a flat top, a dome, a centre ridge, a pyramid) at the shipped 0.09 m bound
and at 0.18 m, prints the profile's volume, its mass and the rise of the robot's centre of mass over the bare
chassis's (mm) three ways: the old solid block at 150 kg/m^3, the robot's ``profile_print`` (the shipped default:
PLA shell, 0.8 mm walls and skins, 20 % infill), and the same shell printed hollow (infill 0). Then the time one
``profile_body(mesh)`` takes (the print's inward offset: a half-space intersection and its hull) against the
solid block's (the mesh volume and centroid), measured in the same run: it runs once per candidate evaluated and
once per simulated launch of a campaign configuration.
"""
import argparse
import dataclasses
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # this checkout first

import numpy as np  # noqa: E402

from rollability_ros.core.profile import ProfilePrintSpec, profile_mesh  # noqa: E402
from rollability_ros.core.profile.geometry import grid_xy  # noqa: E402
from rollability_ros.core.robots.robot import ChassisModel  # noqa: E402
from rollability_ros.core.sim import evaluation  # noqa: E402

OLD_DENSITY_KGPM3 = 150.0


def shapes(grid):
    """name -> heights (simulation units, the grid's bound at the top) of simple profiles."""
    xy = grid_xy(grid)
    nx, ny = np.abs(xy[:, 0]) / (grid.length_m / 2), xy[:, 1] / (grid.width_m / 2)
    top = grid.height_max
    return {"flat top": np.full(grid.n_variables, top),
            "dome": np.clip(top * (1 - 0.5 * ny ** 2 - 0.5 * nx ** 2), 0.0, top),
            "centre ridge": np.where(ny < 0.2, top, 0.0),
            "pyramid": top * (1 - nx) * (1 - ny)}


def com_rise_mm(model, profile):
    """How far the profile lifts the robot's centre of mass above the bare robot's (mm)."""
    _, com, mass = model.standing_shapes_m()
    with_profile = (mass * com + profile.mass_kg * (model.mount_position_m + profile.com_m)) / (mass + profile.mass_kg)
    return (with_profile[2] - com[2]) * 1000.0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", nargs="+", default=["robot"], help="robot parameter files (default: robot)")
    parser.add_argument("--repeats", type=int, default=20, help="timed calls of each weighing (default 20)")
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: each step once, in seconds; the numbers mean nothing (bench/smoke.py)")
    args = parser.parse_args(argv)
    if args.smoke:
        args.repeats = 1
    settings = evaluation.load_settings(args.config)
    spec = settings.robot
    made = spec.profile_print
    makes = {"old solid 150": ProfilePrintSpec(model="solid", solid_density_kgpm3=OLD_DENSITY_KGPM3),
             f"print ({made.model}, infill {made.infill_fraction:g})": made,
             "print, hollow": dataclasses.replace(made, infill_fraction=0.0) if made.model == "shell" else made}
    print(f"robot.profile_print = {made}, profile_mass_scale = {spec.profile_mass_scale}")
    print(f"{'shape':<14}{'height m':>9}{'volume cm3':>11}" + "".join(f"{name:>32}" for name in makes))
    print(f"{'':<14}{'':>9}{'':>11}" + "".join(f"{'mass g / COM rise mm':>32}" for _ in makes))
    for unit in (settings.grid.unit_m,) if args.smoke else (settings.grid.unit_m, 2 * settings.grid.unit_m):
        grid = dataclasses.replace(settings.grid, unit_m=unit)
        for name, heights in list(shapes(grid).items())[:1 if args.smoke else None]:
            mesh = profile_mesh(heights, grid)
            assert mesh is not None   # every shape has a height
            cells = []
            for make in makes.values():
                model = ChassisModel(dataclasses.replace(spec, profile_print=make))
                profile = model.profile_body(mesh)
                cells.append(f"{profile.mass_kg * 1000:>22.0f} / {com_rise_mm(model, profile):5.1f}")
            print(f"{name:<14}{grid.height_max * unit:>9.2f}{mesh.volume * 1e6:>11.0f}" + "".join(cells))
    mesh = profile_mesh(shapes(settings.grid)["dome"], settings.grid)
    assert mesh is not None   # the dome has a height
    old = ChassisModel(dataclasses.replace(spec, profile_print=makes["old solid 150"]))
    timings = {}
    for label, model in (("print", ChassisModel(spec)), ("solid", old)):
        model.profile_body(mesh)  # imports and caches outside the timing
        start = time.perf_counter()
        for _ in range(args.repeats):
            model.profile_body(mesh)
        timings[label] = (time.perf_counter() - start) / args.repeats
    print(f"profile_body(dome): print {timings['print'] * 1000:.1f} ms, solid block {timings['solid'] * 1000:.1f} ms "
          f"per call (ratio {timings['print'] / timings['solid']:.1f}, same run, {args.repeats} calls each)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
