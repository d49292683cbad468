"""The condensed-model dataset: how it was made (the plan), what it holds, and its HDF5 file.

One sample is an equilibrium of the robot for imposed actuator displacements (thesis §5.1.2):
the reached delta_a (and delta_c), W's upper triangle and delta_free there, the rest values
W0 and delta0_free of its design (at lambda = 0), the design parameters and the command.

File layout (format_version 1): root attributes `format` and `format_version` and `metadata`
(JSON: the collection plan, the constraint layout, the software version); groups `train` and
`test` with one dataset per field of :class:`Split`, one row per sample. Every dataset carries
HDF5's Fletcher-32 checksum per storage chunk and a `sha256` attribute over its values, the
metadata a `metadata_sha256`: a corrupt byte anywhere fails `Dataset.load` and `verify` names
the part (files written before the checksums load unchecked). Samples whose static
solve failed are kept, NaN-filled, with `converged` false, so that a plan always gives the same
rows; learning uses the converged ones.
"""

from __future__ import annotations

import hashlib
import json
import math
import numbers
import os
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import h5py
import numpy as np

import pliant
from pliant.condensed.layout import Layout
from pliant.condensed.sampling import Box, grouped_train_test_points, train_test_points
from pliant.errors import DatasetError, LearnedModelError
from pliant.files import atomic_path

FORMAT = "pliant-condensed-dataset"
FORMAT_VERSION = 1
SPLITS = ("train", "test")
SAMPLINGS = ("box", "gripper")
STARTS = ("previous", "rest")
GRIPPER_FINGERS = 3
FLOAT32_MAX = float(
    np.finfo(np.float32).max
)  # fingers of the gripper that "gripper" sampling holds its object with


