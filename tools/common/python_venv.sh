# shellcheck shell=bash
# The Python package in a venv of its own (sourced by tools/python_test.sh and
# tools/readme_figure.sh; run from the repository root after tools/install_deps.sh).

# python_venv EXTRAS: creates build-python/venv when missing and installs the package with
# the extras EXTRAS (e.g. "foxglove,figure"; "" = none) into it, without build isolation (the
# build requirements are installed into the venv), so build-python/<wheel tag> is reused and
# a second run only rebuilds what changed. Sets VENV_PYTHON to the venv's python.
python_venv() {
  local extras=$1 venv=build-python/venv
  if [ ! -x "$venv/bin/python" ]; then python3 -m venv "$venv"; fi
  "$venv/bin/python" -m pip install -q --upgrade pip
  "$venv/bin/python" -m pip install -q "scikit-build-core>=0.10" "nanobind>=2.0" numpy
  "$venv/bin/python" -m pip install -q --no-build-isolation ".${extras:+[$extras]}"
  VENV_PYTHON=$PWD/$venv/bin/python
}
