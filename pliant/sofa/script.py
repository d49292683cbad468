"""A SofaPython3 scene script run into a :class:`pliant.sofa.tree.SceneNode` tree.

The script runs with the SofaPython3 stand-ins (:mod:`pliant.sofa.sofapython3`) and the
STLIB / SPLIB / SoftRobots prefabs (:mod:`pliant.sofa.prefabs`) importable, and its own folder
on the import path and as the working folder (scenes import their local modules and open
their data by relative paths); all of it is removed afterwards. What
goes wrong inside the script is the scene's error: a :class:`SceneError` naming the script's
file and line.
"""

from __future__ import annotations

import copy
import inspect
import os
import re
import runpy
import sys
import traceback
import types
from collections.abc import Mapping
from contextlib import contextmanager
from pathlib import Path

from pliant.sofa.prefabs import prefab_modules
from pliant.sofa.sofapython3 import sofa_modules
from pliant.sofa.tree import SceneError, SceneNode

# Module families Pliant stands in for: an import of one of theirs that Pliant lacks is a
# missing piece of Pliant, not an error of the scene.
FAMILIES = ("Sofa", "SofaRuntime", "stlib3", "splib3", "softrobots", "stlib", "splib", "sofagym")


def read_script(path: Path, config: Mapping | None = None) -> SceneNode:
    """Run the script's ``createScene(rootNode)`` and return the root.

    SofaGym's scenes take ``createScene(rootNode, config)``: they get `config` (a copy, as
    each SofaGym environment gives its scene its own configuration), or, without one, their
    own default configuration, or an empty one where they have none.
    """
    path = path.resolve()  # the script runs in its own folder
    root = SceneNode("root")
    with _stand_ins(path.parent) as own_modules:
        try:
            namespace = runpy.run_path(str(path), run_name="pliant_sofa_scene")
            create = namespace.get("createScene")
            if create is None:
                raise SceneError(f"{path.name} defines no createScene(rootNode)")
            takes_config = len(_positional(create)) >= 2
            if config is not None and not takes_config:
                raise SceneError(
                    f"{path.name}: createScene(rootNode) takes no configuration, one was given"
                )
            if config is not None:
                create(root, copy.deepcopy(dict(config)))
            elif len(_positional(create, required=True)) >= 2:
                create(root, {})
            else:
                create(root)
        except SceneError as exc:  # a prefab's or stand-in's refusal: where the script called
            where = _where(path, exc, message=False)
            raise SceneError(f"{where}{exc}" if where != f"{path.name}: " else str(exc)) from exc
        except ImportError as exc:
            raise _import_error(path, exc) from exc
        except (Exception, SystemExit) as exc:  # a script's sys.exit() ends the scene only
            raise scene_error(path, exc) from exc
    root.modules = own_modules
    return root


def _positional(function, *, required: bool = False) -> list[str]:
    """The positional parameters of `function` (only those without a default: `required`)."""
    return [
        p.name
        for p in inspect.signature(function).parameters.values()
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
        and not (required and p.default is not p.empty)
    ]


def scene_error(path: Path, exc: BaseException, during: str = "createScene") -> SceneError:
    """An exception raised by the scene's own code (its createScene, a controller's event)
    as the scene's error, at the script's line."""
    return SceneError(f"{path.name}: {during} failed at {_where(path, exc)}")


def _import_error(path: Path, exc: ImportError) -> SceneError:
    name = exc.name or ""
    if name.split(".")[0] in FAMILIES or not name:
        what = f"{name!r}" if name else str(exc)
        missing = re.match(r"cannot import name '([^']+)'", str(exc))
        if name and missing:  # the module is Pliant's, the name in it is not
            what = f"{missing.group(1)} from {name!r}"
        return SceneError(
            f"{_where(path, exc, message=False)}imports {what}, which Pliant does not provide"
            " (docs/sofa-reference.md lists the SofaPython3 modules and prefabs it has)"
        )
    return SceneError(_where(path, exc))


def _where(path: Path, exc: BaseException, *, message: bool = True) -> str:
    """Where `exc` happened, as "scene.py, line 12 (in createScene): ValueError: ...": the
    innermost frame in the scene's folder (the script or a module of its own)."""
    folder = path.resolve().parent
    frames = [
        f
        for f in traceback.extract_tb(exc.__traceback__)
        if Path(f.filename).resolve().is_relative_to(folder)
    ]
    at = f"{path.name}"
    if frames:
        frame = frames[-1]
        at = f"{Path(frame.filename).name}, line {frame.lineno} (in {frame.name})"
    if not message:
        return f"{at}: "
    return f"{at}: {type(exc).__name__}: {exc}"


@contextmanager
def _stand_ins(folder: Path):
    """The stand-in modules and the script's folder, for the duration of the load only."""
    modules = {**sofa_modules(), **prefab_modules()}
    # SPLIB's objectmodel imports Sofa and os: ``from splib3.objectmodel import *`` gives them
    modules["splib3.objectmodel"].Sofa = modules["Sofa"]
    modules["splib3.objectmodel"].os = os
    saved = {name: sys.modules.get(name) for name in modules}
    before = set(sys.modules)
    sys.modules.update(modules)
    path = list(sys.path)  # scripts add folders of their own (SofaGym's its parent)
    sys.path.insert(0, str(folder))
    cwd = os.getcwd()
    os.chdir(folder)  # scripts open their data by paths relative to their folder
    own: dict[str, types.ModuleType] = {}  # the script's own modules, filled at the end
    try:
        yield own
    finally:
        os.chdir(cwd)
        sys.path[:] = path
        for name in set(sys.modules) - before:  # the scene's own modules import the stand-ins
            file = getattr(sys.modules[name], "__file__", None)
            if file and Path(file).resolve().is_relative_to(folder):
                own[name] = sys.modules.pop(name)
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = module
