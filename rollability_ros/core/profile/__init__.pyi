"""The face of ``rollability_ros.core.profile``: the names code outside the subpackage imports, and where each
lives. Type checkers read this stub; at run time ``lazy_loader.attach_stub`` (``__init__.py``) reads the same
imports and loads a name's module when the name is first used."""
from .descriptors import ProfileDescriptors, height_bound_mm, mesh_descriptors, profile_descriptors
from .designs import (DESIGN_GRID_KEYS, DesignSources, check_printed_with, configuration_ids, designs_file_labels,
                      print_differences, print_instructions_from_text, profile_mesh_for)
from .geometry import (MESH_UNITS, Mesh, PrinterSpec, ProfileGrid, ProfileMetrics, check_heights, check_printability,
                       design_space_printability, export_mesh, is_baseline, load_profile_mesh, marker_points,
                       mesh_metrics, profile_mesh, simple_profiles)
from .print_mass import MassProperties, ProfilePrintSpec, print_mass_properties

__all__ = [
    "DESIGN_GRID_KEYS", "MESH_UNITS", "DesignSources", "MassProperties", "Mesh", "PrinterSpec", "ProfileDescriptors",
    "ProfileGrid", "ProfileMetrics", "ProfilePrintSpec", "check_heights", "check_printability", "check_printed_with",
    "configuration_ids", "design_space_printability", "designs_file_labels", "export_mesh", "height_bound_mm",
    "is_baseline", "load_profile_mesh", "marker_points", "mesh_descriptors", "mesh_metrics", "print_differences",
    "print_instructions_from_text", "print_mass_properties", "profile_descriptors", "profile_mesh", "profile_mesh_for",
    "simple_profiles"
]
