#!/usr/bin/env bash
# Installs Mitsuba 3 into .venv-mitsuba/ at the repository root, for the `mitsuba_compare`
# experiment and its test (reference::mitsuba finds the venv there, or via $SCATTERBENCH_MITSUBA_PYTHON).
#
# Idempotent: an existing venv that already imports mitsuba is kept. Prints the version.
#
#   scripts/setup-mitsuba.sh            # scalar_rgb variant (works everywhere)
#
# The llvm_ad_rgb variant additionally needs LLVM ≥ 16 at run time; on Debian 12 install
# `libllvm19` (apt-get install -y libllvm19): reference::mitsuba points Dr.Jit at it through
# DRJIT_LIBLLVM_PATH. The default LLVM 15 of Debian 12 makes Dr.Jit abort.
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=.venv-mitsuba
PYTHON=${PYTHON:-python3}
SPEC=${MITSUBA_SPEC:-mitsuba==3.*}

if [ -x "$VENV/bin/python" ] && "$VENV/bin/python" -c 'import mitsuba' >/dev/null 2>&1; then
  echo "== $VENV already has mitsuba"
else
  echo "== creating $VENV with $($PYTHON --version 2>&1)"
  "$PYTHON" -m venv "$VENV"
  "$VENV/bin/python" -m pip install --quiet --upgrade pip
  "$VENV/bin/python" -m pip install --quiet "$SPEC"
fi

"$VENV/bin/python" - <<'PY'
import mitsuba as mi
mi.set_variant("scalar_rgb")
print(f"mitsuba {mi.__version__} (variants: {', '.join(mi.variants())})")
PY
