"""A SOFA scene as a plain tree of nodes and components, read from a ``.scn`` XML file or a
SofaPython3 script.

The tree holds what the scene says, nothing more: each component's type and its attributes
as written (strings from XML, Python values from a script). :mod:`pliant.sofa.loader` turns
it into a Pliant model.
"""

from __future__ import annotations

import difflib
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pliant.errors import ModelError


class SceneError(ModelError):
    """A SOFA scene cannot be read or holds what Pliant cannot simulate."""


class SceneAttributeError(AttributeError):
    """A scene script reads a child, component or data field that is not there (SofaPython3
    raises AttributeError too; :func:`pliant.sofa.script.read_script` reports it as the
    scene's error, at the script's line)."""


class Name(str):
    """A node's or component's name: a string that also answers SofaPython3's ``.value``,
    which renames its owner when set (``obj.name.value = "new"``)."""

    _rename = None

    def __reduce__(self):  # copied or pickled as the plain name
        return Name, (str(self),)

    @property
    def value(self) -> str:
        return str(self)

    @value.setter
    def value(self, new: str) -> None:
        if self._rename is None:
            raise AttributeError(f"{self!r} names nothing that can be renamed")
        self._rename(str(new))


def _owned(name: str, rename) -> Name:
    owned = Name(name)
    owned._rename = rename
    return owned


def data_value(raw):
    """A data field as SofaPython3 reads it: numbers as a float (one value) or a read-only
    array (several), text as text, anything else as it was set."""
    if isinstance(raw, str):
        parts = raw.replace(",", " ").split()
        if not parts:
            return raw
        try:
            numbers = [float(p) for p in parts]
        except ValueError:
            return raw
        if len(numbers) == 1:
            return numbers[0]
        raw = numbers
    if isinstance(raw, (list, tuple, np.ndarray)) and not isinstance(raw, Name):
        try:
            array = np.array(raw, dtype=float)
        except (TypeError, ValueError):
            return raw
        array.flags.writeable = False
        return array
    return raw


def field_numbers(obj: SceneObject, key: str, default) -> np.ndarray:
    """A field's numbers, flat (``data_value`` reads them as SofaPython3 does)."""
    raw = obj.attrs.get(key, default)
    try:
        return np.atleast_1d(np.asarray(data_value(raw), dtype=float)).ravel()
    except (TypeError, ValueError):
        pass
    try:  # nested lists of unequal lengths (a rigid mass as [m, V, [I (9)]]), flattened
        return np.asarray(list(flatten(data_value(raw))), dtype=float)
    except (TypeError, ValueError):
        raise SceneError(f"{obj.path}.{key}: expected numbers, got {raw!r}") from None


def flatten(value):
    """The numbers of a nested sequence (lists, tuples, arrays, mixed as scripts build them)."""
    if isinstance(value, (list, tuple, np.ndarray)):
        for item in value:
            yield from flatten(item)
    else:
        yield value