@dataclass(frozen=True)
class CollectionPlan:
    """What to sample and how to solve it; a plan gives the same dataset on any number of
    workers and across resumes.

    Args:
        robot: registered robot name (pliant.robots.build).
        actuator_bounds: (low, high) of each actuator's imposed displacement.
        n_train: training samples (scrambled Halton); the test set has
            round(test_fraction * n_train) random samples.
        robot_kwargs: builder keywords held fixed.
        design_bounds: builder keyword -> (low, high) of design parameters sampled with the
            displacements (e.g. {"poisson_ratio": (0.40, 0.499)}); empty for one design.
        samples_per_design: consecutive samples that share a design (1: one Halton sequence
            fills the joint box of displacements and designs; more: designs and displacements
            are drawn apart, and each design is built and meshed once for that many samples).
        seed: seed of both point sets.
        max_increment: largest change of an actuator command in one static step (adaptive
            load stepping, halved where Newton fails).
        start: where each sample's load stepping starts. "previous": the previous sample's
            equilibrium in the chunk (fewest steps). "rest": the rest equilibrium of the
            sample's design, so that a robot with several equilibria for one command gets the
            one reached by actuating it from rest, whatever the samples before, and F is a
            function. The Diamond's arms, compressed by antagonist cables, buckle one way or
            the other: from the previous sample, 2 of 4 of the 10 worst-predicted test samples
            of Table 5.1 re-solved from rest sat on another branch (2.6 and 4.9 standard
            deviations apart), and the worst 1 % of the test samples made 75 % of its test loss.
        tolerance: Newton's convergence threshold, relative to the body size (the solver's
            1e-10 costs iterations of its linear tail without changing W or delta_free).
        newton_iterations: Newton iterations before a load step is halved.
        chunk_size: samples solved in a row by one worker and saved together; each chunk starts
            from the rest equilibrium, which makes chunks independent.
        units: the scene's units, recorded in the file.
        contacts: mesh landmark of the robot's fixed contact points (§5.1.4), whose
            displacements delta_c are imposed with the actuators' and recorded; "" for none.
        object_bounds: (low, high) of the displacement of the object the contact points hold,
            a translation (3) then optionally a rotation vector (3) about their centroid:
            sampling "box", from where the actuators alone put the contact points; "gripper",
            from the cube's pose in the grasp.
        sampling: "box": the actuator commands (and object displacement) fill their box;
            "gripper": only the object's displacement is sampled, a cube held by a gripper of
            GRIPPER_FINGERS copies of the robot, and inverse control with the exact matrices
            finds the actuation that holds it there (the thesis' contact datasets); every
            sampled pose gives one sample per finger, and `actuator_bounds` bound the control.
        consistent_tangent: W of the static solver's consistent tangent (the equilibrium's
            compliance, with the cables' geometric stiffness), or of SOFA's material tangent,
            the thesis' W (the equilibria are the same). A finger held at its tip is
            compressed by its cables: with their geometric stiffness its W grows steeply with
            their tension, off the states a box of (delta_a, delta_c) samples; the material
            tangent's W does not. Likewise a Diamond whose held cables stabilise compressed
            arms: its consistent K is near singular there (W up to 10^4 times its median).
    """

    robot: str
    actuator_bounds: tuple[tuple[float, float], ...]
    n_train: int
    robot_kwargs: dict = field(default_factory=dict)
    design_bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    test_fraction: float = 0.25
    seed: int = 0
    max_increment: float = 8.0
    tolerance: float = 1e-8
    newton_iterations: int = 60
    samples_per_design: int = 1
    chunk_size: int = 16
    units: str = "mm, kg, s (forces in mN, W in mm/mN)"
    contacts: str = ""
    object_bounds: tuple[tuple[float, float], ...] = ()
    sampling: str = "box"
    consistent_tangent: bool = True
    start: str = "previous"

    def __post_init__(self) -> None:
        kinds = {
            "n_train": numbers.Integral,
            "chunk_size": numbers.Integral,
            "newton_iterations": numbers.Integral,
            "samples_per_design": numbers.Integral,
            "seed": numbers.Integral,
            "test_fraction": numbers.Real,
            "max_increment": numbers.Real,
            "tolerance": numbers.Real,
        }
        for name, kind in kinds.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, kind):
                what = "an integer" if kind is numbers.Integral else "a real number"
                raise DatasetError(f"{name} must be {what}, got {value!r}")
        if not all(
            math.isfinite(getattr(self, name))
            for name in ("test_fraction", "max_increment", "tolerance")
        ):
            raise DatasetError("test_fraction, max_increment and tolerance must be finite")
        if not isinstance(self.robot, str):
            raise DatasetError(f"robot must be a robot's name, got {self.robot!r}")
        if self.n_train < 1 or self.chunk_size < 1:
            raise DatasetError(
                f"n_train and chunk_size must be >= 1, got {self.n_train}, {self.chunk_size}"
            )
        if not (self.max_increment > 0 and self.tolerance > 0 and self.newton_iterations >= 1):
            raise DatasetError(
                "max_increment and tolerance must be > 0 and newton_iterations >= 1, got"
                f" {self.max_increment}, {self.tolerance}, {self.newton_iterations}"
            )
        if not self.test_fraction >= 0.0:
            raise DatasetError(f"test_fraction must be >= 0, got {self.test_fraction}")
        if self.samples_per_design < 1 or self.chunk_size % self.samples_per_design:
            raise DatasetError(
                f"chunk_size ({self.chunk_size}) must be a multiple of samples_per_design"
                f" ({self.samples_per_design}): a design split between chunks is built twice"
            )
        if self.start not in STARTS:
            raise DatasetError(f"start must be one of {STARTS}, got {self.start!r}")
        if self.sampling not in SAMPLINGS:
            raise DatasetError(f"sampling must be one of {SAMPLINGS}, got {self.sampling!r}")
        if len(self.object_bounds) not in (0, 3, 6):
            raise DatasetError(
                "object_bounds bound a translation (3) or a translation and a rotation (6), got"
                f" {len(self.object_bounds)} intervals"
            )
        if self.object_bounds and not self.contacts:
            raise DatasetError("object_bounds move contact points: name them with `contacts`")
        if self.sampling == "gripper" and not (self.contacts and self.object_bounds):
            raise DatasetError(
                "gripper sampling holds an object by contact points: it needs `contacts` and"
                " `object_bounds`"
            )
        if self.sampling == "gripper" and self.start != "previous":
            raise DatasetError(
                "gripper sampling drives the cube from one sampled pose to the next: start must"
                f" be 'previous', got {self.start!r}"
            )
        if self.sampling == "gripper" and self.design_bounds:
            raise DatasetError("gripper sampling is for one design (no design_bounds)")
        _ = self.box  # Box checks the bounds

    @property
    def n_test(self) -> int:
        return round(self.test_fraction * self.n_train)

    @property
    def rows_per_point(self) -> int:
        """Samples per sampled point: one, or one per finger of the gripper."""
        return GRIPPER_FINGERS if self.sampling == "gripper" else 1

    @property
    def n_commands(self) -> int:
        """Columns of `Split.command`: actuator commands, then the object's displacement."""
        return len(self.actuator_bounds) + len(self.object_bounds)

    @property
    def design_names(self) -> tuple[str, ...]:
        return tuple(self.design_bounds)

    @property
    def box(self) -> Box:
        """The sampled box: displacements (`actuator_box`), then design parameters."""
        bounds = [*self._displacement_bounds, *self.design_bounds.values()]
        return Box([lo for lo, _ in bounds], [hi for _, hi in bounds])

    @property
    def actuator_box(self) -> Box:
        """The sampled displacements: actuators' (sampling "box") and the object's."""
        bounds = self._displacement_bounds
        return Box([lo for lo, _ in bounds], [hi for _, hi in bounds])

    @property
    def _displacement_bounds(self) -> list[tuple[float, float]]:
        actuators = self.actuator_bounds if self.sampling == "box" else ()
        return [*actuators, *self.object_bounds]

    @property
    def design_box(self) -> Box:
        bounds = self.design_bounds.values()
        return Box([lo for lo, _ in bounds], [hi for _, hi in bounds])

    def points(self) -> dict[str, np.ndarray]:
        """Per split, one row per sampled point: actuator commands (sampling "box"), the
        object's displacement, then design parameters."""
        if self.samples_per_design == 1:
            return train_test_points(self.box, self.n_train, self.n_test, seed=self.seed)
        return grouped_train_test_points(
            self.actuator_box,
            self.design_box,
            self.n_train,
            self.n_test,
            self.samples_per_design,
            seed=self.seed,
        )

    def to_dict(self) -> dict:
        data = asdict(self)
        data["actuator_bounds"] = [list(b) for b in self.actuator_bounds]
        data["object_bounds"] = [list(b) for b in self.object_bounds]
        data["design_bounds"] = {k: list(v) for k, v in self.design_bounds.items()}
        return data

    @classmethod
    def from_dict(cls, data: dict) -> CollectionPlan:
        data = dict(data)
        data["actuator_bounds"] = tuple(tuple(b) for b in data["actuator_bounds"])
        data["object_bounds"] = tuple(tuple(b) for b in data.get("object_bounds", ()))
        data["design_bounds"] = {k: tuple(v) for k, v in data["design_bounds"].items()}
        # Plans stored before the field existed were solved with SOFA's material tangent.
        data.setdefault("consistent_tangent", False)
        data.setdefault("start", "previous")
        return cls(**data)


