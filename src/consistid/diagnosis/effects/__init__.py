"""The registry of diagnosis effects: every module of this package that defines
``EFFECT = <an Effect instance>`` (see :mod:`consistid.diagnosis.effects.base`), in the order of
their ``order`` attribute. Adding an effect is adding one module here.

``REGISTRY`` maps name → effect; ``EFFECT_NAMES`` lists the names in report order;
:func:`effect` looks one up with a named error; :func:`effects_table` renders the list (name,
model of the residual, signature, sign rules) as a Markdown table for the documentation.
"""

from __future__ import annotations

import importlib
import pkgutil

from ...errors import ModelError, check_option
from .base import Atom, Effect, EffectParameter


def _discover() -> dict[str, Effect]:
    found: list[Effect] = []
    for info in pkgutil.iter_modules(__path__):
        if info.name == "base" or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        eff = getattr(module, "EFFECT", None)
        if not isinstance(eff, Effect):
            continue
        if not eff.name or eff.name != eff.name.lower():
            raise ModelError(f"diagnosis effect module {module.__name__} defines an effect "
                             f"without a lower-case name ({eff.name!r})")
        found.append(eff)
    found.sort(key=lambda e: (e.order, e.name))
    registry: dict[str, Effect] = {}
    for eff in found:
        if eff.name in registry:
            raise ModelError(f"two diagnosis effect modules define the effect {eff.name!r}")
        registry[eff.name] = eff
    return registry


#: Every diagnosis effect by name, in report order.
REGISTRY: dict[str, Effect] = _discover()
#: Effect names in the order reports list them.
EFFECT_NAMES: tuple[str, ...] = tuple(REGISTRY)


def effect(name: str) -> Effect:
    """The registered effect called ``name`` (OptionError naming the known ones otherwise)."""
    check_option("effect", name, EFFECT_NAMES)
    return REGISTRY[name]


def effects_table() -> str:
    """The registry as a Markdown table: name, model of the residual, signature, sign rule."""
    rows = ["| name | model of the residual | signature | physical sign |",
            "| --- | --- | --- | --- |"]
    for e in REGISTRY.values():
        sign = ("parameter ≥ 0" if e.nonnegative == (0,) else
                ", ".join(f"parameter {i + 1} ≥ 0" for i in e.nonnegative) or "either")
        rows.append(f"| `{e.name}` | {e.equation} | {e.signature} | {sign} |")
    return "\n".join(rows)


__all__ = [
    "EFFECT_NAMES",
    "REGISTRY",
    "Atom",
    "Effect",
    "EffectParameter",
    "effect",
    "effects_table",
]
