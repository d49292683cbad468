"""Pliant: simulate, control and learn soft robots with the finite element method."""

__version__ = "0.1.0"