class Data:
    """One data field of a component or node, as SofaPython3 gives it: ``.value`` to read
    (SofaPython3's arrays are read-only) and to write, ``writeable()`` to edit in place,
    ``getLinkPath()`` for a ``@path.field`` link, and the sequence protocol on the value."""

    def __init__(self, owner: SceneObject | SceneNode, key: str, default=None):
        object.__setattr__(self, "owner", owner)
        object.__setattr__(self, "key", key)
        object.__setattr__(self, "default", default)

    @property
    def value(self):
        raw = self.owner.attrs.get(self.key, self.default)
        if self._unread_state(raw):  # a script reads a state before SOFA would fill it
            self.owner.init()
            raw = self.owner.attrs.get("rest_position", raw)
        value = data_value(raw)
        if not isinstance(value, (np.ndarray, float, int)) or isinstance(value, bool):
            return value
        scalar = isinstance(self.default, (int, float)) and not isinstance(self.default, bool)
        if self.key in ONE_DERIVATIVE.get(getattr(self.owner, "type", ""), ()):
            value = _one_derivative(self.owner, value)
        elif self.key in POINT_FIELDS and not scalar:  # points: (n, 3), or (n, 7) rigid poses
            template = str(self.owner.attrs.get("template", ""))
            width = 7 if template.startswith("Rigid3") else 1 if template.startswith("Vec1") else 3
            if width == 7 and self.key in DERIVATIVES:  # a rigid twist or wrench: 6 values
                width = 6
            value = np.asarray(value, dtype=float).reshape(-1, width)
        elif self.key in INDEX_FIELDS:
            value = np.atleast_1d(value).astype(np.int64)
        elif isinstance(self.default, (list, tuple)):  # a vector field, whatever its length
            value = np.atleast_1d(value)
        else:
            return value
        value.flags.writeable = False
        return value

    @value.setter
    def value(self, value) -> None:
        self.owner.attrs[self.key] = value

    def _unread_state(self, raw) -> bool:
        """A MechanicalObject's positions not given, or linked to a loader's: SOFA fills them
        at init from its mesh (read then, see SceneObject.init)."""
        owner = self.owner
        if self.key not in ("position", "rest_position") or not isinstance(owner, SceneObject):
            return False
        if owner.type != "MechanicalObject":
            return False
        return (isinstance(raw, str) and raw.strip().startswith("@")) or np.size(raw) == 0

    @contextmanager
    def writeable(self):
        value = self.value  # index fields stay integers, as SofaPython3 gives them
        integer = isinstance(value, np.ndarray) and value.dtype.kind in "iu"
        array = np.array(value, dtype=np.int64 if integer else float)
        yield array
        self.owner.attrs[self.key] = array

    def getName(self) -> str:  # noqa: N802 (SofaPython3's API)
        return self.key

    def setParent(self, parent) -> None:  # noqa: N802
        """Links this field to another (a Data or a ``@path.field`` link)."""
        link = parent.getLinkPath() if isinstance(parent, Data) else str(parent)
        self.owner.attrs[self.key] = link

    def getValueString(self) -> str:  # noqa: N802
        value = self.value
        if isinstance(value, np.ndarray):
            return " ".join(f"{v:g}" for v in value.ravel())
        return str(value)

    def getLinkPath(self) -> str:  # noqa: N802
        return f"{self.owner.getLinkPath()}.{self.key}"

    @property
    def linkpath(self) -> str:
        return self.getLinkPath()

    def __getitem__(self, index):
        return self.value[index]

    # Arithmetic on the value (SofaPython3's array data): ``cable.value += 1`` computes the
    # sum and assigns it to the field.
    def __add__(self, other):
        return np.add(self.value, other)

    def __radd__(self, other):
        return np.add(other, self.value)

    def __sub__(self, other):
        return np.subtract(self.value, other)

    def __rsub__(self, other):
        return np.subtract(other, self.value)

    def __mul__(self, other):
        return np.multiply(self.value, other)

    def __rmul__(self, other):
        return np.multiply(other, self.value)

    def __truediv__(self, other):
        return np.divide(self.value, other)

    def __neg__(self):
        return np.negative(self.value)

    @property
    def shape(self) -> tuple[int, ...]:
        """The value's array shape, as SofaPython3's array data give it."""
        return np.shape(self.value)

    @property
    def ndim(self) -> int:
        return len(self.shape)

    def __len__(self) -> int:
        return len(self.value)

    def __iter__(self):
        return iter(self.value)

    def __array__(self, dtype=None, copy=None):
        return np.asarray(self.value, dtype=dtype)

    def __float__(self) -> float:
        return float(self.value)

    def __bool__(self) -> bool:
        return bool(np.any(self.value)) if isinstance(self.value, np.ndarray) else bool(self.value)

    def __str__(self) -> str:
        return self.getValueString()

    def __repr__(self) -> str:
        return f"Data({self.key}={self.value!r})"


# Data fields that hold a vector of points (SofaPython3 gives them as (n, 3) arrays).
POINT_FIELDS = frozenset(
    {"position", "velocity", "rest_position", "force", "externalForce", "free_position",
     "effectorGoal"}
)  # fmt: skip
# Point fields that are derivatives (a Rigid3 point's: velocity and angular velocity, force
# and moment, six values).
DERIVATIVES = frozenset({"velocity", "force", "externalForce"})

# Fields of one derivative of the component's state (a force on each of its points: six
# values, force and moment, on a Rigid3 state), not a vector of points.
ONE_DERIVATIVE = {"ConstantForceField": ("force", "totalForce")}


def _one_derivative(owner, value) -> np.ndarray:
    """`value` as one derivative of the owner's state: (6,) on a Rigid3 MechanicalObject
    (SOFA's default zero where the field gives three), else (3,)."""
    dofs = owner.node.getMechanicalState()
    rigid = dofs is not None and str(dofs.attrs.get("template", "")).startswith("Rigid3")
    out = np.asarray(value, dtype=float).reshape(-1)
    if rigid and out.size == 3 and not out.any():
        out = np.zeros(6)
    out.flags.writeable = False
    return out