@dataclass
class Split:
    """The samples of one split, one row each.

    Attributes:
        command: imposed actuator displacements, then the object's displacement (n,
            plan.n_commands).
        design: design parameters (n, n_design).
        delta_a, delta_c: reached actuator and contact distances (n, rows).
        w_triangle, free_distance: W's upper triangle and delta_free at the equilibrium.
        w0_triangle, free_distance0: the same at the rest equilibrium of the sample's design.
        converged: whether the static solve converged (other fields NaN where not).
    """

    command: np.ndarray
    design: np.ndarray
    delta_a: np.ndarray
    delta_c: np.ndarray
    w_triangle: np.ndarray
    free_distance: np.ndarray
    w0_triangle: np.ndarray
    free_distance0: np.ndarray
    converged: np.ndarray

    def __len__(self) -> int:
        return len(self.converged)

    @classmethod
    def empty(cls, widths: dict[str, int]) -> Split:
        """No samples, with the columns of `widths` (:meth:`widths`): a split of zero rows."""
        return cls(
            **{name: np.zeros((0, n)) for name, n in widths.items()},
            converged=np.zeros(0, dtype=bool),
        )

    @classmethod
    def concatenate(cls, parts: list[Split]) -> Split:
        return cls(
            **{f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(cls)}
        )

    def converged_only(self) -> Split:
        keep = self.converged.astype(bool)
        return Split(**{f.name: getattr(self, f.name)[keep] for f in fields(self)})

    def head(self, n: int) -> Split:
        """The first `n` samples (training points are a Halton sequence: its first `n` are
        themselves evenly spread)."""
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
            raise DatasetError(f"a split's head needs a count >= 0, got {n!r}")
        return Split(**{f.name: getattr(self, f.name)[:n] for f in fields(self)})

    def inputs(self) -> np.ndarray:
        """Inputs of F (Eq. 5.2): (delta_a, delta_c, W0 triangle, delta0_free)."""
        return np.hstack([self.delta_a, self.delta_c, self.w0_triangle, self.free_distance0])

    def outputs(self) -> np.ndarray:
        """Outputs of F: (W triangle, delta_free)."""
        return np.hstack([self.w_triangle, self.free_distance])

    @staticmethod
    def widths(plan: CollectionPlan, layout: Layout) -> dict[str, int]:
        """Expected number of columns of each field."""
        counts = layout.counts
        return {
            "command": plan.n_commands,
            "design": len(plan.design_names),
            "delta_a": counts["actuator"],
            "delta_c": counts["contact"],
            "w_triangle": layout.n_triangle,
            "free_distance": layout.n_rows,
            "w0_triangle": layout.n_triangle,
            "free_distance0": layout.n_rows,
        }


