"""Learned condensed FEM model (thesis §5.1): W and delta_free of a robot predicted by a
network from its actuator (and contact) state, for control, calibration and design.

Data flow: :mod:`~pliant.condensed.collect` solves the robot at sampled displacements (and
designs) into a :class:`~pliant.condensed.dataset.Dataset`; :mod:`~pliant.condensed.train` fits
the networks F and G on it; :class:`~pliant.condensed.learned.LearnedCondensedModel` predicts
condensed problems, :mod:`~pliant.condensed.control` controls with them;
:class:`~pliant.condensed.contact.ContactRobot` holds fixed contact points (§5.1.4) and
:mod:`~pliant.condensed.manipulation` controls objects held by them (Eq. 5.10-5.13,
Algorithm 1);
:class:`~pliant.condensed.parametric.ParametricCondensedModel` (F after G) is differentiated by
:mod:`~pliant.condensed.calibration` and :mod:`~pliant.condensed.design`. torch and h5py are
needed (``pip install 'pliant[learn]'``).
"""

from importlib import import_module

# Names resolved on first use: `pliant condensed --help` and the rest of Pliant must not need
# torch and h5py until a condensed model is actually used.
_WHERE = {
    "collect": "collect",
    "load_or_collect": "collect",
    "calibrate": "calibration",
    "observe": "calibration",
    "CalibrationResult": "calibration",
    "ParametricCondensedModel": "parametric",
    "train_parametric": "parametric",
    "FingerObjectives": "design",
    "design_study": "design",
    "WarmInverse": "control",
    "CollectionPlan": "dataset",
    "ContactRobot": "contact",
    "Grasp": "manipulation",
    "ManipulationController": "manipulation",
    "RigidObject": "manipulation",
    "follow_object": "manipulation",
    "Dataset": "dataset",
    "Layout": "layout",
    "LearnedCondensedModel": "learned",
    "OutOfBoundsWarning": "learned",
    "TrainConfig": "train",
    "evaluate": "train",
    "train_condensed": "train",
    "train_design": "train",
    "PID": "control",
    "EmbeddedController": "control",
    "ExactCondensed": "control",
    "follow_embedded": "control",
    "follow_trajectory": "control",
    "loop_frequency": "control",
}
__all__ = sorted(_WHERE)


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module 'pliant.condensed' has no attribute {name!r}")
    return getattr(import_module(f"pliant.condensed.{_WHERE[name]}"), name)