# Data fields that hold indices (SofaPython3 gives them as integer arrays).
INDEX_FIELDS = frozenset(
    {"indices", "points", "edges", "triangles", "quads", "tetrahedra", "tetras", "hexahedra"}
)

# SOFA's other names for components (registered aliases: older and case variants).
ALIASES = {
    "MeshObjLoader": "MeshOBJLoader",
    "FreeMotionMasterSolver": "FreeMotionAnimationLoop",  # until SOFA v24.12
    "TTriangleModel": "TriangleCollisionModel",
    "TriangleModel": "TriangleCollisionModel",
    "TLineModel": "LineCollisionModel",
    "LineModel": "LineCollisionModel",
    "TPointModel": "PointCollisionModel",
    "PointModel": "PointCollisionModel",
    "SphereModel": "SphereCollisionModel",
    "SparseGrid": "SparseGridTopology",
    "RegularGrid": "RegularGridTopology",
}

# Data fields every component and node answers with SOFA's defaults, set or not.
OBJECT_DEFAULTS = {"listening": False, "printLog": False, "tags": "", "bbox": ""}
NODE_DEFAULTS = {
    "dt": 0.01,
    "gravity": [0.0, -9.81, 0.0],
    "time": 0.0,
    "animate": False,
    "activated": True,
}


@dataclass(eq=False)
class SceneObject:
    """One component: its SOFA type and attributes (``name`` among them).

    Offers SofaPython3's component API to scripts: data fields as attributes (``obj.position``,
    a :class:`Data`), assignment (``obj.value = [2]``), ``findData`` / ``getData``,
    ``getLinkPath`` and the name. A field read that the component does not hold is a
    :class:`SceneAttributeError`; which fields SOFA gives each type (set or not) is
    :data:`pliant.sofa.components.FIELDS`.
    """

    type: str
    attrs: dict[str, Any]
    node: SceneNode = field(repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "type", ALIASES.get(self.type, self.type))

    @property
    def name(self) -> Name:
        return _owned(self.attrs.get("name", self.type), lambda new: self.attrs.update(name=new))

    @property
    def path(self) -> str:
        return f"{self.node.path}/{self.name}"

    def __setattr__(self, key: str, value) -> None:
        if key in SceneObject.__dataclass_fields__:
            object.__setattr__(self, key, value)
        else:  # SofaPython3: obj.value = [2] sets the data field
            self.attrs[key] = value

    def __getattr__(self, key: str):
        if key.startswith("__") or "attrs" not in self.__dict__:
            raise AttributeError(key)
        data = self.findData(key)
        if data is None:
            raise SceneAttributeError(
                f"{self.path}: a {self.type} has no data field {key!r}"
                + close_match(key, self.attrs.keys() | _fields(self.type))
            )
        return data

    def findData(self, key: str) -> Data | None:  # noqa: N802 (SofaPython3's API)
        from pliant.sofa.components import FIELDS

        defaults = FIELDS.get(self.type, {})
        if key in self.attrs or key in defaults or key in OBJECT_DEFAULTS:
            default = defaults.get(key, OBJECT_DEFAULTS.get(key))
            rigid_force = self.type == "ConstantForceField" and key in ("force", "totalForce")
            if rigid_force and self._on_rigid():  # a Rigid3 force: a force and a moment
                default = [0.0] * 6
            return Data(self, key, default)
        return None

    def _on_rigid(self) -> bool:
        """Whether the component acts on a Rigid3 state (its template, else its node's
        MechanicalObject's)."""
        template = self.attrs.get("template")
        if template is None:
            dofs = next((o for o in self.node.objects if o.type == "MechanicalObject"), None)
            template = None if dofs is None else dofs.attrs.get("template")
        return str(template or "").startswith("Rigid3")

    def getData(self, key: str) -> Data | None:  # noqa: N802
        return self.findData(key)

    def getName(self) -> str:  # noqa: N802
        return str(self.name)

    def getPathName(self) -> str:  # noqa: N802
        return self.node.sofa_path.rstrip("/") + "/" + self.name

    def getLinkPath(self) -> str:  # noqa: N802
        return "@" + self.getPathName()

    @property
    def linkpath(self) -> str:
        return self.getLinkPath()

    def getContext(self) -> SceneNode:  # noqa: N802
        return self.node

    getOwner = getContext  # noqa: N815

    def getClassName(self) -> str:  # noqa: N802
        return self.type

    def init(self) -> None:
        """SOFA initialises components after the scene is built; Pliant reads them then. A
        script that calls ``init()`` itself reads some outputs at once: a MechanicalObject's
        positions from its mesh loader, a ROI's ``indices`` (:data:`INITIALISERS`)."""
        initialise = INITIALISERS.get(self.type)
        if initialise is not None:
            initialise(self)

    reinit = bwdInit = init  # noqa: N815


