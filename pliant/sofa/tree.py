"""A SOFA scene as a plain tree of nodes and components, read from a ``.scn`` XML file or a
SofaPython3 script.

The tree holds what the scene says, nothing more: each component's type and its attributes
as written (strings from XML, Python values from a script). :mod:`pliant.sofa.loader` turns
it into a Pliant model.
"""

from __future__ import annotations

import runpy
import sys
import types
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pliant.errors import ModelError


class SceneError(ModelError):
    """A SOFA scene cannot be read or holds what Pliant cannot simulate."""


@dataclass
class SceneObject:
    """One component: its SOFA type and attributes (``name`` among them)."""

    type: str
    attrs: dict[str, Any]
    node: SceneNode = field(repr=False)

    @property
    def name(self) -> str:
        return str(self.attrs.get("name", self.type))

    @property
    def path(self) -> str:
        return f"{self.node.path}/{self.name}"

    def __getattr__(self, key: str):
        # Scripts read data back (``loader.position``): give the attribute when it was set.
        attrs = self.__dict__.get("attrs", {})
        if key in attrs:
            return attrs[key]
        raise AttributeError(key)


@dataclass
class SceneNode:
    """A node: its attributes, components in order, and child nodes.

    Offers the SofaPython3 calls scene scripts use to build it: ``addChild`` /
    ``createChild``, ``addObject`` / ``createObject``, and attribute assignment (``root.dt``).
    """

    name: str
    attrs: dict[str, Any] = field(default_factory=dict)
    objects: list[SceneObject] = field(default_factory=list)
    children: list[SceneNode] = field(default_factory=list)
    parent: SceneNode | None = field(default=None, repr=False)

    @property
    def path(self) -> str:
        return self.name if self.parent is None else f"{self.parent.path}/{self.name}"

    def addChild(self, name: str, **attrs) -> SceneNode:  # noqa: N802 (SofaPython3's API)
        child = SceneNode(str(name), dict(attrs), parent=self)
        self.children.append(child)
        return child

    createChild = addChild  # noqa: N815 (SofaPython 2's name)

    def addObject(self, type_name: str, **attrs) -> SceneObject:  # noqa: N802
        obj = SceneObject(str(type_name), dict(attrs), self)
        self.objects.append(obj)
        return obj

    createObject = addObject  # noqa: N815

    def __setattr__(self, key: str, value) -> None:
        if key in SceneNode.__dataclass_fields__:
            object.__setattr__(self, key, value)
        else:  # root.dt = 0.01, root.gravity = [...]
            self.attrs[key] = value

    def __getattr__(self, key: str):
        for child in self.__dict__.get("children", []):
            if child.name == key:
                return child
        for obj in self.__dict__.get("objects", []):
            if obj.name == key:
                return obj
        attrs = self.__dict__.get("attrs", {})
        if key in attrs:
            return attrs[key]
        raise AttributeError(key)

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


def read_scene(path: str | Path) -> SceneNode:
    """Read a ``.scn`` / ``.xml`` scene or a ``.py`` scene script (its ``createScene(root)``)."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"scene file {str(path)!r} does not exist")
    if path.suffix == ".py":
        return _read_script(path)
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


def _read_script(path: Path) -> SceneNode:
    """Run the script with stand-ins for the ``Sofa`` modules and call its createScene."""
    stubs = {}
    for name in ("Sofa", "Sofa.Core", "Sofa.Simulation", "SofaRuntime", "Sofa.Gui"):
        module = types.ModuleType(name)
        module.Node = SceneNode  # type: ignore[attr-defined]
        module.importPlugin = lambda *_a, **_k: None  # type: ignore[attr-defined]
        stubs[name] = module
    stubs["Sofa"].Core = stubs["Sofa.Core"]  # type: ignore[attr-defined]
    stubs["Sofa"].Simulation = stubs["Sofa.Simulation"]  # type: ignore[attr-defined]
    saved = {name: sys.modules.get(name) for name in stubs}
    sys.modules.update(stubs)
    try:
        namespace = runpy.run_path(str(path), run_name="pliant_sofa_scene")
        create = namespace.get("createScene")
        if create is None:
            raise SceneError(f"{str(path)!r} defines no createScene(rootNode)")
        root = SceneNode("root")
        create(root)
    except ImportError as exc:
        raise SceneError(
            f"{str(path)!r} imports {exc.name!r}, which Pliant does not provide: scene scripts"
            " may use addChild / addObject on the root node only (no SOFA prefabs such as"
            " stlib3)"
        ) from exc
    finally:
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = module
    return root
