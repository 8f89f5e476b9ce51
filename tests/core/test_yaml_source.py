"""The one YAML reader of bench and procedure files: duplicate keys, alias bombs, huge files, number syntax."""

from __future__ import annotations

import tracemalloc

import pytest

from benches.bench_config import load_bench_text
from core.yaml_source import MAX_ALIASES, MAX_BYTES, MAX_NODES, ConfigError, load_yaml, load_yaml_text
from procedures.loader import load_procedure_text
from tests import REPO_ROOT

_PEAK_LIMIT = 5_000_000  # bytes of Python allocations while refusing a hostile file ("a few MB")


def _refused(text: str, file: str = "hostile.yaml") -> tuple[ConfigError, int]:
    tracemalloc.start()
    try:
        with pytest.raises(ConfigError) as info:
            load_yaml_text(text, file)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return info.value, peak


def test_duplicate_key_names_both_lines() -> None:
    text = "name: x\nsteps:\n  - hold:\n      duration_s: 10\n      settle_s: 1\n      duration_s: 20000\n"
    err, _ = _refused(text, "p.yaml")
    assert err.line == 6
    assert "duplicate key 'duration_s'" in str(err)
    assert "line 4" in str(err) and "line 6" in str(err)
    assert str(err).startswith("p.yaml:6:")


def test_duplicate_top_level_key_in_a_procedure() -> None:
    text = "name: a\nname: b\nsteps:\n  - note: hi\n"
    with pytest.raises(ConfigError, match=r"<procedure>:2: duplicate key 'name' \(first on line 1"):
        load_procedure_text(text)


def test_same_key_in_different_mappings_is_fine() -> None:
    data, smap = load_yaml_text("a: {k: 1}\nb: {k: 2}\n")
    assert data == {"a": {"k": 1}, "b": {"k": 2}}
    assert smap.line(("b", "k")) == 2


def test_ten_line_alias_bomb_is_refused_small() -> None:
    lines = ['a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, 10):
        prev, cur = chr(96 + i), chr(97 + i)
        lines.append(f"{cur}: &{cur} [" + ", ".join([f"*{prev}"] * 9) + "]")
    text = "\n".join(lines) + "\n"
    assert len(lines) == 10
    err, peak = _refused(text)
    assert "alias" in str(err)
    assert peak < _PEAK_LIMIT


def test_alias_bomb_under_the_alias_cap_is_refused_by_the_value_cap() -> None:
    # 6 levels × 10 aliases = 60 alias uses (< MAX_ALIASES) expanding to 10⁶ values (> MAX_NODES)
    lines = ["a0: &a0 [" + ", ".join(["x"] * 10) + "]"]
    for i in range(1, 7):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]")
    assert 6 * 10 < MAX_ALIASES and 10**6 > MAX_NODES
    err, peak = _refused("\n".join(lines) + "\n")
    assert "too many values" in str(err) or "alias" in str(err)
    assert peak < _PEAK_LIMIT


def test_recursive_alias_is_refused() -> None:
    err, _ = _refused("a: &a [1, *a]\n")
    assert "recursive alias" in str(err) or "nested" in str(err)


def test_huge_file_is_refused_from_its_size(tmp_path) -> None:
    p = tmp_path / "huge.yaml"
    step = "  - hold: {duration_s: 1}\n"
    with p.open("w") as f:
        f.write("name: huge\nsteps:\n")
        f.write(step * 2_000_000)  # ≈ 50 MB, 2 M steps
    tracemalloc.start()
    try:
        with pytest.raises(ConfigError, match=r"huge\.yaml: is 5\d\.\d MB; .* at most"):
            load_yaml(p)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < _PEAK_LIMIT


def test_many_steps_under_the_size_limit_are_refused_by_count() -> None:
    text = "name: many\nsteps:\n" + "  - hold: {duration_s: 1}\n" * 60_000
    assert len(text) < MAX_BYTES
    err, peak = _refused(text)
    assert "too many values" in str(err) and err.line is not None
    assert peak < _PEAK_LIMIT


def test_deep_nesting_is_refused() -> None:
    err, _ = _refused("a: " + "[" * 200 + "]" * 200 + "\n")
    assert "nested" in str(err)


@pytest.mark.parametrize(
    ("text", "value"),
    [("v: 6e2", 600.0), ("v: 1e2", 100.0), ("v: 1e-4", 1e-4), ("v: -1.5E+3", -1500.0), ("v: 2.5e1", 25.0)],
)
def test_exponent_numbers_without_a_dot_are_numbers(text: str, value: float) -> None:
    data, _ = load_yaml_text(text + "\n")
    assert data["v"] == value and isinstance(data["v"], float)


def test_quoted_exponent_stays_text() -> None:
    data, _ = load_yaml_text("v: '1e2'\n")
    assert data["v"] == "1e2"


def test_procedures_accept_exponent_numbers_like_bench_files() -> None:
    proc = load_procedure_text("name: p\nsteps:\n  - warmup: {duration_s: 6e2}\n  - hold: {duration_s: 1e2}\n")
    assert proc.steps[0].duration == 600.0  # type: ignore[attr-defined]
    assert proc.steps[1].duration == 100.0  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    "body",
    [
        "  - hold: {duration_s: 1e300}",
        "  - warmup: {duration_s: 1e300}",
        "  - spin: {axis: z, rate_dps: 1e300, revolutions: 1}",
        "  - spin: {axis: z, rate_dps: 10, revolutions: 1e300}",
        "  - hold: {duration_s: 1, settle_s: 1e300}",
    ],
)
def test_absurd_numbers_in_procedures_are_refused_by_range(body: str) -> None:
    with pytest.raises(ConfigError, match=r"<procedure>:3: .*not allowed; must be"):
        load_procedure_text("name: p\nsteps:\n" + body + "\n")


def test_absurd_parameter_default_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"parameters\.d: expected a finite number"):
        load_procedure_text("name: p\nparameters: {d: .inf}\nsteps:\n  - hold: {duration_s: $d}\n")


def test_bench_files_use_the_same_loader() -> None:
    text = (REPO_ROOT / "benches" / "sim.yaml").read_text(encoding="utf-8")
    bench = load_bench_text(text, "sim.yaml")
    assert bench.name
    lines = text.splitlines()
    first = next(i for i, ln in enumerate(lines) if ln and not ln.startswith((" ", "#")))
    dup = "\n".join(lines[: first + 1] + [lines[first]] + lines[first + 1 :]) + "\n"
    with pytest.raises(ConfigError, match=rf"sim\.yaml:{first + 2}: duplicate key .*line {first + 1}"):
        load_bench_text(dup, "sim.yaml")
