"""Every public class, function, method and property of fsm has a docstring of its own, so
help(fsm.Simulation) is useful. pybind11 writes a signature line into every function's __doc__;
only text beyond the signatures counts."""
import importlib
import inspect
import re

import pytest

import fsm

SIGNATURE = re.compile(r"^(\d+\. )?[A-Za-z_][A-Za-z_0-9]*\(.*\)( -> .*)?$")


def own_text(doc):
    """The docstring without pybind11's signature lines and overload headers."""
    lines = [] if doc is None else doc.splitlines()
    return "\n".join(l for l in lines
                     if not SIGNATURE.match(l.strip()) and l.strip() != "Overloaded function."
                     ).strip()


def modules():
    mods = [fsm]
    try:
        mods.append(importlib.import_module("fsm.build"))
    except ImportError:  # the builder module is optional
        pass
    return mods


def public_objects():
    for mod in modules():
        names = getattr(mod, "__all__", [n for n in dir(mod) if not n.startswith("_")])
        for name in names:
            obj = getattr(mod, name)
            if inspect.isclass(obj) or callable(obj):
                yield f"{mod.__name__}.{name}", obj


def members(cls):
    for name, attr in vars(cls).items():
        if name.startswith("_") or (name in ("name", "value") and hasattr(cls, "__members__")):
            continue  # pybind11's own enum properties
        if isinstance(attr, property):
            yield name, attr.__doc__
        elif callable(attr) and not isinstance(attr, cls):  # not enum values
            yield name, getattr(attr, "__doc__", None)


def test_modules_have_docstrings():
    for mod in modules():
        assert own_text(mod.__doc__), mod.__name__


def test_every_public_class_and_function_has_a_docstring():
    missing = [name for name, obj in public_objects() if not own_text(obj.__doc__)]
    assert not missing, "no docstring: " + ", ".join(missing)


def test_every_public_method_and_property_has_a_docstring():
    missing = []
    for name, obj in public_objects():
        if inspect.isclass(obj):
            missing += [f"{name}.{m}" for m, doc in members(obj) if not own_text(doc)]
    assert not missing, "no docstring: " + ", ".join(missing)


def test_the_checker_can_fail():
    assert own_text("step(self: fsm._fsm.Simulation, dt: float) -> StepReport\n") == ""
    assert own_text("Overloaded function.\n\n1. f(x: int) -> None\n\n2. f(x: str) -> None\n") == ""
    assert own_text("f(x: int) -> None\n\nDoes f.\n") == "Does f."


@pytest.mark.parametrize("name", ["Simulation", "ContactSolver", "SphereModel"])
def test_help_is_substantial(name):
    text = inspect.getdoc(getattr(fsm, name))
    assert len(text) > 200
