"""Stand-ins for SofaPython3's modules (``Sofa``, ``Sofa.Core``, ``Sofa.Simulation``,
``Sofa.constants``, ``SofaRuntime``, ``Sofa.Gui``), installed in ``sys.modules`` only while
Pliant runs a scene script (:func:`pliant.sofa.script.read_script`).

A scene's nodes and components are :class:`pliant.sofa.tree.SceneNode` and
:class:`pliant.sofa.tree.SceneObject`; this module adds what scripts subclass or call:
:class:`Controller` (its ``onAnimateBeginEvent`` / ``onAnimateEndEvent`` are called around
each step by :class:`pliant.sofa.loader.SofaScene`; key and mouse events are accepted and
never fired), :class:`Prefab`, the key codes, the message functions and the simulation calls
a script makes at import (no-ops: Pliant builds and steps the scene itself).
"""

from __future__ import annotations

import types
from typing import Any

from pliant.sofa.tree import Name, SceneAttributeError, SceneNode


class Controller:
    """``Sofa.Core.Controller``: a Python component whose event methods Pliant calls.

    ``onAnimateBeginEvent(event)`` runs before each step, ``onAnimateEndEvent(event)`` after
    it; ``event`` is a dict with ``type``, ``dt`` and ``time``. Between them a controller
    reads and writes data fields: actuator ``value``, an effector's ``effectorGoal``, a
    MechanicalObject's ``position``.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.name = Name(kwargs.get("name", type(self).__name__))
        self.listening = True

    def getContext(self) -> SceneNode | None:  # noqa: N802 (SofaPython3's API)
        return self.__dict__.get("_sofa_node")

    getOwner = getContext  # noqa: N815

    def getName(self) -> str:  # noqa: N802
        return str(self.name)

    def init(self) -> None:
        """Called by SOFA when the graph is initialised; Pliant builds the model then."""

    reinit = bwdInit = init  # noqa: N815


class Prefab(SceneNode):
    """``Sofa.Prefab``: a node built by its ``init()`` from ``prefabParameters`` (a list of
    ``{"name", "type", "help", "default"}``), which become the node's data; ``init()`` runs
    when the prefab is created."""

    prefabParameters: list[dict] = []  # noqa: RUF012 (SofaPython3's class attribute)
    prefabData: list[dict] = []  # noqa: RUF012

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        name = kwargs.pop("name", args[0] if args and isinstance(args[0], str) else None)
        SceneNode.__init__(self, Name(name or type(self).__name__))
        parent = kwargs.pop("parent", None) or kwargs.pop("attachedTo", None)
        for parameter in [*self.prefabParameters, *self.prefabData]:
            self.attrs[parameter["name"]] = kwargs.pop(parameter["name"], parameter.get("default"))
        self.attrs.update(kwargs)
        if parent is not None:
            parent.addChild(self)
        self.init()

    def init(self) -> None:
        """Builds the prefab's components (subclasses)."""


class Key:
    """SOFA's key codes (``Sofa.constants.Key``): letters and digits are their characters'
    codes, the arrows SOFA's own. Key events are never fired in Pliant."""

    leftarrow, uparrow, rightarrow, downarrow = 18, 19, 20, 21
    space, plus, minus, escape, enter, backspace, tab = 32, 43, 45, 27, 13, 8, 9
    pageup, pagedown, home, end, delete, insert = 22, 23, 16, 17, 127, 26


for _code in [*range(ord("A"), ord("Z") + 1), *range(ord("0"), ord("9") + 1)]:
    setattr(Key, chr(_code), _code)
for _digit in range(10):
    setattr(Key, f"KP_{_digit}", ord(str(_digit)))


def _message(*_args: Any, **_kwargs: Any) -> None:
    """SOFA's msg_info / msg_warning / msg_error: the scene's own log, not Pliant's."""


def _no_op(*_args: Any, **_kwargs: Any) -> None:
    """A call that SOFA needs and Pliant does not (plugins, graph initialisation, GUI)."""


class _Module(types.ModuleType):
    """A stand-in module: what it lacks is named as Pliant's, not a bare AttributeError."""

    def __getattr__(self, key: str):
        if key.startswith("__"):
            raise AttributeError(key)
        raise SceneAttributeError(f"{self.__name__}.{key} is not provided by Pliant")


def module(name: str, members: dict[str, Any]) -> types.ModuleType:
    """A stand-in module called `name` holding `members` (a package: submodules attach)."""
    made = _Module(name)
    made.__path__ = []  # type: ignore[attr-defined] (a package, so submodules import)
    for key, value in members.items():
        setattr(made, key, value)
    return made


class _Repository:
    addFirstPath = addLastPath = removePath = staticmethod(_no_op)  # noqa: N815


MESSAGES = {
    name: _message
    for name in ("msg_info", "msg_warning", "msg_error", "msg_deprecated", "msg_fatal")
}


def sofa_modules() -> dict[str, types.ModuleType]:
    """The SofaPython3 modules by name, fresh for one scene."""
    key = module("Sofa.constants.Key", {k: v for k, v in vars(Key).items() if k[0] != "_"})
    core = {
        "Node": SceneNode,
        "Controller": Controller,
        "Prefab": Prefab,
        "RawPrefab": Prefab,
    }
    simulation = {
        "init": _no_op,
        "initRoot": _no_op,
        "initVisual": _no_op,
        "animate": _no_op,
        "reset": _no_op,
        "unload": _no_op,
        "updateVisual": _no_op,
    }
    gui = types.SimpleNamespace(
        **{
            k: _no_op
            for k in ("Init", "createGUI", "SetDimension", "MainLoop", "closeGUI", "addGUI")
        }
    )
    modules = {
        "Sofa": module(
            "Sofa", {"Prefab": Prefab, "Node": SceneNode, **MESSAGES, "importPlugin": _no_op}
        ),
        "Sofa.Core": module("Sofa.Core", core),
        "Sofa.Simulation": module("Sofa.Simulation", simulation),
        "Sofa.Helper": module("Sofa.Helper", dict(MESSAGES)),
        "Sofa.constants": module("Sofa.constants", {"Key": key}),
        "Sofa.constants.Key": key,
        "Sofa.Gui": module("Sofa.Gui", {"GUIManager": gui}),
        "Sofa.Components": module("Sofa.Components", {}),
        "SofaRuntime": module(
            "SofaRuntime",
            {
                "importPlugin": _no_op,
                "PluginRepository": _Repository(),
                "DataRepository": _Repository(),
                "Input": _no_op,
            },
        ),
    }
    for name, made in modules.items():
        parent, _, leaf = name.rpartition(".")
        if parent:
            setattr(modules[parent], leaf, made)
    return modules
