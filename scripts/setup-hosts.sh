#!/usr/bin/env bash
# Installs the real host programs the host tests drive against `sim serve`, from PyPI, into
# Python virtual environments under .hosts/ (ignored by git):
#   .hosts/octoprint  OctoPrint 1.11.8 with its dependencies frozen (hosts/octoprint-requirements.txt)
#                     plus this repository's plugin hosts/octoprint_layerpause
#   .hosts/printrun   Printrun 2.2.0 (printcore) without its GUI dependencies (wxPython, pyglet,
#                     numpy...): printcore itself needs only pyserial.
# Idempotent: a venv that already has its pinned release is kept (about 1 s); the plugin is
# re-installed every time (no network, about 2 s). A fresh install takes about 60-90 s on the
# 2-core machine (OctoPrint's wheels dominate). HOSTS_DIR overrides the folder.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
dir=${HOSTS_DIR:-$root/.hosts}
py=${PYTHON:-python3}
mkdir -p "$dir"

OCTOPRINT_VERSION=1.11.8
PRINTRUN_VERSION=2.2.0

have() { # venv, module, version
  [ -x "$1/bin/python" ] && "$1/bin/python" - "$2" "$3" <<'EOF' 2>/dev/null
import sys
from importlib.metadata import version
sys.exit(0 if version(sys.argv[1]) == sys.argv[2] else 1)
EOF
}

t0=$(date +%s)
if have "$dir/printrun" Printrun "$PRINTRUN_VERSION"; then
  echo "setup-hosts: printrun $PRINTRUN_VERSION present"
else
  echo "setup-hosts: installing Printrun $PRINTRUN_VERSION (printcore, no GUI deps)"
  rm -rf "$dir/printrun"
  "$py" -m venv "$dir/printrun"
  "$dir/printrun/bin/pip" install -q --disable-pip-version-check "pyserial==3.5"
  "$dir/printrun/bin/pip" install -q --disable-pip-version-check --no-deps "Printrun==$PRINTRUN_VERSION"
fi
"$dir/printrun/bin/python" -c "from printrun.printcore import printcore; from printrun import gcoder"

if have "$dir/octoprint" OctoPrint "$OCTOPRINT_VERSION"; then
  echo "setup-hosts: OctoPrint $OCTOPRINT_VERSION present"
else
  echo "setup-hosts: installing OctoPrint $OCTOPRINT_VERSION"
  rm -rf "$dir/octoprint"
  "$py" -m venv "$dir/octoprint"
  "$dir/octoprint/bin/pip" install -q --disable-pip-version-check -r hosts/octoprint-requirements.txt
fi
# The plugin from this repository (no dependencies beyond OctoPrint itself).
if [ -d "$root/hosts/octoprint_layerpause" ]; then
  "$dir/octoprint/bin/pip" install -q --disable-pip-version-check --no-deps --no-build-isolation \
    --force-reinstall "$root/hosts/octoprint_layerpause" >/dev/null
fi
"$dir/octoprint/bin/octoprint" --version
echo "setup-hosts: done in $(( $(date +%s) - t0 )) s"
