"""YAML loading that remembers where every value came from, for error messages a user can act on.

Both bench files and procedure files are read through :func:`load_yaml`, which returns plain Python data
plus a :class:`SourceMap` that answers "which line of which file holds the value at this key path?".
Errors are raised as :class:`ConfigError`, whose message always names the file and line, what is wrong
and what is allowed, e.g.::

    benches/sim.yaml:12: site.latitude_deg: expected a number between -90 and 90, got 'north'
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from core.errors import UserError

KeyPath = tuple[str | int, ...]


class ConfigError(UserError, ValueError):
    """A bench or procedure file is wrong; the message names file, line and the fix."""

    def __init__(self, file: str | Path | None, line: int | None, message: str) -> None:
        self.file = str(file) if file is not None else None
        self.line = line
        self.detail = message
        where = self.file or "<input>"
        if line is not None:
            where = f"{where}:{line}"
        super().__init__(f"{where}: {message}")


@dataclass
class SourceMap:
    """Line numbers (1-based) of every mapping key / sequence item, by key path."""

    file: str
    lines: dict[KeyPath, int] = field(default_factory=dict)

    def line(self, path: Sequence[str | int]) -> int | None:
        """Line of the value at ``path``, or of its nearest ancestor that has one."""
        p = tuple(path)
        while p:
            if p in self.lines:
                return self.lines[p]
            p = p[:-1]
        return self.lines.get((), None)

    def error(self, path: Sequence[str | int], message: str) -> ConfigError:
        """A :class:`ConfigError` located at ``path``, with the dotted path in the message."""
        dotted = ".".join(str(k) if isinstance(k, str) else f"[{k}]" for k in path).replace(".[", "[")
        text = f"{dotted}: {message}" if dotted else message
        return ConfigError(self.file, self.line(path), text)


# ---- the one YAML reader for bench and procedure files ------------------------------------------------

MAX_BYTES = 2_000_000
"""Largest bench or procedure file, bytes (the shipped ones are a few kB)."""
MAX_NODES = 50_000
"""Largest number of values (keys, items, scalars) in a file, counting every alias expansion."""
MAX_ALIASES = 100
"""Largest number of alias uses (``*name``) in a file."""
MAX_DEPTH = 64
"""Deepest nesting of mappings and lists."""

_FLOAT_EXP = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")

_BaseLoader: type = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _Loader(_BaseLoader):  # type: ignore[misc, valid-type]
    """Safe YAML loader with one number syntax: ``6e2``, ``1e-4`` are numbers (YAML 1.2), as ``6.0e2`` is."""


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_EXP, list("-+0123456789."))


class _Walk:
    """Record the line of every key / item, reject duplicate keys, and cap aliases, values and depth."""

    def __init__(self, file: str, lines: dict[KeyPath, int]) -> None:
        self.file = file
        self.lines = lines
        self.nodes = 0
        self.aliases = 0
        self.seen: set[int] = set()

    def visit(self, node: yaml.Node, path: KeyPath, depth: int) -> None:
        line = node.start_mark.line + 1
        self.nodes += 1
        if self.nodes > MAX_NODES:
            raise _too_many(self.file, line)
        if depth > MAX_DEPTH:
            raise ConfigError(self.file, line, f"nested more than {MAX_DEPTH} levels deep (or a recursive alias)")
        if isinstance(node, (yaml.MappingNode, yaml.SequenceNode)):
            if id(node) in self.seen:  # the composer hands an alias out as the anchored node itself
                self.aliases += 1
                if self.aliases > MAX_ALIASES:
                    raise ConfigError(
                        self.file,
                        line,
                        f"more than {MAX_ALIASES} alias uses (*name); write the values out or use repeat:",
                    )
            self.seen.add(id(node))
        self.lines.setdefault(path, line)
        if isinstance(node, yaml.MappingNode):
            first: dict[object, int] = {}
            for key_node, value_node in node.value:
                key = key_node.value
                kline = key_node.start_mark.line + 1
                if isinstance(key_node, yaml.ScalarNode) and key != "<<":
                    if key in first:
                        raise ConfigError(
                            self.file,
                            kline,
                            f"duplicate key {key!r} (first on line {first[key]}, again on line {kline}); a key may "
                            "appear only once in a mapping — delete or rename one",
                        )
                    first[key] = kline
                self.lines[path + (key,)] = kline
                self.visit(value_node, path + (key,), depth + 1)
                self.lines[path + (key,)] = kline
        elif isinstance(node, yaml.SequenceNode):
            for i, item in enumerate(node.value):
                self.visit(item, path + (i,), depth + 1)


def _too_many(file: str, line: int | None) -> ConfigError:
    return ConfigError(
        file,
        line,
        f"too many values (more than {MAX_NODES}, counting alias expansions); a bench or procedure file is much "
        "smaller: use repeat: for repetition, not copies or nested aliases",
    )


def _count_events(text: str, file: str) -> None:
    """Refuse a document with more than :data:`MAX_NODES` values before building it (a fast C-level scan)."""
    n = 0
    for event in yaml.parse(text, Loader=_Loader):
        if isinstance(event, (yaml.ScalarEvent, yaml.AliasEvent, yaml.CollectionStartEvent)):
            n += 1
            if n > MAX_NODES:
                raise _too_many(file, event.start_mark.line + 1)


def load_yaml_text(text: str, file: str | Path = "<input>") -> tuple[Any, SourceMap]:
    """Parse YAML ``text``; return (data, source map).

    The one YAML reader of bench and procedure files: safe types only; ``6e2`` / ``1e-4`` are numbers
    (as in YAML 1.2); a duplicate key is an error naming both lines; the file size, the number of values
    (counting alias expansions), alias uses and nesting depth are capped (:data:`MAX_BYTES`,
    :data:`MAX_NODES`, :data:`MAX_ALIASES`, :data:`MAX_DEPTH`), so a hostile file is refused in well under
    a second and a few MB. Every problem is a :class:`ConfigError` naming the file and line.
    """
    smap = SourceMap(str(file))
    size = len(text.encode("utf-8", "surrogatepass")) if len(text) * 4 > MAX_BYTES else len(text)
    if size > MAX_BYTES:
        raise ConfigError(
            file, None, f"is {size / 1e6:.1f} MB; a bench or procedure file may be at most {MAX_BYTES / 1e6:g} MB"
        )
    loader = _Loader(text)
    try:
        _count_events(text, str(file))
        node = loader.get_single_node()
        if node is None:
            return None, smap
        _Walk(str(file), smap.lines).visit(node, (), 0)
        data = loader.construct_document(node)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        problem = exc.problem or str(exc)
        raise ConfigError(file, line, f"YAML syntax error: {problem} (check indentation, colons and quotes)") from None
    except yaml.reader.ReaderError as exc:  # a control character or bad byte: its position → line and column
        pos = min(max(int(exc.position), 0), len(text))
        line = text.count("\n", 0, pos) + 1
        column = pos - (text.rfind("\n", 0, pos) + 1) + 1
        what = f"character #x{exc.character:04x}" if isinstance(exc.character, int) else f"byte {exc.character!r}"
        raise ConfigError(
            file, line, f"column {column}: {what} is not allowed in YAML ({exc.reason}); delete or retype it"
        ) from None
    except yaml.YAMLError as exc:  # pragma: no cover - non-marked errors are rare
        raise ConfigError(file, None, f"YAML error: {exc}") from None
    except RecursionError:
        raise ConfigError(file, None, f"nested more than {MAX_DEPTH} levels deep (or a recursive alias)") from None
    finally:
        loader.dispose()
    return data, smap


def load_yaml(path: str | Path) -> tuple[Any, SourceMap, str]:
    """Read and parse a YAML file; return (data, source map, raw text).

    Raises
    ------
    ConfigError
        If the file cannot be read, is larger than :data:`MAX_BYTES`, is not UTF-8, or is not valid YAML
        (see :func:`load_yaml_text`).
    """
    p = Path(path)
    try:
        size = p.stat().st_size
        if p.is_file() and size > MAX_BYTES:
            raise ConfigError(
                p, None, f"is {size / 1e6:.1f} MB; a bench or procedure file may be at most {MAX_BYTES / 1e6:g} MB"
            )
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(p, None, "file not found (check the path)") from None
    except IsADirectoryError:
        raise ConfigError(p, None, "is a directory, expected a YAML file") from None
    except UnicodeDecodeError:
        raise ConfigError(p, None, "is not UTF-8 text; expected a YAML file") from None
    except OSError as exc:
        raise ConfigError(p, None, f"cannot be read: {exc.strerror}") from None
    data, smap = load_yaml_text(text, p)
    return data, smap, text


# ---- small typed accessors used by both bench and procedure schemas ------------------------------

_MISSING = object()


def get_mapping(data: Any, smap: SourceMap, path: KeyPath) -> dict[str, Any]:
    """Require ``data`` (found at ``path``) to be a mapping."""
    if not isinstance(data, dict):
        raise smap.error(path, f"expected a mapping (key: value lines), got {type(data).__name__}")
    return data


def check_keys(data: dict[str, Any], smap: SourceMap, path: KeyPath, allowed: Sequence[str]) -> None:
    """Reject keys not in ``allowed``, listing what is allowed."""
    for key in data:
        if key not in allowed:
            raise smap.error(path + (str(key),), f"unknown key {key!r}; allowed here: {', '.join(allowed)}")


def get_number(
    data: dict[str, Any],
    smap: SourceMap,
    path: KeyPath,
    key: str,
    default: Any = _MISSING,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    exclusive_minimum: bool = False,
) -> float:
    """Read a finite number at ``data[key]`` with optional bounds; message names the range allowed."""
    if key not in data or data[key] is None:
        if default is _MISSING:
            raise smap.error(path + (key,), "is required (a number)")
        return default
    value = data[key]
    where = path + (key,)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise smap.error(where, f"expected a number, got {value!r}")
    v = float(value)
    if v != v or v in (float("inf"), float("-inf")):
        raise smap.error(where, f"expected a finite number, got {value!r}")
    low_ok = minimum is None or (v > minimum if exclusive_minimum else v >= minimum)
    high_ok = maximum is None or v <= maximum
    if not (low_ok and high_ok):
        lo = "-inf" if minimum is None else f"{minimum:g}"
        hi = "+inf" if maximum is None else f"{maximum:g}"
        bracket = "(" if exclusive_minimum else "["
        raise smap.error(where, f"{v:g} is out of range; allowed {bracket}{lo}, {hi}]")
    return v


def get_str(
    data: dict[str, Any],
    smap: SourceMap,
    path: KeyPath,
    key: str,
    default: Any = _MISSING,
    *,
    choices: Sequence[str] | None = None,
) -> str:
    """Read a string at ``data[key]``, optionally one of ``choices``."""
    if key not in data or data[key] is None:
        if default is _MISSING:
            raise smap.error(path + (key,), "is required (text)")
        return default
    value = data[key]
    if not isinstance(value, str):
        raise smap.error(path + (key,), f"expected text, got {value!r}")
    if choices is not None and value not in choices:
        raise smap.error(path + (key,), f"{value!r} is not allowed; choose one of: {', '.join(choices)}")
    return value


def get_vector(
    data: dict[str, Any], smap: SourceMap, path: KeyPath, key: str, length: int = 3, default: Any = _MISSING
) -> list[float]:
    """Read a list of ``length`` finite numbers at ``data[key]``."""
    if key not in data or data[key] is None:
        if default is _MISSING:
            raise smap.error(path + (key,), f"is required (a list of {length} numbers)")
        return default
    value = data[key]
    if not isinstance(value, list) or len(value) != length:
        raise smap.error(path + (key,), f"expected a list of {length} numbers like [0, 0, 0], got {value!r}")
    out: list[float] = []
    for i, item in enumerate(value):
        if isinstance(item, bool) or not isinstance(item, (int, float)) or item != item:
            raise smap.error(path + (key, i), f"expected a number, got {item!r}")
        out.append(float(item))
    return out


def get_section(data: dict[str, Any], smap: SourceMap, path: KeyPath, key: str, required: bool = True) -> dict | None:
    """The mapping at ``data[key]`` (None if absent and not ``required``)."""
    if key not in data or data[key] is None:
        if required:
            raise smap.error(path + (key,), "is required (a mapping of key: value lines)")
        return None
    return get_mapping(data[key], smap, path + (key,))


def get_components(
    data: dict, smap: SourceMap, path: KeyPath, key: str, si: float, default: Any = None, length: int = 3, **bounds: Any
) -> tuple[float, ...]:
    """A vector in display units (a list, or one number for all components) → SI tuple."""
    if key not in data or data[key] is None:
        if default is None:
            raise smap.error(path + (key,), f"is required (a list of {length} numbers, or one number for all)")
        return tuple(default)
    v = data[key]
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        vals = [get_number(data, smap, path, key, **bounds)] * length
    else:
        vals = get_vector(data, smap, path, key, length)
        lo, hi = bounds.get("minimum"), bounds.get("maximum")
        open_lo = bool(bounds.get("exclusive_minimum"))
        for i, x in enumerate(vals):
            below = lo is not None and (x <= lo if open_lo else x < lo)
            if below or (hi is not None and x > hi):
                bracket = "(" if open_lo else "["
                lo_txt = "-inf" if lo is None else f"{lo:g}"
                hi_txt = "+inf" if hi is None else f"{hi:g}"
                raise smap.error(path + (key, i), f"{x:g} is out of range; allowed {bracket}{lo_txt}, {hi_txt}]")
    return tuple(x * si for x in vals)


def get_matrix(data: dict, smap: SourceMap, path: KeyPath, key: str, si: float, default: Any) -> tuple:
    """A 3×3 matrix in display units (three rows) → SI tuple of rows; ``default`` if absent."""
    if key not in data or data[key] is None:
        return default
    v = data[key]
    where = path + (key,)
    if not isinstance(v, list) or len(v) != 3:
        raise smap.error(where, f"expected a 3×3 matrix as three rows [[a, b, c], [d, e, f], [g, h, i]], got {v!r}")
    rows = []
    for i, row in enumerate(v):
        if not isinstance(row, list):
            raise smap.error(where + (i,), f"expected a row of 3 numbers, got {row!r}")
        rows.append(tuple(x * si for x in get_vector({"row": row}, smap, where + (i,), "row", 3)))
    return tuple(rows)


def get_int(data: dict, smap: SourceMap, path: KeyPath, key: str, default: int, minimum: int, maximum: int) -> int:
    """A whole number in [minimum, maximum]."""
    v = get_number(data, smap, path, key, default, minimum=minimum, maximum=maximum)
    if v != int(v):
        raise smap.error(path + (key,), f"expected a whole number, got {data[key]!r}")
    return int(v)


def get_list_of_maps(d: dict, smap: SourceMap, p: KeyPath, key: str) -> list[tuple[KeyPath, dict]]:
    """The list of mappings at ``d[key]`` with their key paths (empty if absent)."""
    v = d.get(key)
    if v is None:
        return []
    if not isinstance(v, list):
        raise smap.error(p + (key,), f"expected a list of mappings (lines starting with '- '), got {v!r}")
    return [(p + (key, i), get_mapping(item, smap, p + (key, i))) for i, item in enumerate(v)]