@dataclass
class Dataset:
    """A collected dataset: its plan, the robot's constraint layout and the two splits."""

    plan: CollectionPlan
    layout: Layout
    train: Split
    test: Split
    software_version: str = pliant.__version__

    def split(self, name: str) -> Split:
        if name not in SPLITS:
            raise DatasetError(f"split must be one of {SPLITS}, got {name!r}")
        return self.train if name == "train" else self.test

    def metadata(self) -> dict:
        return {
            "plan": self.plan.to_dict(),
            "layout": self.layout.to_dict(),
            "software_version": self.software_version,
        }

    def save(self, path: str | os.PathLike) -> Path:
        """Write the HDF5 file atomically: a temporary file in the same folder, then rename."""
        self.validate("the dataset to save")
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, self._write)
        return path

    def _write(self, filename: str) -> None:
        with h5py.File(filename, "w") as f:
            f.attrs["format"] = FORMAT
            f.attrs["format_version"] = FORMAT_VERSION
            metadata = json.dumps(self.metadata())
            f.attrs["metadata"] = metadata
            f.attrs["metadata_sha256"] = hashlib.sha256(metadata.encode()).hexdigest()
            for name in SPLITS:
                group = f.create_group(name)
                for fld in fields(Split):
                    values = getattr(self.split(name), fld.name)
                    # Fletcher-32 needs chunked storage, which needs at least one element.
                    stored = group.create_dataset(fld.name, data=values, fletcher32=values.size > 0)
                    stored.attrs["sha256"] = checksum(values)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Dataset:
        """Read and validate a dataset file; DatasetError names what is wrong."""
        path = Path(path)
        if not path.is_file():
            raise DatasetError(f"no dataset file at {path}")
        try:
            f = h5py.File(path, "r")
        except OSError as exc:
            raise DatasetError(f"{path} is not a readable HDF5 file (corrupt?): {exc}") from exc
        try:
            with f:
                return cls._read(f, path)
        except DatasetError:
            raise
        except Exception as exc:  # h5py raises many types on a damaged file's structure
            raise DatasetError(f"{path} is damaged (corrupt HDF5 structure): {exc}") from exc

    @classmethod
    def _read(cls, f: h5py.File, path: Path) -> Dataset:
        """The dataset in the open file `f`, every checksum verified."""
        fmt = f.attrs.get("format")
        if fmt != FORMAT:
            raise DatasetError(f"{path} is not a Pliant condensed dataset (format {fmt!r})")
        version = int(f.attrs.get("format_version", -1))
        if version != FORMAT_VERSION:
            raise DatasetError(
                f"{path} has dataset format version {version}; this Pliant reads version"
                f" {FORMAT_VERSION}"
            )
        stored = f.attrs.get("metadata_sha256")
        metadata = f.attrs.get("metadata", "")
        if stored is not None and stored != hashlib.sha256(str(metadata).encode()).hexdigest():
            raise DatasetError(f"{path}: its metadata fail their checksum (corrupt file)")
        try:
            meta = json.loads(f.attrs["metadata"])
            plan = CollectionPlan.from_dict(meta["plan"])
            layout = Layout.from_dict(meta["layout"])
            version_made = meta["software_version"]
        except (KeyError, TypeError, ValueError, LearnedModelError) as exc:
            raise DatasetError(f"{path} has malformed metadata: {exc}") from exc
        splits = {}
        for name in SPLITS:
            if name not in f:
                raise DatasetError(f"{path} has no '{name}' group")
            missing = [fld.name for fld in fields(Split) if fld.name not in f[name]]
            if missing:
                raise DatasetError(f"{path}: the '{name}' group lacks {missing}")
            splits[name] = Split(
                **{fld.name: _read_checked(f[name], fld.name, path) for fld in fields(Split)}
            )
        dataset = cls(plan, layout, splits["train"], splits["test"], version_made)
        dataset.validate(str(path))
        return dataset

    def validate(self, what: str) -> None:
        """Raise DatasetError unless every field has the plan's rows and the layout's columns
        and the converged samples are finite."""
        rows = self.plan.rows_per_point
        expected_rows = {"train": rows * self.plan.n_train, "test": rows * self.plan.n_test}
        for name in SPLITS:
            split = self.split(name)
            if len(split) != expected_rows[name]:
                raise DatasetError(
                    f"{what}: '{name}' has {len(split)} samples, its plan {expected_rows[name]}"
                )
            for key, width in split.widths(self.plan, self.layout).items():
                shape = getattr(split, key).shape
                if shape != (len(split), width):
                    raise DatasetError(
                        f"{what}: '{name}/{key}' has shape {shape}, expected"
                        f" {(len(split), width)} for this robot's constraint layout"
                    )
            good = split.converged_only()
            if not all(np.all(np.isfinite(getattr(good, f.name))) for f in fields(Split)):
                raise DatasetError(f"{what}: '{name}' has non-finite values in converged samples")
            # Learning runs in float32: a value beyond its range is an infinity there.
            for f in fields(Split):
                values = getattr(good, f.name)
                if values.size and np.max(np.abs(values)) > FLOAT32_MAX:
                    raise DatasetError(
                        f"{what}: '{name}/{f.name}' holds {np.max(np.abs(values)):.3g}, beyond"
                        f" float32's range ({FLOAT32_MAX:.3g}) in which learning runs (corrupt?)"
                    )


