"""Geometry below the bodies and the contacts: rotations, collision shapes with their signed
distances and the detection of contacts between them, and the inertia of solid shapes."""
