"""Constraints in the compliance space: actuators, effectors, contacts and friction, and the
direct and inverse problems that choose their forces."""