def atomic_write(path: Path, write: Callable[[str], object]) -> None:
    """write(tmp) into a temporary file beside `path`, then rename it to `path`: readers see
    the old file or the whole new one, never a part (:func:`pliant.files.atomic_path`)."""
    with atomic_path(path) as tmp:
        write(str(tmp))


def checksum(values: np.ndarray) -> str:
    """SHA-256 of an array's dtype, shape and values (C order)."""
    values = np.ascontiguousarray(values)
    digest = hashlib.sha256(f"{values.dtype.str}{values.shape}".encode())
    digest.update(values.tobytes())
    return digest.hexdigest()


def _read_checked(group: h5py.Group, name: str, path: Path) -> np.ndarray:
    """The values of `group[name]`, their checksums verified (DatasetError naming the part)."""
    where = f"{path}: '{group.name.strip('/')}/{name}'"
    try:
        values = group[name][()]
    except OSError as exc:  # Fletcher-32 mismatch, unreadable chunk
        raise DatasetError(f"{where} is unreadable (corrupt?): {exc}") from exc
    stored = group[name].attrs.get("sha256")
    if stored is not None and stored != checksum(values):
        raise DatasetError(f"{where} fails its checksum: the file is corrupt")
    return values


def verify(path: str | os.PathLike) -> list[str]:
    """Every problem found in the dataset file at `path` (empty: it is sound): each split's
    fields read and checked against their checksums one by one, then the whole validated."""
    path = Path(path)
    try:
        Dataset.load(path)
    except DatasetError as exc:
        first = str(exc)
    else:
        return []
    problems = []
    try:
        with h5py.File(path, "r") as f:
            for name in SPLITS:
                for fld in fields(Split):
                    try:
                        _read_checked(f[name], fld.name, path)
                    except DatasetError as exc:
                        problems.append(str(exc))
                    except Exception as exc:  # a damaged group or a missing dataset
                        problems.append(f"{path}: '{name}/{fld.name}' is unreadable: {exc}")
    except Exception:  # not even the structure reads: the first error says why
        pass
    return problems or [first]