# What ``init()`` computes for a component type, filled by the loader (which reads meshes):
# a function of the component that sets its output data.
INITIALISERS: dict[str, Any] = {}


def _fields(type_name: str) -> set[str]:
    from pliant.sofa.components import FIELDS

    return set(FIELDS.get(type_name, {})) | set(OBJECT_DEFAULTS)


def close_match(key: str, known, cutoff: float = 0.75) -> str:
    """The hint " (did you mean 'x'?)" for the known name closest to `key`, or empty."""
    close = difflib.get_close_matches(key, sorted(known), n=1, cutoff=cutoff)
    return f" (did you mean {close[0]!r}?)" if close else ""


@dataclass(eq=False)
class SceneNode:
    """A node: its attributes, components in order, and child nodes.

    Offers SofaPython3's Node API to scene scripts: ``addChild`` / ``addObject`` (also their
    SofaPython 2 names ``createChild`` / ``createObject``), ``getChild``, ``getObject``,
    ``getMechanicalState``, ``getRoot``, children and components as attributes, and the
    node's data (``root.dt``, ``root.gravity``) read as :class:`Data` and assigned directly.
    Python controllers (:class:`pliant.sofa.sofapython3.Controller`) added to a node are kept
    apart in ``controllers``.
    """

    name: str
    attrs: dict[str, Any] = field(default_factory=dict)
    objects: list[SceneObject] = field(default_factory=list)
    children: list[SceneNode] = field(default_factory=list)
    parent: SceneNode | None = field(default=None, repr=False)
    controllers: list[Any] = field(default_factory=list, repr=False)
    extras: dict[str, Any] = field(default_factory=dict, repr=False)
    #: the root of a script's scene: the modules of the script's folder that it imported, by
    #: name (out of ``sys.modules`` after the load; SofaGym's toolbox functions are called
    #: on the scene after it is built).
    modules: dict[str, Any] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self.name = Name(self.name)

    @property
    def path(self) -> str:
        return self.name if self.parent is None else f"{self.parent.path}/{self.name}"

    @property
    def sofa_path(self) -> str:
        """SofaPython3's path: "/" for the root, "/Body/cable" below it."""
        return "/" if self.parent is None else f"{self.parent.sofa_path.rstrip('/')}/{self.name}"

    def addChild(self, child: str | SceneNode, **attrs) -> SceneNode:  # noqa: N802 (SofaPython3)
        if isinstance(child, SceneNode):  # a node built apart (Sofa.Core.Node, a prefab)
            if child.parent is not None and child in child.parent.children:
                # SOFA's node then has two parents; Pliant's tree keeps it under the new one
                # and the old one still answers its name.
                child.parent.children.remove(child)
                child.parent.extras[str(child.name)] = child
            child.parent = self
            self.children.append(child)
            return child
        node = SceneNode(Name(child), dict(attrs), parent=self)
        self.children.append(node)
        return node

    createChild = addChild  # noqa: N815 (SofaPython 2's name)

    def addObject(self, type_name, **attrs):  # noqa: N802
        if not isinstance(type_name, str):  # a Python controller
            type_name.__dict__["_sofa_node"] = self
            self.controllers.append(type_name)
            return type_name
        obj = SceneObject(str(type_name), dict(attrs), self)
        self.objects.append(obj)
        return obj

    createObject = addObject  # noqa: N815

    def removeChild(self, child: SceneNode | str) -> None:  # noqa: N802
        self.children = [c for c in self.children if c is not child and c.name != child]

    def removeObject(self, obj) -> None:  # noqa: N802
        self.objects = [o for o in self.objects if o is not obj]
        self.controllers = [c for c in self.controllers if c is not obj]

    def getChild(self, name: str) -> SceneNode | None:  # noqa: N802
        found = next((c for c in self.children if c.name == name), None)
        moved = self.extras.get(name)
        return found if found is not None or not isinstance(moved, SceneNode) else moved

    def getObject(self, name: str):  # noqa: N802
        found = next((o for o in self.objects if o.name == name), None)
        if found is None:
            found = next((c for c in self.controllers if _controller_name(c) == name), None)
        return found

    def hasObject(self, name: str) -> bool:  # noqa: N802
        return self.getObject(name) is not None

    def getMechanicalState(self) -> SceneObject | None:  # noqa: N802
        return next((o for o in self.objects if o.type == "MechanicalObject"), None)

    def getRoot(self) -> SceneNode:  # noqa: N802
        return self if self.parent is None else self.parent.getRoot()

    def getName(self) -> str:  # noqa: N802
        return str(self.name)

    def getPathName(self) -> str:  # noqa: N802
        return self.sofa_path

    def getLinkPath(self) -> str:  # noqa: N802
        return "@" + self.sofa_path

    def getContext(self) -> SceneNode:  # noqa: N802
        return self

    def findData(self, key: str) -> Data | None:  # noqa: N802
        if key in self.attrs or key in NODE_DEFAULTS:
            return Data(self, key, NODE_DEFAULTS.get(key))
        return None

    getData = findData  # noqa: N815

    def addData(self, name: str, value=None, **_info) -> Data:  # noqa: N802
        self.attrs[name] = value if value is not None else _info.get("default")
        return Data(self, name)

    def init(self) -> None:
        """SOFA initialises the graph after the scene is built; Pliant reads it then."""

    def __setattr__(self, key: str, value) -> None:
        if key == "name":
            object.__setattr__(self, key, _owned(value, lambda new: setattr(self, "name", new)))
        elif key in SceneNode.__dataclass_fields__ or key.startswith("_"):
            object.__setattr__(self, key, value)
        elif key in self.attrs or key in NODE_DEFAULTS:  # root.dt = 0.01, root.gravity = [...]
            self.attrs[key] = value
        else:  # a Python attribute of the script's (a prefab's method, handles, lists)
            self.extras[key] = value

    def __getattr__(self, key: str):
        if key.startswith("__") or "children" not in self.__dict__:
            raise AttributeError(key)
        for child in self.__dict__.get("children", []):
            if child.name == key:
                return child
        for obj in self.__dict__.get("objects", []):
            if obj.name == key:
                return obj
        for controller in self.__dict__.get("controllers", []):
            if _controller_name(controller) == key:
                return controller
        if key in self.__dict__.get("extras", {}):
            return self.extras[key]
        data = self.findData(key)
        if data is not None:
            return data
        known = [c.name for c in self.children] + [o.name for o in self.objects]
        raise SceneAttributeError(
            f"{self.path}: no child, component or data field {key!r}" + close_match(key, known)
        )

    def walk(self):
        """This node and its descendants, depth first in scene order."""
        yield self
        for child in self.children:
            yield from child.walk()

    def find(self, name: str) -> SceneObject | None:
        """The component called `name` here or in an ancestor (SOFA's link lookup)."""
        node: SceneNode | None = self
        while node is not None:
            for obj in node.objects:
                if obj.name == name:
                    return obj
            node = node.parent
        return None


