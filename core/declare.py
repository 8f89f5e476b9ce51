"""Declarative configuration: a YAML section as a list of field declarations, read into a frozen dataclass.

A section (the bench's ``turntable``, a procedure step, the simulator's ``table``) is declared once as its
fields — key, SI unit factor, default, range, choices — and :meth:`Section.read` checks the keys and reads
every field with the same accessors and messages as hand-written parsing (:mod:`core.yaml_source`: one
line naming file:line, the key path, what is wrong and what is allowed)::

    TABLE = Section(
        number("overshoot_arcsec", 5.0, unit=ARCSEC, minimum=0, attr="overshoot"),
        integer("encoder_bits", 24, 0, 40),
        text("transport", "in-process", choices=["in-process", "loopback"]),
    )
    values = TABLE.read(section, smap, ("simulation", "table"))      # {"overshoot": 2.4e-5, ...} (SI)
    model = TABLE.build(TableModel, section, smap, path, limits=...)  # TableModel(**values, limits=...)

Defaults that depend on the context (another section's value) are given to ``read``/``build`` as
``defaults={"attr": value}``. A reader other than :class:`CoreReader` formats the messages its own way
(the procedure loader names the step).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

from .yaml_source import (
    _MISSING,
    KeyPath,
    SourceMap,
    check_keys,
    get_components,
    get_int,
    get_matrix,
    get_number,
    get_str,
)

REQUIRED: Any = object()
"""The default of a field that must be given."""

T = TypeVar("T")


@dataclass(frozen=True)
class Field:
    """One key of a section.

    Attributes
    ----------
    key : str
        The YAML key.
    kind : {"number", "integer", "text", "components", "matrix", "flag"}
        How the value is read.
    attr : str
        The dataclass attribute it fills (default: ``key``).
    unit : float
        SI per YAML unit (numbers, components and matrices are multiplied by it).
    default : Any
        Value when absent (in SI; :data:`REQUIRED` if it must be given). ``None`` is a valid default.
    minimum, maximum : float or None
        Allowed range in YAML units; ``exclusive_minimum`` makes the lower bound strict.
    choices : sequence of str or None
        Allowed texts.
    length : int
        Components of a vector.
    what : str
        How the value is described in messages of readers that say it (procedure steps).
    """

    key: str
    kind: str
    attr: str = ""
    unit: float = 1.0
    default: Any = REQUIRED
    minimum: float | None = None
    maximum: float | None = None
    exclusive_minimum: bool = False
    choices: tuple[str, ...] | None = None
    length: int = 3
    what: str = ""

    @property
    def name(self) -> str:
        """The attribute it fills."""
        return self.attr or self.key


def number(
    key: str,
    default: Any = REQUIRED,
    *,
    unit: float = 1.0,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive_minimum: bool = False,
    attr: str = "",
    what: str = "",
) -> Field:
    """A finite number (× ``unit`` to SI; ``default`` is SI)."""
    return Field(key, "number", attr, unit, default, minimum, maximum, exclusive_minimum, what=what)


def integer(key: str, default: Any, minimum: int, maximum: int, *, attr: str = "", what: str = "") -> Field:
    """A whole number in [minimum, maximum]."""
    return Field(key, "integer", attr, 1.0, default, minimum, maximum, what=what)


def text(key: str, default: Any = REQUIRED, *, choices: Sequence[str] | None = None, attr: str = "") -> Field:
    """A string, optionally one of ``choices``."""
    return Field(key, "text", attr, default=default, choices=None if choices is None else tuple(choices))


def components(
    key: str, unit: float, default: Any = REQUIRED, *, length: int = 3, minimum: float | None = None, attr: str = ""
) -> Field:
    """A vector of ``length`` numbers (or one number for all) × ``unit``; ``default`` is an SI tuple."""
    return Field(key, "components", attr, unit, default, minimum, length=length)


def matrix(key: str, unit: float, default: Any, *, attr: str = "") -> Field:
    """A 3×3 matrix as three rows × ``unit``; ``default`` is an SI tuple of rows."""
    return Field(key, "matrix", attr, unit, default)


def flag(key: str, default: bool = False, *, attr: str = "") -> Field:
    """true or false."""
    return Field(key, "flag", attr, default=default)


class Reader(Protocol):
    """Reads one declared field of a mapping (the messages are the reader's)."""

    def read(self, f: Field, d: Mapping[str, Any], smap: SourceMap, path: KeyPath, default: Any) -> Any:
        """The field's value in SI (``default`` when absent, already SI; raise if required and absent)."""
        ...

    def check_keys(self, d: Mapping[str, Any], smap: SourceMap, path: KeyPath, allowed: Sequence[str]) -> None:
        """Refuse a key not in ``allowed``, listing what is allowed."""
        ...


class CoreReader:
    """The bench file's reader: :mod:`core.yaml_source`'s accessors and messages."""

    def check_keys(self, d: Mapping[str, Any], smap: SourceMap, path: KeyPath, allowed: Sequence[str]) -> None:
        check_keys(dict(d), smap, path, allowed)

    def read(self, f: Field, d: Mapping[str, Any], smap: SourceMap, path: KeyPath, default: Any) -> Any:
        data = dict(d)
        if f.kind == "number":
            if default is not REQUIRED and (f.key not in data or data[f.key] is None):
                return default
            bounds = {"minimum": f.minimum, "maximum": f.maximum, "exclusive_minimum": f.exclusive_minimum}
            return get_number(data, smap, path, f.key, **bounds) * f.unit
        if f.kind == "integer":
            dflt = _MISSING if default is REQUIRED else default
            return get_int(data, smap, path, f.key, dflt, int(f.minimum or 0), int(f.maximum or 0))
        if f.kind == "text":
            return get_str(data, smap, path, f.key, _MISSING if default is REQUIRED else default, choices=f.choices)
        if f.kind == "components":
            bounds = {} if f.minimum is None else {"minimum": f.minimum}
            return get_components(data, smap, path, f.key, f.unit, None if default is REQUIRED else default,
                                  length=f.length, **bounds)  # fmt: skip
        if f.kind == "matrix":
            return get_matrix(data, smap, path, f.key, f.unit, default)
        if f.kind == "flag":
            v = data.get(f.key, default)
            if not isinstance(v, bool):
                raise smap.error(path + (f.key,), f"expected true or false, got {v!r}")
            return v
        raise ValueError(f"field {f.key!r}: unknown kind {f.kind!r}")


CORE = CoreReader()


@dataclass(frozen=True)
class Section:
    """A section's declared fields, in the order its keys are listed in messages.

    ``extra`` names keys the section also allows but which are read by hand (a sub-section, a key whose
    meaning depends on another); they are listed in the allowed keys at their position in ``order``.
    """

    fields: tuple[Field, ...]
    extra: tuple[str, ...] = ()
    order: tuple[str, ...] = ()
    reader: Reader = field(default=CORE, compare=False, repr=False)

    def __init__(self, *fields: Field, extra: Sequence[str] = (), order: Sequence[str] = (),
                 reader: Reader = CORE) -> None:  # fmt: skip
        object.__setattr__(self, "fields", tuple(fields))
        object.__setattr__(self, "extra", tuple(extra))
        object.__setattr__(self, "order", tuple(order))
        object.__setattr__(self, "reader", reader)

    def keys(self) -> list[str]:
        """The allowed keys: ``order`` if given, else the fields' keys followed by ``extra``."""
        if self.order:
            return list(self.order)
        return [f.key for f in self.fields] + list(self.extra)

    def field(self, key: str) -> Field:
        """The declaration of ``key``."""
        return next(f for f in self.fields if f.key == key)

    def read(
        self,
        d: Mapping[str, Any] | None,
        smap: SourceMap,
        path: KeyPath,
        defaults: Mapping[str, Any] | None = None,
        *,
        check: bool = True,
        reader: Reader | None = None,
    ) -> dict[str, Any]:
        """Check the keys of ``d`` (absent: empty) and read every field: attribute → value (SI). ``reader``
        replaces the section's own for this call (messages that name the caller's context)."""
        d = d or {}
        r = reader or self.reader
        if check:
            r.check_keys(d, smap, path, self.keys())
        given = defaults or {}
        return {f.name: r.read(f, d, smap, path, given.get(f.name, f.default)) for f in self.fields}

    def build(
        self,
        cls: type[T],
        d: Mapping[str, Any] | None,
        smap: SourceMap,
        path: KeyPath,
        defaults: Mapping[str, Any] | None = None,
        **given: Any,
    ) -> T:
        """``cls(**read(...), **given)``: the frozen dataclass of the section."""
        return cls(**self.read(d, smap, path, defaults), **given)


__all__ = [
    "CORE",
    "REQUIRED",
    "CoreReader",
    "Field",
    "Reader",
    "Section",
    "components",
    "flag",
    "integer",
    "matrix",
    "number",
    "text",
]
