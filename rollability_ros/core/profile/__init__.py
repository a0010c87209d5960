"""Profile geometry: grid heights -> mirrored vertices -> convex hull mesh, metrics, printability, STL;
configuration ids -> profile solids (baseline, designs, files).

- geometry: ProfileGrid, profile_mesh, printability checks
- descriptors: the traits maximum height (mm) and sharpness (deg) of a profile's hull
- designs: campaign configuration id -> the solid it mounts
- print_mass: a profile's mass, centre of mass and inertia from its mesh and how it is printed

The face is ``__init__.pyi`` beside this file: the names code outside ``core/profile`` imports (``from
rollability_ros.core.profile import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
