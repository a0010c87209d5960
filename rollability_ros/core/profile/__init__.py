"""Profile geometry: grid heights -> mirrored vertices -> convex hull mesh, metrics, printability, STL;
configuration ids -> profile solids (baseline, designs, files).

- geometry: ProfileGrid, profile_mesh, printability checks
- descriptors: the traits maximum height (mm) and sharpness (deg) of a profile's hull
- designs: campaign configuration id -> the solid it mounts
"""
