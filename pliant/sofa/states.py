"""SOFA's ReadState: a deformable body's state read from a file as the scene runs.

The file is what SOFA's WriteState writes: records ``T= time`` followed by ``X= x y z ...``
(the positions) and maybe ``V= ...`` (the velocities). As a step begins at simulation time t,
SOFA reads the records not read yet whose time is at most t + ``shift`` and sets the body's
MechanicalObject from the last of them (positions, and velocities where the record has them);
the others leave the state as it is. With one record at time ``shift`` (SofaGym's TrunkCup) the
first step starts from the recorded state. Pliant does the same in a scene hook
(:class:`pliant.sofa.loader.SofaScene`, ``bindings.hooks``), from the step's time alone: the
records due at a step are those in (t - dt + shift, t + shift], all up to ``shift`` at t = 0,
so a state taken back to time 0 (an environment's reset) starts from the record again.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from pliant.sofa.tree import SceneError

# Times that differ by less than this share of the step are the same (SOFA sums its dt).
TIME_TOLERANCE = 1e-9


@dataclasses.dataclass
class Record:
    time: float
    positions: np.ndarray
    velocities: np.ndarray | None


def read_records(file: Path, n_points: int, where: str) -> list[Record]:
    """The records of a WriteState file for a body of `n_points` nodes, in time order."""
    records: list[Record] = []
    for number, line in enumerate(file.read_text().splitlines(), start=1):
        words = line.split()
        if not words:
            continue
        head, values = words[0], words[1:]
        if head == "T=":
            if len(values) != 1:
                raise SceneError(f"{where}: {file.name}:{number}: 'T=' takes one time")
            records.append(Record(_number(values[0], file, number), np.empty((0, 3)), None))
            continue
        if head not in ("X=", "V="):
            raise SceneError(
                f"{where}: {file.name}:{number}: {head!r} is not a record's line (T=, X=, V=)"
            )
        if not records:
            raise SceneError(f"{where}: {file.name}:{number}: {head} before any 'T='")
        array = np.array([_number(v, file, number) for v in values])
        if array.size != 3 * n_points:
            raise SceneError(
                f"{where}: {file.name}:{number}: {array.size // 3} points where the body has"
                f" {n_points}"
            )
        if head == "X=":
            records[-1].positions = array.reshape(-1, 3)
        else:
            records[-1].velocities = array.reshape(-1, 3)
    if not records:
        raise SceneError(f"{where}: {file.name} holds no record ('T=' lines)")
    for record in records:
        if record.positions.size == 0:
            raise SceneError(f"{where}: {file.name}: the record at T={record.time:g} has no 'X='")
    return sorted(records, key=lambda r: r.time)


def _number(word: str, file: Path, line: int) -> float:
    try:
        value = float(word)
    except ValueError:
        raise SceneError(f"{file.name}:{line}: {word!r} is not a number") from None
    if not np.isfinite(value):
        raise SceneError(f"{file.name}:{line}: {word!r} is not finite")
    return value


@dataclasses.dataclass
class RecordedStates:
    """A scene hook setting the rows `rows` of the state from the records due at each step.

    Attributes:
        records: the file's records, in time order.
        shift: SOFA's ``shift`` (the file's time read at simulation time t is t + shift).
        dt: the scene's time step.
        rows: the body's nodes among the model's.
    """

    records: list[Record]
    shift: float
    dt: float
    rows: slice

    def due(self, time: float) -> Record | None:
        """The record a step beginning at `time` takes, or None."""
        eps = TIME_TOLERANCE * self.dt
        now = time + self.shift + eps
        before = -np.inf if time <= eps else time - self.dt + self.shift + eps
        chosen = [r for r in self.records if before < r.time <= now]
        return chosen[-1] if chosen else None

    def read(self, state):
        record = self.due(state.time)
        if record is None:
            return state
        positions = state.positions.copy()
        positions[self.rows] = record.positions
        changed = {"positions": positions}
        if record.velocities is not None:
            velocities = state.velocities.copy()
            velocities[self.rows] = record.velocities
            changed["velocities"] = velocities
        return dataclasses.replace(state, **changed)

    def write(self, state) -> None:
        """Nothing: the body's data are written with the others'."""
