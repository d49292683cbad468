"""Deformable bodies (tetrahedra, rods, membranes), materials, rigid bodies and the compiled
kernels of their forces and tangents."""
