"""Robot models the simulation spawns: the built-in chassis, and any wheeled robot from its URDF.

- robot: RobotModel interface, ChassisSpec, ProfileBody
- mesh_files: an ASCII STL collision mesh as a binary STL in the converted-mesh cache (both engines read it)
- urdf_description: read and check a URDF into a rigid-body description
- urdf_robot: a URDF robot with the profile on a mount link

The face is ``__init__.pyi`` beside this file: the names code outside ``core/robots`` imports (``from
rollability_ros.core.robots import <name>``), each with the module it lives in. ``lazy_loader.attach_stub``
(scientific-python SPEC 1) reads it: importing the face loads none of the modules behind it, and a name's
module is imported when the name is first used, so a light caller (the rig computer) never pays for numpy,
physics or plotting. Type checkers read the same stub. test/core/test_faces.py checks both.
"""
import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
