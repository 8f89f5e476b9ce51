# Sourced by scripts/run.sh and scripts/test.sh (not run on its own): make sure the project's own virtual
# environment .venv exists in the project folder and holds tablebench (editable) with the extras in
# $TABLEBENCH_EXTRAS (e.g. "test"); then "$VENV_PY" is its python.
#
# Only the system python3 is needed (3.10 or newer, with its venv module). Nothing is installed outside the
# project folder: packages go to .venv, pip's cache to .venv/cache/pip, matplotlib's to .venv/cache. A system
# python3 marked EXTERNALLY-MANAGED (PEP 668; Debian, Ubuntu, Fedora) is fine: it only creates the venv.
# The install is skipped when pyproject.toml and the extras are unchanged since the last one (works offline).

VENV_DIR=".venv"
VENV_PY="$VENV_DIR/bin/python"
_extras="${TABLEBENCH_EXTRAS:-}"

_die() { echo "tablebench setup: error: $*" >&2; exit 2; }

_system_python() {
    local py
    for py in python3 python3.13 python3.12 python3.11 python3.10; do
        if command -v "$py" >/dev/null 2>&1 &&
            "$py" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 10) else 1)' 2>/dev/null; then
            echo "$py"
            return 0
        fi
    done
    return 1
}

if [ ! -x "$VENV_PY" ] || ! "$VENV_PY" -c 'import sys' >/dev/null 2>&1; then
    sys_py="$(_system_python)" || _die "python3 (3.10 or newer) is needed on PATH"
    echo "tablebench setup: creating the project environment $VENV_DIR with $(command -v "$sys_py") ($("$sys_py" -V 2>&1))" >&2
    rm -rf "$VENV_DIR"
    if ! "$sys_py" -m venv "$VENV_DIR" >&2; then
        rm -rf "$VENV_DIR"
        _die "'$sys_py -m venv' failed; install the venv module (Debian/Ubuntu: apt install python3-venv) and retry"
    fi
fi

export PIP_CACHE_DIR="${PIP_CACHE_DIR:-$PWD/$VENV_DIR/cache/pip}"
export MPLCONFIGDIR="${MPLCONFIGDIR:-$PWD/$VENV_DIR/cache/matplotlib}"
export PIP_DISABLE_PIP_VERSION_CHECK=1
export PYTHONNOUSERSITE=1

_spec="."
[ -n "$_extras" ] && _spec=".[$_extras]"
_stamp="$VENV_DIR/.tablebench-install"
_want="$("$VENV_PY" -c 'import hashlib, sys; print(hashlib.sha256(open("pyproject.toml", "rb").read()).hexdigest(), sys.argv[1])' "$_spec")"
if [ ! -f "$_stamp" ] || [ "$(cat "$_stamp")" != "$_want" ]; then
    echo "tablebench setup: installing tablebench ($_spec, editable) into $VENV_DIR ..." >&2
    if ! "$VENV_PY" -m pip install --quiet --retries 3 --timeout 60 -e "$_spec" >&2; then
        _die "could not install the dependencies into $VENV_DIR (see pip's message above). The package registry
  (pypi.org, or your pip index / proxy settings: pip config list) must be reachable for the first set-up;
  later runs reuse $VENV_DIR without network. Fix the connection and rerun the same command."
    fi
    echo "$_want" >"$_stamp"
fi
