"""Every CLI command on a corpus of bad inputs: no traceback, exit code 2, the place named.

The commands are discovered from the parser (:func:`benches.cli.build_parser`), so a new command is covered
by the generic cases at once: an unknown option; every positional argument given a missing file, a
directory, an empty file, bad YAML, binary garbage, an HDF5 file that is not a recording and a truncated
recording; every numeric option given text, NaN, ±1e300 and 2⁶⁴; every choice option a bogus choice; every
``--out`` a path that cannot be created; ``--bench``/``--procedure``/``--resume`` bad files. The cases of the
front-door issue follow (seed 2⁶⁴, priors of 1e300 µg, values ~1e296, damaged recordings, ``--channels ""``,
``runs /nonexistent``).

A case that still fails in an area another change owns is marked ``xfail(strict=False)`` with the owner in
the reason (see ``KNOWN``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import shutil
import signal
import traceback
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import pytest

from analysis.units import G0
from benches.cli import build_parser, main
from drivers.imu_unit.description import compile_format, load_frame
from drivers.imu_unit.samples import encode_samples
from tests import REPO_ROOT
from tests.certificate_fixtures import make_run_folder

TIMEOUT_S = 60
"""A bad input must be refused quickly; a case still running after this is reported as a hang."""


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    for action in parser._actions:  # noqa: SLF001 - argparse keeps its sub-parsers here
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            return dict(action.choices)
    raise AssertionError("the CLI has no sub-commands")


COMMANDS = _commands()


def _positionals(p: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in p._actions if not a.option_strings and not isinstance(a, argparse._HelpAction)]  # noqa: SLF001


def _options(p: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in p._actions if a.option_strings and a.nargs != 0 and not isinstance(a, argparse._HelpAction)]  # noqa: SLF001


# ---- the corpus on disk --------------------------------------------------------------------------------------


@dataclass
class Corpus:
    root: Path
    run: Path  # a good (small, fake) run folder: recording.h5 + calibration.json
    npy: Path  # a good 2-column .npy record (use with --rate 100)
    tiny: Path  # a tiny valid procedure (a run that wrongly accepts a bad input stays short)
    capture: Path  # a good raw byte capture of a KVH 1750 (format A) unit
    files: dict[str, Path]  # bad files by kind

    def bad(self, kind: str) -> Path:
        return self.files[kind]


DAMAGED = ("other-version", "bad-rate-attr", "no-steps")
FILE_KINDS = ("missing", "directory", "empty", "bad-yaml", "duplicate-keys", "garbage", "not-recording", "truncated")


@pytest.fixture(scope="module")
def corpus(tmp_path_factory: pytest.TempPathFactory) -> Corpus:
    root = tmp_path_factory.mktemp("corpus")
    run = make_run_folder(root / "good-run")
    rng = np.random.default_rng(0)
    npy = root / "good.npy"
    np.save(npy, rng.standard_normal((1500, 1)) * 1e-3)  # 15 s at --rate 100: enough for every analysis, quick
    fmt = compile_format(load_frame("kvh-1750-a"), None, 1000.0)
    idx = np.arange(400)
    rows = encode_samples(
        fmt, idx, idx / 1000.0, np.tile([0.0, 0.0, G0], (400, 1)), np.zeros((400, 3)), np.full(400, 300.0)
    )
    capture = root / "capture.bin"
    capture.write_bytes(rows.tobytes())
    tiny = root / "tiny.yaml"
    tiny.write_text("name: tiny\nsteps:\n  - warmup: {duration_s: 1}\n", encoding="utf-8")
    f: dict[str, Path] = {"missing": root / "no-such-file.yaml", "directory": root / "a-folder"}
    f["directory"].mkdir()
    f["empty"] = root / "empty.yaml"
    f["empty"].write_bytes(b"")
    f["bad-yaml"] = root / "bad.yaml"
    f["bad-yaml"].write_text("name: x\nsteps: [\n  - hold: {duration_s: 1\n", encoding="utf-8")
    f["duplicate-keys"] = root / "dup.yaml"
    f["duplicate-keys"].write_text("name: a\nname: b\nsteps:\n  - note: hi\n", encoding="utf-8")
    f["garbage"] = root / "garbage.bin"
    f["garbage"].write_bytes(rng.integers(0, 256, 4096, dtype=np.uint8).tobytes())
    f["not-recording"] = root / "not-recording.h5"
    with h5py.File(f["not-recording"], "w") as h:
        h["x"] = np.arange(10.0)
    data = (run / "recording.h5").read_bytes()
    f["truncated"] = root / "truncated.h5"
    f["truncated"].write_bytes(data[: len(data) // 2])
    # run folders whose recording is damaged in its metadata (calibration.json beside it is fine)
    for kind in DAMAGED:
        f[kind] = root / kind
        shutil.copytree(run, f[kind])
        with h5py.File(f[kind] / "recording.h5", "r+") as h:
            if kind == "other-version":
                h.attrs["format_version"] = 999
            elif kind == "bad-rate-attr":
                h.attrs["sample_rate_hz"] = "fast"
            else:
                del h["steps"]
    # absurd numbers
    f["huge-values"] = root / "huge-values.npy"
    np.save(f["huge-values"], np.full((1500, 1), 1e296) + rng.standard_normal((1500, 1)) * 1e294)
    sim = (REPO_ROOT / "benches" / "sim.yaml").read_text(encoding="utf-8")
    assert "    bias_ug: 300.0\n" in sim
    f["prior-1e300"] = root / "prior-1e300.yaml"
    f["prior-1e300"].write_text(sim.replace("    bias_ug: 300.0\n", "    bias_ug: 1e300\n", 1), encoding="utf-8")
    f["a-file"] = root / "a-file.txt"
    f["a-file"].write_text("not a folder\n", encoding="utf-8")
    return Corpus(root, run, npy, tiny, capture, f)


# ---- cases ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """``argv`` with ``{name}`` placeholders filled from the corpus; ``place``: text the error must name."""

    id: str
    argv: tuple[str, ...]
    place: str


GOOD_POSITIONAL = {
    ("certificate", "run"): "{run}",
    ("check", "procedure"): "{tiny}",
    ("correct", "calibration"): "{run}/calibration.json",
    ("correct", "input"): "{run}",
    ("decode", "capture"): "{capture}",
    ("drift", "input"): "{npy}",
    ("identify", "run"): "{run}",
    ("noise", "input"): "{npy}",
    ("periodic", "input"): "{npy}",
    ("runs", "folder"): "{root}",
    ("registry", "action"): "list",
    ("table", "action"): "status",
}
"""A valid value for each positional, so the other arguments can be tested one at a time (a command not
listed gets the bad file in every positional)."""
CONTEXT = {
    "correct": ("--out", "{root}/out-{id}.npy"),
    "decode": ("--frame", "kvh-1750-a", "--out", "{root}/out-{id}.npy"),
    "drift": ("--rate", "100", "--out", "{root}/out-{id}"),
    "noise": ("--rate", "100", "--out", "{root}/out-{id}"),
    "periodic": ("--rate", "100", "--out", "{root}/out-{id}"),
    "run": ("--procedure", "{tiny}", "--out", "{root}/out-{id}", "--no-identify", "--no-certificate"),
    "plan": ("--procedure", "{tiny}"),
    "identify": ("--out", "{root}/out-{id}.json"),
    "certificate": ("--out", "{root}/out-{id}.pdf", "--json", "{root}/out-{id}.json"),
}
"""Options added to every case of a command unless the case sets them: outputs go to the corpus folder,
a run that wrongly accepts a bad input runs only the tiny procedure."""
BAD_NUMBERS = {"text": "abc", "nan": "nan", "inf": "inf", "huge": "1e300", "minus-huge": "-1e300", "2**64": str(2**64)}
FILE_OPTIONS = ("--bench", "--procedure", "--resume", "--calibration", "--frame", "--unit-config")
"""Options that name an input file (outputs: ``--out``, ``--json``)."""
OUTPUT_OPTIONS = ("--out", "--json")
ACCEPTABLE = {("runs", "folder"): {"directory"}}
"""Corpus kinds that are valid for a positional (an empty folder has no runs: an empty list, exit 0)."""


def _argv(cmd: str, positionals: dict[str, str], options: dict[str, str]) -> tuple[str, ...]:
    ctx = list(CONTEXT.get(cmd, ()))
    merged: dict[str, str] = {}
    for i in range(0, len(ctx), 2):
        merged[ctx[i]] = ctx[i + 1]
    merged.update(options)
    out = [cmd, *positionals.values()]
    for k, v in merged.items():
        out += [k, v]
    return tuple(out)


def _generic_cases() -> Iterator[Case]:
    for cmd, p in COMMANDS.items():
        pos = _positionals(p)
        yield Case(
            f"{cmd}/unknown-option",
            (*_argv(cmd, {a.dest: GOOD_POSITIONAL.get((cmd, a.dest), "x") for a in pos}, {}), "--no-such-option"),
            "--no-such-option",
        )
        for target in pos:
            for kind in FILE_KINDS:
                if kind in ACCEPTABLE.get((cmd, target.dest), ()):
                    continue
                values = {
                    a.dest: (f"{{{kind}}}" if a is target else GOOD_POSITIONAL.get((cmd, a.dest), f"{{{kind}}}"))
                    for a in pos
                }
                yield Case(f"{cmd}/{target.dest}={kind}", _argv(cmd, values, {}), f"{{{kind}}}")
        good = {a.dest: GOOD_POSITIONAL.get((cmd, a.dest), "{missing}") for a in pos}
        for opt in _options(p):
            name = max(opt.option_strings, key=len)
            if opt.choices is not None:
                yield Case(f"{cmd}/{name}=bogus", _argv(cmd, good, {name: "bogus"}), name)
            elif opt.type is not None and opt.type is not str:
                for label, value in BAD_NUMBERS.items():
                    yield Case(f"{cmd}/{name}={label}", _argv(cmd, good, {name: value}), name)
            if name in OUTPUT_OPTIONS:
                yield Case(f"{cmd}/--out=uncreatable", _argv(cmd, good, {name: "{a-file}/sub/out"}), "a-file.txt")
            if name in FILE_OPTIONS:
                for kind in ("missing", "directory", "bad-yaml", "duplicate-keys", "garbage"):
                    yield Case(f"{cmd}/{name}={kind}", _argv(cmd, good, {name: f"{{{kind}}}"}), f"{{{kind}}}")


SPECIFIC = [
    Case("run/--seed=2**64", _argv("run", {}, {"--seed": str(2**64)}), "--seed"),
    Case("run/--seed=-1", _argv("run", {}, {"--seed": "-1"}), "--seed"),
    Case("run/--set=1e300", _argv("run", {}, {"--set": "duration_s=1e300"}), "duration_s"),
    Case("plan/--bench=prior-1e300", _argv("plan", {}, {"--bench": "{prior-1e300}"}), "prior"),
    Case("run/--bench=prior-1e300", _argv("run", {}, {"--bench": "{prior-1e300}"}), "prior"),
    Case("check/--bench=prior-1e300", _argv("check", {"procedure": "{tiny}"}, {"--bench": "{prior-1e300}"}), "prior"),
    Case("drift/values-1e296", _argv("drift", {"input": "{huge-values}"}, {}), "huge-values.npy"),
    Case("noise/values-1e296", _argv("noise", {"input": "{huge-values}"}, {}), "huge-values.npy"),
    Case("periodic/values-1e296", _argv("periodic", {"input": "{huge-values}"}, {}), "huge-values.npy"),
    Case("noise/--channels=empty", _argv("noise", {"input": "{npy}"}, {"--channels": ""}), "--channels"),
    Case("drift/--channels=empty", _argv("drift", {"input": "{npy}"}, {"--channels": ""}), "--channels"),
    Case("periodic/--channels=empty", _argv("periodic", {"input": "{npy}"}, {"--channels": ""}), "--channels"),
    Case("runs/nonexistent", ("runs", "/nonexistent/runs"), "/nonexistent/runs"),
    Case("run/--resume=not-a-run", ("run", "--resume", "{directory}"), "a-folder"),
]
for _kind in DAMAGED:
    SPECIFIC += [
        Case(f"identify/{_kind}", _argv("identify", {"run": f"{{{_kind}}}"}, {}), f"{{{_kind}}}"),
        Case(f"certificate/{_kind}", _argv("certificate", {"run": f"{{{_kind}}}"}, {}), f"{{{_kind}}}"),
        Case(
            f"correct/{_kind}",
            _argv("correct", {"c": "{run}/calibration.json", "i": f"{{{_kind}}}"}, {}),
            f"{{{_kind}}}",
        ),
        Case(f"noise/{_kind}", ("noise", f"{{{_kind}}}"), f"{{{_kind}}}"),
        Case(f"drift/{_kind}", ("drift", f"{{{_kind}}}", "--channels", "accel_x"), f"{{{_kind}}}"),
        Case(f"periodic/{_kind}", ("periodic", f"{{{_kind}}}"), f"{{{_kind}}}"),
    ]

KNOWN: dict[str, str] = {
}
"""Case id → owner and reason, for failures in areas other changes own (xfail, not strict)."""


def _params() -> list:
    cases = list({c.id: c for c in [*SPECIFIC, *_generic_cases()][::-1]}.values())[::-1]  # first of an id wins
    out = []
    for c in cases:
        marks = [pytest.mark.xfail(strict=False, reason=KNOWN[c.id])] if c.id in KNOWN else []
        out.append(pytest.param(c, id=c.id, marks=marks))
    return out


# ---- running a case ------------------------------------------------------------------------------------------


class _Hang(BaseException):
    pass


@contextlib.contextmanager
def _time_limit(seconds: int) -> Iterator[None]:
    def on_alarm(signum, frame):  # noqa: ARG001
        raise _Hang()

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _fill(text: str, corpus: Corpus, case_id: str) -> str:
    values = {k: str(v) for k, v in corpus.files.items()}
    values |= {"run": str(corpus.run), "npy": str(corpus.npy), "tiny": str(corpus.tiny), "root": str(corpus.root)}
    values["capture"] = str(corpus.capture)
    values["id"] = case_id.replace("/", "_").replace("*", "x")
    for k, v in values.items():
        text = text.replace("{" + k + "}", v)
    return text


def run_cli(argv: list[str]) -> tuple[int | None, str, str]:
    """(exit code or None on a traceback/hang, stdout, stderr + any traceback)."""
    out, err = io.StringIO(), io.StringIO()
    code: int | None
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        warnings.filterwarnings("ignore", category=DeprecationWarning)
        try:
            with _time_limit(TIMEOUT_S):
                code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 2
        except _Hang:
            code = None
            err.write(f"\nHANG: still running after {TIMEOUT_S} s\n")
        except BaseException:  # noqa: BLE001 - a traceback is exactly what this test looks for
            code = None
            err.write("\nTraceback (most recent call last):\n" + traceback.format_exc())
    # a warning would reach the user's terminal as extra lines (outside pytest nothing captures it)
    extra = "".join(f"WARNING {w.category.__name__}: {w.message} ({w.filename}:{w.lineno})\n" for w in seen)
    return code, out.getvalue(), extra + err.getvalue()


@pytest.mark.parametrize("case", _params())
def test_bad_input_is_one_clear_line_and_exit_2(case: Case, corpus: Corpus, monkeypatch) -> None:
    monkeypatch.chdir(corpus.root)  # nothing lands in the checkout
    monkeypatch.setenv("MPLBACKEND", "Agg")
    argv = [_fill(a, corpus, case.id) for a in case.argv]
    place = _fill(case.place, corpus, case.id)
    code, _out, err = run_cli(argv)
    assert "Traceback" not in err and "HANG" not in err, f"{' '.join(argv)}\n{err[-3000:]}"
    assert "WARNING " not in err, f"a Python warning reaches the user: {' '.join(argv)}\n{err[-3000:]}"
    assert code == 2, f"exit {code} (expected 2) for: {' '.join(argv)}\n{err[-2000:]}"
    named = place in err or Path(place).name in err
    assert named, f"the error does not name {place!r}: {err.strip()[-600:]}"
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"tablebench {argv[0]}: error: "), f"the last line is not the one error line: {last!r}"


def test_every_command_is_covered() -> None:
    ids = {c.values[0].id.split("/")[0] for c in _params()}
    assert ids == set(COMMANDS), f"commands without cases: {set(COMMANDS) - ids}"
