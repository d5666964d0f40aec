#!/usr/bin/env bash
# mrcal for the side-by-side tests and benchmarks, in a venv of its own (.mrcal-venv): its wheels
# exist for Python >= 3.12 only, and a plain `pip install mrcal` fails building pyfltk (its GUI's),
# so it is not an extra of this project (docs/methods.md, "Side by side with mrcal").
# Prints the venv's python, or nothing (with a note on stderr) when no Python >= 3.12 or no
# package index is at hand; the tests that need mrcal then skip and say why.
set -uo pipefail
cd "$(dirname "$0")/.."
VENV=.mrcal-venv
STAMP=$VENV/.installed
if [ -f "$STAMP" ]; then echo "$PWD/$VENV/bin/python"; exit 0; fi
# on PATH, or installed by pyenv but not selected (its shims then refuse to run it)
pyenv_root=$(pyenv root 2>/dev/null || echo "$HOME/.pyenv")
for candidate in python3.13 python3.12 "$pyenv_root"/versions/3.1[2-9]*/bin/python3; do
    if command -v "$candidate" >/dev/null 2>&1 && "$candidate" -c 'import venv' >/dev/null 2>&1; then
        python=$candidate
        break
    fi
done
if [ -z "${python:-}" ]; then
    echo "note: no Python 3.12 or newer for mrcal's venv; the mrcal side-by-side tests will be skipped" >&2
    exit 0
fi
echo "installing mrcal into $VENV ($python)" >&2
log=$(mktemp)
if "$python" -m venv "$VENV" >"$log" 2>&1 \
    && "$VENV/bin/pip" install --quiet --no-deps mrcal >>"$log" 2>&1 \
    && "$VENV/bin/pip" install --quiet numpy scipy numpysane gnuplotlib shapely pyyaml opencv-python-headless >>"$log" 2>&1 \
    && "$VENV/bin/python" -c 'import mrcal' >>"$log" 2>&1; then
    touch "$STAMP"
    echo "$PWD/$VENV/bin/python"
else
    tail -5 "$log" >&2
    echo "note: mrcal could not be installed into $VENV; the mrcal side-by-side tests will be skipped" >&2
    rm -rf "$VENV"
fi
rm -f "$log"
exit 0