def _controller_name(controller) -> str:
    return str(getattr(controller, "name", type(controller).__name__))


def read_scene(path: str | Path, config: Mapping | None = None) -> SceneNode:
    """Read a ``.scn`` / ``.xml`` scene or a ``.py`` scene script (its ``createScene(root)``,
    or ``createScene(root, config)`` with `config`, as SofaGym calls its scenes)."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"scene file {str(path)!r} does not exist")
    if path.suffix == ".py":
        from pliant.sofa.script import read_script

        return read_script(path, config)
    if config is not None:
        raise SceneError(f"{path.name}: a configuration is for a createScene script, not XML")
    try:
        element = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise SceneError(f"cannot parse scene {str(path)!r}: {exc}") from exc
    if element.tag != "Node":
        raise SceneError(f"{str(path)!r}: the root element is <{element.tag}>, not <Node>")
    return _from_xml(element, None)


def _from_xml(element: ET.Element, parent: SceneNode | None) -> SceneNode:
    attrs = dict(element.attrib)
    node = SceneNode(attrs.pop("name", "root"), attrs, parent=parent)
    for child in element:
        if not isinstance(child.tag, str):  # comments
            continue
        if child.tag == "Node":
            node.children.append(_from_xml(child, node))
        else:
            node.objects.append(SceneObject(child.tag, dict(child.attrib), node))
    return node
