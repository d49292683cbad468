"""Learning: RL training and evaluation, behaviour cloning, the configuration-space graph."""
