"""Profile geometry: grid heights -> mirrored vertices -> convex hull mesh, metrics, printability, STL;
configuration ids -> profile solids (baseline, designs, files).

- geometry: ProfileGrid, profile_mesh, printability checks
- descriptors: the traits maximum height (mm) and sharpness (deg) of a profile's hull
- designs: campaign configuration id -> the solid it mounts
- print_mass: a profile's mass, centre of mass and inertia from its mesh and how it is printed

The face below is what code outside ``core/profile`` imports (``from rollability_ros.core.profile import
ProfileGrid``). It is lazy (``core/faces.py``): importing it loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller never pays for numpy and trimesh.
"""
import typing

from rollability_ros.core.faces import lazy_attribute

if typing.TYPE_CHECKING:   # imported when first used: lazy_attribute reads this block
    from rollability_ros.core.profile import descriptors, designs, geometry, print_mass
    from rollability_ros.core.profile.descriptors import ProfileDescriptors, mesh_descriptors, profile_descriptors
    from rollability_ros.core.profile.designs import DesignSources, configuration_ids, profile_mesh_for
    from rollability_ros.core.profile.geometry import (Mesh, PrinterSpec, ProfileGrid, check_heights,
                                                       design_space_printability, is_baseline, load_profile_mesh,
                                                       profile_mesh)
    from rollability_ros.core.profile.print_mass import MassProperties, ProfilePrintSpec, print_mass_properties

__all__ = [
    "DesignSources", "MassProperties", "Mesh", "PrinterSpec", "ProfileDescriptors", "ProfileGrid", "ProfilePrintSpec",
    "check_heights", "configuration_ids", "descriptors", "design_space_printability", "designs", "geometry",
    "is_baseline", "load_profile_mesh", "mesh_descriptors", "print_mass", "print_mass_properties",
    "profile_descriptors", "profile_mesh", "profile_mesh_for",
]


def __getattr__(name: str) -> typing.Any:
    return lazy_attribute(__name__, name)
